//! Prints what the interpreter makes of a program: `cargo run -p kerf-gcode --example dump -- DIALECT FILE`.

use std::io::BufReader;

use kerf_gcode::{Dialect, Interpreter, Item, Path, Settings};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(d), Some(file)) = (args.get(1).and_then(|d| Dialect::from_name(d)), args.get(2))
    else {
        eprintln!("usage: dump DIALECT FILE");
        std::process::exit(2);
    };
    let reader: Box<dyn std::io::BufRead> = if file == "-" {
        Box::new(BufReader::new(std::io::stdin()))
    } else {
        match std::fs::File::open(file) {
            Ok(f) => Box::new(BufReader::new(f)),
            Err(e) => {
                eprintln!("{file}: {e}");
                std::process::exit(2);
            }
        }
    };
    if args.get(3).map(String::as_str) == Some("--count") {
        let t = std::time::Instant::now();
        let mut n = 0u64;
        for item in Interpreter::new(reader, d, Settings::default()) {
            if item.is_err() {
                break;
            }
            n += 1;
        }
        let s = t.elapsed().as_secs_f64();
        println!("{n} items in {s:.3} s: {:.2} M items/s", n as f64 / s / 1e6);
        return;
    }
    for item in Interpreter::new(reader, d, Settings::default()) {
        match item {
            Ok(Item::Move(m)) => match m.path {
                Path::Line(l) => println!(
                    "{:>4} {} ({:.4},{:.4},{:.4}) -> ({:.4},{:.4},{:.4}) F{:?} {:?} {:?}",
                    m.line,
                    if m.rapid { "rapid" } else { "line " },
                    l.start.x,
                    l.start.y,
                    l.start.z,
                    l.end.x,
                    l.end.y,
                    l.end.z,
                    m.feed_mm_min,
                    m.abc_deg,
                    m.corner
                ),
                Path::Arc(a) => println!(
                    "{:>4} arc   ({:.4},{:.4},{:.4}) -> ({:.4},{:.4},{:.4}) c=({:.4},{:.4},{:.4}) axis=({},{},{}) sweep={:.4}deg F{:?} {:?}",
                    m.line,
                    a.start.x,
                    a.start.y,
                    a.start.z,
                    a.end.x,
                    a.end.y,
                    a.end.z,
                    a.center.x,
                    a.center.y,
                    a.center.z,
                    a.axis.x,
                    a.axis.y,
                    a.axis.z,
                    a.sweep_rad.to_degrees(),
                    m.feed_mm_min,
                    m.abc_deg
                ),
            },
            Ok(Item::Event(e)) => println!("{:>4} event {} {:?}", e.line, e.code.as_str(), e.value),
            Err(e) => {
                println!("{file}:{e}");
                std::process::exit(2);
            }
        }
    }
}
