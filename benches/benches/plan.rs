//! Throughput of the G-code front end and of `kerf plan`.
//!
//! - `parse_resolve`: lexing, parsing, modal state and exact arc resolution of a generated
//!   LinuxCNC program of dense lines and arcs, in memory (no I/O), in blocks per second.
//! - `plan_json`: the same plus the JSON lines of `kerf plan`, written to `io::sink()`
//!   (`kerf::plan`: the interpreter and the JSON writer on two threads).
//! - `plan_json_one_thread`: the same on one thread (`kerf::plan::plan_sequential`).
//! - `json_only`: only the JSON formatting of the already resolved items, to show what the
//!   output costs on its own.
//!
//! Run: `cargo bench -p kerf-benches --bench plan`. Figures go in docs/PERFORMANCE.md.
// criterion_main! writes this bench's `main`, without a doc comment.
#![allow(missing_docs)]

use std::hint::black_box;
use std::io;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kerf_gcode::{Dialect, Interpreter, Item, Settings};

/// Blocks in the generated program: large enough that per-run overhead vanishes.
const BLOCKS: u64 = 1_000_000;

fn bench_plan(c: &mut Criterion) {
    let program = kerf_benches::program(BLOCKS);
    let mut group = c.benchmark_group("plan");
    group.throughput(Throughput::Elements(BLOCKS));
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));

    group.bench_function("parse_resolve", |b| {
        b.iter(|| {
            let mut moves = 0u64;
            for item in Interpreter::new(&program[..], Dialect::LinuxCnc, Settings::default()) {
                match item {
                    Ok(Item::Move(m)) => {
                        black_box(&m);
                        moves += 1;
                    }
                    Ok(Item::Event(e)) => {
                        black_box(&e);
                    }
                    Err(e) => panic!("generated program rejected: {e}"),
                }
            }
            black_box(moves)
        })
    });

    group.bench_function("plan_json", |b| {
        b.iter(|| {
            kerf::plan(
                &program[..],
                io::sink(),
                Dialect::LinuxCnc,
                Settings::default(),
            )
            .expect("generated program is valid")
        })
    });
    group.bench_function("plan_json_one_thread", |b| {
        b.iter(|| {
            kerf::plan::plan_sequential(
                &program[..],
                io::sink(),
                Dialect::LinuxCnc,
                Settings::default(),
            )
            .expect("generated program is valid")
        })
    });

    let items: Vec<Item> = Interpreter::new(&program[..], Dialect::LinuxCnc, Settings::default())
        .map_while(Result::ok)
        .collect();
    group.bench_function("json_only", |b| {
        let mut buf = Vec::with_capacity(1 << 20);
        b.iter(|| {
            let mut json = kerf::plan::JsonLines::new();
            let mut bytes = 0usize;
            for item in &items {
                json.write(&mut buf, item).expect("finite numbers");
                if buf.len() >= 1 << 20 {
                    bytes += buf.len();
                    buf.clear();
                }
            }
            bytes += buf.len();
            buf.clear();
            black_box(bytes)
        })
    });
    group.finish();
}

criterion_group!(benches, bench_plan);
criterion_main!(benches);
