//! Measurements of the interpolator daemon (docs/PERFORMANCE.md, section "kerfd"). Not a
//! test: it prints figures, it asserts nothing about time.
//!
//! ```text
//! kerfd_bench timing [--period-us N] [--seconds S] [--fifo]
//!     Starts the daemon in this process (its real threads and iceoryx2 services, the
//!     real cycle loop; `--fifo` as kerfd: SCHED_FIFO and mlockall, without it as
//!     `kerf run --embedded`), streams a dense program of S seconds of motion through
//!     the moves service with flow control, waits for the end, stops the daemon and
//!     prints the cycle's wake-up latency, compute time and publishing latency.
//! kerfd_bench throughput [--moves N]
//!     Streams N dense-line moves through the moves service (MoveSender) into the
//!     daemon's planning thread (subscriber, stream check, travel check, planner) with
//!     the flow-control window; a thread drains the planned items as the cycle would.
//!     Prints moves per second.
//! kerfd_bench hold [--period-us N] [--repeats R] [--fifo] [--config FILE]
//!     Runs a long line at constant feed, and R times: sends `hold` (the request and
//!     acknowledgement `kerf hold` uses), finds the first setpoint whose feed decreases,
//!     resumes. Prints the delay from the request (CLOCK_MONOTONIC, compared with the
//!     setpoints' time stamps) and the request round trip. With `--config FILE` it talks
//!     to a running `kerfd` of that machine instead of starting one.
//! kerfd_bench roundtrip [--period-us N] [--requests N] [--fifo] [--config FILE]
//!     The request round trip of a status request (the machine idle: no command for the
//!     cycle to apply), N times (10,000 unless given), 100 µs apart: min, median, p99,
//!     p99.9, max.
//!
//! `hold` and `roundtrip` take `--cpu-latency-us N` for the daemon they start
//! (`daemon.cpu_latency_us`, requested with `--fifo`; 1000000 asks nothing of the CPUs)
//! and `--cpu N` (`daemon.cpu`: the cycle pinned to CPU N, the daemon's other threads and
//! this process's client kept off it, as on a machine that isolates the cycle's CPU).
//! kerfd_bench send-copy [--samples N]
//!     The cost of iceoryx2's `send_copy` of one setpoint called inline.
//! ```

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use kerf::client::{Client, MoveSender, SetpointReader};
use kerf_config::Config;
use kerf_proto::{ControlCommand, MoveMsg, PROGRAM_END_NONE};
use kerfd::timing::Histogram;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("timing") => timing(&args[1..]),
        Some("throughput") => throughput(&args[1..]),
        Some("hold") => hold(&args[1..]),
        Some("roundtrip") => roundtrip(&args[1..]),
        Some("send-copy") => send_copy(&args[1..]),
        _ => Err(
            "usage: kerfd_bench timing|throughput|hold|roundtrip|send-copy [options] (see the source's header)"
                .to_string(),
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kerfd_bench: {e}");
            ExitCode::from(1)
        }
    }
}

/// The value after `--name`, parsed, or `default`.
fn opt<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> Result<T, String> {
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| format!("{name} needs a value")),
    }
}

fn flag(args: &[String], name: &str) -> bool {
    args.iter().any(|a| a == name)
}

/// The built-in machine under a name of its own (so that runs never collide), without
/// its homing (every axis homed at start: the benchmark measures the cycle, not homing).
fn bench_config(period_us: u32) -> Config {
    let mut config = Config::from_toml_str(
        &kerf_testkit::config_text::without_homing(kerf_config::BUILTIN_TOML),
        kerf_config::BUILTIN_ORIGIN,
    )
    .expect("the built-in machine without homing");
    config.machine = format!("bench_{}", std::process::id());
    config.period_us = period_us;
    config
}

/// A dense CAM-style raster from `start`: rows of 1,000 chords of 0.1 mm along X with
/// ±0.01 mm of noise across, rows 0.1 mm apart, at F3000 with G64 P0.01: `moves` moves.
fn dense_raster(moves: usize, start: [f64; 6]) -> String {
    let mut text = String::with_capacity(moves * 24 + 64);
    text.push_str("G21 G90 G17 G94 G64 P0.01 F3000\n");
    let (x0, y0) = (start[0], start[1]);
    let mut row = 0usize;
    let mut k = 0usize;
    for i in 0..moves {
        let along = (k + 1) as f64 * 0.1;
        let x = if row.is_multiple_of(2) {
            along
        } else {
            100.0 - along
        };
        let noise = if i.is_multiple_of(2) { 0.01 } else { -0.01 };
        let y = row as f64 * 0.1 + noise;
        text += &format!("G1 X{:.3} Y{:.3}\n", x0 + x, y0 + y);
        k += 1;
        if k == 1000 {
            k = 0;
            row += 1;
            text += &format!("G1 Y{:.3}\n", y0 + row as f64 * 0.1);
        }
    }
    // A LinuxCNC program ends with M2.
    text.push_str("M2\n");
    text
}

/// A dense contour: `moves` chords of 0.1 mm along a slowly widening spiral of radius
/// 20 mm and more, from the origin, at F3000 with G64 P0.01 (smoothed into curves).
fn dense_spiral(moves: usize) -> String {
    let mut text = String::with_capacity(moves * 24 + 64);
    text.push_str("G21 G90 G17 G94 G64 P0.01 F3000\n");
    let mut theta = 0.0f64;
    for _ in 0..moves {
        let r = 20.0 + 0.02 * theta;
        theta += 0.1 / r;
        let r = 20.0 + 0.02 * theta;
        text += &format!(
            "G1 X{:.4} Y{:.4}\n",
            r * theta.cos() - 20.0,
            r * theta.sin()
        );
    }
    // A LinuxCNC program ends with M2.
    text.push_str("M2\n");
    text
}

/// The messages of one program: BEGIN, one per item, END.
fn messages(config: &Config, id: u64, start: [f64; 6], text: &str) -> Result<Vec<MoveMsg>, String> {
    let mut settings = config.settings();
    settings.start_mm_deg = start;
    let mut out = vec![MoveMsg::begin(id, start, 0)];
    let mut seq = 0;
    for item in
        kerf_gcode::Interpreter::new(text.as_bytes(), kerf_gcode::Dialect::LinuxCnc, settings)
    {
        let item = item.map_err(|d| format!("generated program: {d}"))?;
        seq += 1;
        out.push(MoveMsg::from_item(id, seq, &item));
    }
    out.push(MoveMsg::end(id, seq));
    Ok(out)
}

/// Streams `msgs` as `kerf run` does: never more than the daemon's window unacknowledged
/// (acknowledged by the status's `moves_received`).
fn stream(client: &mut Client, sender: &mut MoveSender, msgs: &[MoveMsg]) -> Result<(), String> {
    let id = msgs.first().map_or(0, |m| m.program_id);
    let status = client.status().map_err(|e| e.to_string())?;
    let window = status.window_items.max(1);
    let mut acked = 0u64;
    for m in msgs {
        while sender.sent - acked >= window {
            let s = client.status().map_err(|e| e.to_string())?;
            if s.program_id == id {
                acked = s.moves_received;
            }
            if sender.sent - acked >= window {
                std::thread::sleep(Duration::from_micros(500));
            }
        }
        sender.send(*m).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn wait_end(client: &mut Client, id: u64) -> Result<kerf_proto::StatusMsg, String> {
    loop {
        let s = client.status().map_err(|e| e.to_string())?;
        if s.program_id == id && s.program_end != PROGRAM_END_NONE {
            return Ok(s);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

fn timing(args: &[String]) -> Result<(), String> {
    let period_us: u32 = opt(args, "--period-us", 1000)?;
    let seconds: f64 = opt(args, "--seconds", 20.0)?;
    let fifo = flag(args, "--fifo");
    let config = bench_config(period_us);
    let daemon = kerfd::start(&config, fifo).map_err(|e| e.to_string())?;
    let rt = daemon.rt().clone();
    let mut client = Client::connect(&config.machine).map_err(|e| e.to_string())?;
    let mut sender = MoveSender::open(client.node(), &config.machine).map_err(|e| e.to_string())?;
    // 500 chords per second of motion at 50 mm/s.
    let moves = (seconds * 500.0) as usize;
    let msgs = messages(&config, 7, [0.0; 6], &dense_spiral(moves))?;
    let t0 = Instant::now();
    stream(&mut client, &mut sender, &msgs)?;
    let end = wait_end(&mut client, 7)?;
    let elapsed = t0.elapsed();
    daemon.shutdown();
    let deadline = Instant::now() + Duration::from_secs(20);
    let summary = loop {
        if let Some(s) = daemon.timing() {
            break s;
        }
        if Instant::now() > deadline {
            return Err("the daemon did not stop".to_string());
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    daemon.join()?;
    println!(
        "period {period_us} µs, SCHED_FIFO requested: {fifo}, rt in effect: {} ({}), {} moves, {:.1} s, program end {}, overruns {}",
        rt.rt,
        rt.messages.join("; "),
        msgs.len() - 2,
        elapsed.as_secs_f64(),
        end.program_end,
        end.overruns
    );
    println!("{summary}");
    println!("| what | p50 µs | p99 µs | p99.9 µs | max µs |");
    for (name, p) in [
        ("wake-up latency", summary.latency),
        ("compute (wake-up to hand-over)", summary.compute),
        (
            "publish added (hand-over to after send_copy)",
            summary.publish,
        ),
    ] {
        println!(
            "| {name} | {:.1} | {:.1} | {:.1} | {:.1} |",
            us(p.p50_ns),
            us(p.p99_ns),
            us(p.p999_ns),
            us(p.max_ns)
        );
    }
    Ok(())
}

/// A straight raster: rows of 1,000 collinear chords of 0.1 mm (nothing to smooth).
fn straight_raster(moves: usize) -> String {
    let mut text = String::with_capacity(moves * 24 + 64);
    text.push_str("G21 G90 G17 G94 G64 P0.01 F3000\n");
    for i in 0..moves {
        let (row, k) = (i / 1000, i % 1000);
        let along = (k + 1) as f64 * 0.1;
        let x = if row.is_multiple_of(2) {
            along
        } else {
            100.0 - along
        };
        text += &format!("G1 X{x:.3} Y{:.3}\n", row as f64 * 0.1);
    }
    // A LinuxCNC program ends with M2.
    text.push_str("M2\n");
    text
}

fn throughput(args: &[String]) -> Result<(), String> {
    let moves: usize = opt(args, "--moves", 500_000)?;
    let program: String = opt(args, "--program", "noisy".to_string())?;
    let config = bench_config(1000);
    let window = config.daemon.move_window as usize;
    let text = match program.as_str() {
        "noisy" => dense_raster(moves, [0.0; 6]),
        "spiral" => dense_spiral(moves),
        "straight" => straight_raster(moves),
        "cam" => {
            String::from_utf8(kerf_benches::program(moves as u64)).map_err(|e| e.to_string())?
        }
        _ => return Err("--program noisy|spiral|straight|cam".to_string()),
    };
    let msgs = messages(&config, 9, [0.0; 6], &text)?;
    let n = msgs.len() as u64;
    if flag(args, "--transport-only") {
        return transport_only(&config, &msgs);
    }

    let stop = Arc::new(AtomicBool::new(false));
    let counters = kerfd::worker::PlanningCounters::default();
    let (items_tx, mut items_rx) =
        rtrb::RingBuffer::<kerfd::worker::RtItem>::new(kerfd::PLANNED_RING);
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let planning = {
        let (config, stop, counters) = (config.clone(), stop.clone(), counters.clone());
        std::thread::spawn(move || {
            let machine = config.machine.clone();
            kerfd::planning_thread(
                &config, &machine, window, ready_tx, stop, counters, items_tx,
            )
        })
    };
    match ready_rx.recv_timeout(Duration::from_secs(10)) {
        Ok(Ok(_)) => {}
        Ok(Err(e)) => return Err(e.to_string()),
        Err(_) => return Err("the planning thread did not start".to_string()),
    }
    // The cycle's side: takes every planned item, as fast as they come.
    let drain = std::thread::spawn(move || {
        let mut items = 0u64;
        loop {
            match items_rx.pop() {
                Ok(kerfd::worker::RtItem::End(_)) => return (items, Instant::now()),
                Ok(_) => items += 1,
                Err(_) => std::thread::sleep(Duration::from_micros(50)),
            }
        }
    });
    let node = kerfd::ipc::node("kerfd-bench")
        .map_err(|e| e.to_string())
        .map_err(|e| e.to_string())?;
    let mut sender = MoveSender::open(&node, &config.machine).map_err(|e| e.to_string())?;
    let mut waits = 0u64;
    let t0 = Instant::now();
    for m in &msgs {
        // The flow-control window, acknowledged by the count `kerf status` reports.
        while sender.sent - counters.received.load(Ordering::Acquire) >= window as u64 {
            waits += 1;
            std::thread::sleep(Duration::from_micros(500));
        }
        sender.send(*m).map_err(|e| e.to_string())?;
    }
    let sent_at = t0.elapsed();
    let (items, done) = drain
        .join()
        .map_err(|_| "the drain thread panicked".to_string())?;
    let elapsed = done.duration_since(t0);
    stop.store(true, Ordering::Release);
    planning
        .join()
        .map_err(|_| "the planning thread panicked".to_string())??;
    let secs = elapsed.as_secs_f64();
    println!(
        "{} messages ({} moves) sent in {:.3} s, planned to the last item in {:.3} s: {:.0} moves/s ({} planned items, {} window waits)",
        n,
        n - 2,
        sent_at.as_secs_f64(),
        secs,
        (n - 2) as f64 / secs,
        items,
        waits
    );
    Ok(())
}

/// The moves service and the stream check alone (no planning): what the transport
/// carries.
fn transport_only(config: &Config, msgs: &[MoveMsg]) -> Result<(), String> {
    let window = config.daemon.move_window as usize;
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), String>>();
    let machine = config.machine.clone();
    let received = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let n = msgs.len() as u64;
    let rx = {
        let received = received.clone();
        std::thread::spawn(move || -> Result<Instant, String> {
            let setup = || -> Result<_, String> {
                let node = kerfd::ipc::node("kerfd-bench-rx").map_err(|e| e.to_string())?;
                let service =
                    kerfd::ipc::create_moves(&node, &machine, window).map_err(|e| e.to_string())?;
                let subscriber =
                    kerfd::ipc::move_subscriber(&service, window).map_err(|e| e.to_string())?;
                Ok((node, service, subscriber))
            };
            let (_node, _service, subscriber) = match setup() {
                Ok(p) => {
                    let _ = ready_tx.send(Ok(()));
                    p
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e.clone()));
                    return Err(e);
                }
            };
            let mut check = kerf_proto::StreamCheck::new();
            loop {
                match subscriber.receive() {
                    Ok(Some(sample)) => {
                        let msg: MoveMsg = *sample;
                        check.check(&msg).map_err(|e| e.to_string())?;
                        if received.fetch_add(1, Ordering::AcqRel) + 1 == n {
                            return Ok(Instant::now());
                        }
                    }
                    Ok(None) => std::thread::sleep(Duration::from_micros(200)),
                    Err(e) => return Err(format!("{e:?}")),
                }
            }
        })
    };
    ready_rx
        .recv()
        .map_err(|_| "the receiver ended".to_string())??;
    let tx_node = kerfd::ipc::node("kerfd-bench-tx").map_err(|e| e.to_string())?;
    let mut sender = MoveSender::open(&tx_node, &config.machine).map_err(|e| e.to_string())?;
    let t0 = Instant::now();
    for m in msgs {
        while sender.sent - received.load(Ordering::Acquire) >= window as u64 {
            std::thread::sleep(Duration::from_micros(500));
        }
        sender.send(*m).map_err(|e| e.to_string())?;
    }
    let done = rx
        .join()
        .map_err(|_| "the receiver panicked".to_string())??;
    let secs = done.duration_since(t0).as_secs_f64();
    println!(
        "transport only (moves service + stream check, same window and sleeps): {} messages in {:.3} s: {:.0} messages/s",
        n,
        secs,
        n as f64 / secs
    );
    Ok(())
}

/// What iceoryx2's `send_copy` of one setpoint costs when called inline (as the cycle
/// did before publishing moved to a helper thread), with one subscriber.
fn send_copy(args: &[String]) -> Result<(), String> {
    let n: u64 = opt(args, "--samples", 100_000)?;
    let config = bench_config(1000);
    let node = kerfd::ipc::node("kerfd-bench-pub").map_err(|e| e.to_string())?;
    let service =
        kerfd::ipc::create_setpoints(&node, &config.machine).map_err(|e| e.to_string())?;
    let publisher = service
        .publisher_builder()
        .create()
        .map_err(|e| format!("{e:?}"))?;
    let subscriber = kerfd::ipc::setpoint_subscriber(&service).map_err(|e| e.to_string())?;
    let mut h = Histogram::new();
    let mut msg = kerf_proto::SetpointMsg::new();
    for seq in 1..=n {
        msg.seq = seq;
        let t = kerf_rt::now_ns();
        let _ = publisher.send_copy(msg);
        h.record(kerf_rt::now_ns() - t);
        while let Ok(Some(_)) = subscriber.receive() {}
    }
    println!(
        "inline send_copy of a SetpointMsg, {n} samples: {}",
        h.percentiles()
    );
    Ok(())
}

/// The machine a measurement talks to: the running `kerfd` of `--config FILE`, or a
/// daemon started in this process at `period_us` (`--fifo`: SCHED_FIFO, as kerfd), which
/// the caller shuts down.
fn daemon_of(args: &[String], period_us: u32) -> Result<(Config, Option<kerfd::Daemon>), String> {
    let fifo = flag(args, "--fifo");
    let external: Option<String> =
        opt(args, "--config", String::new()).map(|s| if s.is_empty() { None } else { Some(s) })?;
    match &external {
        Some(path) => {
            let c = Config::load(std::path::Path::new(path)).map_err(|e| e.to_string())?;
            Ok((c, None))
        }
        None => {
            let mut c = bench_config(period_us);
            c.daemon.cpu_latency_us = opt(args, "--cpu-latency-us", c.daemon.cpu_latency_us)?;
            let cpu: i64 = opt(args, "--cpu", -1)?;
            c.daemon.cpu = u32::try_from(cpu).ok();
            if let Some(cpu) = c.daemon.cpu {
                // The client (this thread) off the cycle's CPU too, as on a machine whose
                // cycle has an isolated CPU (deploy/README.md).
                kerf_rt::avoid_cpu(cpu as usize).map_err(|e| e.to_string())?;
            }
            let d = kerfd::start(&c, fifo).map_err(|e| e.to_string())?;
            let rt = d.rt();
            println!(
                "daemon in this process: real-time {}, CPU wake-up latency request {}{}",
                rt.rt,
                rt.cpu_latency_us
                    .map_or("none".to_owned(), |us| format!("{us} µs")),
                if rt.messages.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", rt.messages.join("; "))
                }
            );
            Ok((c, Some(d)))
        }
    }
}

fn roundtrip(args: &[String]) -> Result<(), String> {
    let period_us: u32 = opt(args, "--period-us", 1000)?;
    let requests: usize = opt(args, "--requests", 10_000)?;
    let (config, daemon) = daemon_of(args, period_us)?;
    let mut client = Client::connect(&config.machine).map_err(|e| e.to_string())?;
    let mut rtt_us = Vec::with_capacity(requests);
    for _ in 0..requests {
        let sent_ns = kerf_rt::now_ns();
        client.status().map_err(|e| e.to_string())?;
        rtt_us.push(us(kerf_rt::now_ns() - sent_ns));
        std::thread::sleep(Duration::from_micros(100));
    }
    rtt_us.sort_by(f64::total_cmp);
    let at = |q: f64| rtt_us[((rtt_us.len() - 1) as f64 * q).round() as usize];
    println!(
        "status round trip over {requests} requests, µs: min {:.1}, median {:.1}, p99 {:.1}, p99.9 {:.1}, max {:.1}",
        at(0.0),
        at(0.5),
        at(0.99),
        at(0.999),
        at(1.0)
    );
    if let Some(d) = daemon {
        d.shutdown();
        d.join()?;
    }
    Ok(())
}

fn hold(args: &[String]) -> Result<(), String> {
    let period_us: u32 = opt(args, "--period-us", 1000)?;
    let repeats: usize = opt(args, "--repeats", 20)?;
    let (config, daemon) = daemon_of(args, period_us)?;
    let mut client = Client::connect(&config.machine).map_err(|e| e.to_string())?;
    let status = client.status().map_err(|e| e.to_string())?;
    let period_ns = status.period_ns;
    let start = status.position_mm_deg;
    let mut reader =
        SetpointReader::open(client.node(), &config.machine).map_err(|e| e.to_string())?;
    let mut sender = MoveSender::open(client.node(), &config.machine).map_err(|e| e.to_string())?;
    let id = 11;
    let text = format!("G21 G90 G94 F3000\nG1 X{:.3}\nM2\n", start[0] + 900.0);
    stream(
        &mut client,
        &mut sender,
        &messages(&config, id, start, &text)?,
    )?;

    let mut delay_us = Vec::new();
    let mut rtt_us = Vec::new();
    let mut excess_cycles = Vec::new();
    println!(
        "period {} µs; per hold: delay to the first decelerating setpoint, request round trip",
        period_ns / 1000
    );
    for _ in 0..repeats {
        // Wait for 100 setpoints at the programmed feed.
        let mut steady = 0;
        while steady < 100 {
            reader
                .drain(true, |m| {
                    if m.program_id == id && (m.feed_mm_s - 50.0).abs() < 1e-6 {
                        steady += 1;
                    } else {
                        steady = 0;
                    }
                    Ok(())
                })
                .map_err(|e| e.to_string())?;
            std::thread::sleep(Duration::from_micros(200));
        }
        let sent_ns = kerf_rt::now_ns();
        client
            .command(ControlCommand::Hold)
            .map_err(|e| e.to_string())?;
        let acked_ns = kerf_rt::now_ns();
        // The first setpoint stamped after the request whose feed is below the one before.
        // The feed of the last setpoint before the request: the steady one.
        let mut previous = 50.0;
        let mut first: Option<u64> = None;
        let mut stopped = 0;
        while stopped < 20 {
            reader
                .drain(true, |m| {
                    if first.is_none() && m.time_ns >= sent_ns && m.feed_mm_s < previous - 1e-9 {
                        first = Some(m.time_ns);
                    }
                    previous = m.feed_mm_s;
                    if first.is_some() && m.feed_mm_s == 0.0 {
                        stopped += 1;
                    }
                    Ok(())
                })
                .map_err(|e| e.to_string())?;
            std::thread::sleep(Duration::from_micros(200));
        }
        let first = first.ok_or("no decelerating setpoint")?;
        let delay = first - sent_ns;
        let rtt = acked_ns - sent_ns;
        delay_us.push(us(delay));
        rtt_us.push(us(rtt));
        let excess = (delay as f64 - rtt as f64) / period_ns as f64;
        excess_cycles.push(excess);
        println!(
            "  delay {:.1} µs = {:.2} cycles; round trip {:.1} µs; delay - round trip = {:.2} cycles",
            us(delay),
            delay as f64 / period_ns as f64,
            us(rtt),
            excess
        );
        client
            .command(ControlCommand::Resume)
            .map_err(|e| e.to_string())?;
    }
    let worst = excess_cycles
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let exact = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        format!(
            "min {:.1}, median {:.1}, max {:.1}",
            v[0],
            v[n / 2],
            v[n - 1]
        )
    };
    println!(
        "delay µs: {}; in cycles: {}",
        exact(delay_us.clone()),
        exact(
            delay_us
                .iter()
                .map(|d| d * 1000.0 / period_ns as f64)
                .collect()
        )
    );
    println!("round trip µs: {}", exact(rtt_us));
    println!("largest (delay - round trip): {worst:.2} cycles");
    let _ = client.command(ControlCommand::Abort);
    wait_end(&mut client, id)?;
    if let Some(d) = daemon {
        d.shutdown();
        d.join()?;
    }
    Ok(())
}
