//! 20 WebSocket watchers during a part: the daemon's setpoints stay `kerf sim`'s, and
//! `kerf serve`'s CPU and memory within budget.

use crate::*;

/// CPU time (user + system) and peak resident memory of process `pid`, from /proc: s and
/// bytes.
fn cpu_and_peak_memory(pid: u32) -> (f64, u64) {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    // The fields after the command's closing parenthesis: utime and stime are the 12th
    // and 13th of them (fields 14 and 15 of the line), in clock ticks.
    let after = stat.rsplit_once(')').unwrap().1;
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks: u64 = fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap();
    let hz = 100.0; // USER_HZ, 100 on every Linux this runs on
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let kib: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap();
    (ticks as f64 / hz, kib * 1024)
}

#[test]
fn twenty_watchers_change_no_setpoint_and_kerf_serve_stays_within_its_memory_budget() {
    let s = served("load");
    status_until(s.addr, "idle", |st| st["state"] == "idle");
    // A part of lines and arcs without waits (no tool change, no spindle: the daemon
    // waits for those in real time, kerf sim does not), about 10 s; kerf sim's setpoints
    // for it, the machine at rest at 0.
    let mut text = String::from("G21 G90 G17\n");
    for i in 0..6 {
        let d = f64::from(i) * 2.0;
        text.push_str(&format!(
            "G1 X{} Y{d} F3000\nG1 X{} Y{d}\nG2 X{} Y{} I0 J10\nG1 X{} Y{} Z-1\nG3 X{} Y{d} I0 J-10\n",
            10.0 + d,
            60.0 - d,
            60.0 - d,
            d + 20.0,
            10.0 + d,
            d + 20.0,
            10.0 + d,
        ));
    }
    text.push_str("G0 Z5\nG0 X0 Y0\nG0 Z0\nM2\n");
    let part = s.env.write("load.ngc", &text);
    let sim = s.env.path("sim.csv");
    let out = s
        .env
        .kerf_command(
            &["sim"],
            &[part.to_str().unwrap(), "--out", sim.to_str().unwrap()],
        )
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "kerf sim: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // 20 watchers on the stream, each reading every message until the run is over.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let url = format!("ws://{}/api/v1/ws", s.addr);
    let watchers: Vec<_> = (0..20)
        .map(|_| {
            let (url, stop, addr) = (url.clone(), stop.clone(), s.addr);
            std::thread::spawn(move || {
                let connected = Instant::now();
                let stream = TcpStream::connect(addr).unwrap();
                stream.set_read_timeout(Some(MACHINE_PATIENCE)).unwrap();
                let mut ws = tungstenite::client(url.as_str(), stream).unwrap().0;
                let (mut messages, mut bytes) = (0u64, 0u64);
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    if let tungstenite::Message::Text(t) = ws.read().unwrap() {
                        messages += 1;
                        bytes += t.len() as u64;
                    }
                }
                (messages, bytes, connected.elapsed().as_secs_f64())
            })
        })
        .collect();
    let serve_pid = s._serve.pid();
    let (cpu0, _) = cpu_and_peak_memory(serve_pid);
    let started = Instant::now();
    let run = s.env.path("run.csv");
    s.env.kerf_ok(
        &["run"],
        &["--record", run.to_str().unwrap(), part.to_str().unwrap()],
    );
    let seconds = started.elapsed().as_secs_f64();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let counts: Vec<(u64, u64, f64)> = watchers.into_iter().map(|w| w.join().unwrap()).collect();
    let (cpu1, peak) = cpu_and_peak_memory(serve_pid);
    assert!(
        std::fs::read(&sim).unwrap() == std::fs::read(&run).unwrap(),
        "with 20 watchers the daemon's setpoints differ from kerf sim's"
    );
    for (messages, _, window) in &counts {
        assert!(*messages > 0, "a watcher received nothing: {counts:?}");
        // The server sends at most one every 50 ms: over the watcher's own window, at
        // most 20 a second and the first.
        assert!(
            *messages as f64 <= 20.0 * window + 1.0,
            "{messages} in {window} s"
        );
    }
    // The memory ceiling of deploy/kerf-serve.service is 256 MiB; it needs a small part.
    assert!(peak < 64 * 1024 * 1024, "kerf serve peaked at {peak} bytes");
    let per_watcher_bytes_s = counts.iter().map(|c| c.1).sum::<u64>() as f64 / 20.0 / seconds;
    eprintln!(
        "kerf serve with 20 watchers over a {seconds:.1} s run: CPU {:.1} % of one core, peak RSS {:.1} MiB, {:.1} kB/s per watcher",
        100.0 * (cpu1 - cpu0) / seconds,
        peak as f64 / 1048576.0,
        per_watcher_bytes_s / 1000.0
    );
}
