//! Control of a running program: hold, resume, override and abort, SIGTERM, status with and
//! without a daemon, and an abort while `kerf run` still streams.

use super::*;

#[test]
fn hold_resume_override_and_abort_mid_program() {
    let env = Env::new("ctl", &[]);
    let _daemon = env.start_daemon("kerfd");

    // Refusals on an idle daemon.
    let hold = env.kerf("hold", &[]);
    assert!(!hold.status.success(), "hold when idle was accepted");
    let resume = env.kerf("resume", &[]);
    assert!(!resume.status.success(), "resume when idle was accepted");
    let over = env.kerf("override", &["250"]);
    assert!(!over.status.success(), "override 250 was accepted");
    assert_eq!(env.status()["override_pct"].as_f64(), Some(100.0));

    let (record, recorded) = env.start_record("record.csv");
    let mut moves = Vec::new();

    // Hold, then resume.
    let part = env.write("part.ngc", PART);
    moves.extend(env.moves(PART, [0.0; 6]));
    let mut run = env.spawn_run("run-hold", &part, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    let o = env.kerf("hold", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // At rest on hold: the same position over at least ten cycles.
    let mut before: Option<Value> = None;
    let held = env.wait_status("rest on hold", |s| {
        let rest = state(s) == "holding"
            && before
                .as_ref()
                .is_some_and(|b| position(b) == position(s) && cycles(s) >= cycles(b) + 10);
        before = Some(s.clone());
        rest
    });
    assert_eq!(program_end(&held), "running", "{held}");
    // A second planner process is turned away while the program holds.
    let o = env.kerf("run", &[env.write("other.ngc", LINES).to_str().unwrap()]);
    assert!(!o.status.success(), "a second kerf run was accepted");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("busy"), "{err}");
    let o = env.kerf("resume", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let status = wait(&mut run, 1);
    assert!(status.success(), "{}", run.stderr());
    let s = env.status();
    assert_eq!(program_end(&s), "finished", "{s}");
    assert_eq!(position(&s), [0.0; 6]);

    // Override 50 %, then 150 %.
    let lines = env.write("lines.ngc", LINES);
    moves.extend(env.moves(LINES, [0.0; 6]));
    let lines_csv = env.path("lines-run.csv");
    let mut run = env.spawn_run("run-override", &lines, Some(&lines_csv));
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    assert!(env.kerf("override", &["50"]).status.success());
    let s = env.wait_status("override 50", |s| s["override_pct"].as_f64() == Some(50.0));
    assert_eq!(program_end(&s), "running", "{s}");
    env.wait_cycles(200);
    // 0 % stands still on the path until raised again.
    assert!(env.kerf("override", &["0"]).status.success());
    let mut before: Option<Value> = None;
    env.wait_status("rest at 0 %", |s| {
        let rest = before
            .as_ref()
            .is_some_and(|b| position(b) == position(s) && cycles(s) >= cycles(b) + 10);
        before = Some(s.clone());
        rest
    });
    assert!(env.kerf("override", &["150"]).status.success());
    let s = env.wait_status("override 150", |s| {
        s["override_pct"].as_f64() == Some(150.0)
    });
    assert_eq!(program_end(&s), "running", "{s}");
    let status = wait(&mut run, 1);
    assert!(status.success(), "{}", run.stderr());
    assert!(env.kerf("override", &["100"]).status.success());

    // Abort, then the next program.
    let cam = cam_program(4, 600, 0.05, 3000.0);
    let cam_path = env.write("cam.ngc", &cam);
    moves.extend(env.moves(&cam, [0.0; 6]));
    let mut run = env.spawn_run("run-abort", &cam_path, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    let o = env.kerf("abort", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let status = wait(&mut run, 1);
    assert!(!status.success(), "kerf run exited 0 after an abort");
    assert!(run.stderr().contains("aborted"), "{}", run.stderr());
    let s = env.wait_status("rest after the abort", |s| state(s) != "running");
    assert_eq!(state(&s), "idle", "{s}");
    assert_eq!(program_end(&s), "aborted", "{s}");
    let stop = position(&s);
    assert!(stop != [0.0; 6], "the abort came after the motion began");
    let o = env.kerf("hold", &[]);
    assert!(!o.status.success(), "hold after the abort was accepted");
    moves.extend(env.moves(PART, stop));
    env.run_ok("run-after-abort", &part, None);
    let s = env.status();
    assert_eq!(program_end(&s), "finished", "{s}");
    assert_eq!(state(&s), "idle", "{s}");
    env.wait_cycles(300);
    stop_record(record);

    let rows = check_stream(&env, &recorded, &moves, "record");
    // The hold stood still on the path in the middle of the first program.
    let first = first_moving(&rows);
    let longest_rest_mid_program = rows[first..]
        .windows(2)
        .take_while(|w| !(w[0].position == [0.0; 6] && w[1].position == [0.0; 6]))
        .fold((0usize, 0usize), |(run, best), w| {
            if w[0].position == w[1].position {
                (run + 1, best.max(run + 1))
            } else {
                (0, best)
            }
        })
        .1;
    assert!(
        longest_rest_mid_program >= 10,
        "no stop on hold in the recording ({longest_rest_mid_program} rows)"
    );
    // On the G1 lines (2 to 6) at F3000, the 150 % override ran faster than the
    // programmed 50 mm/s, and no faster than 75 mm/s.
    let lines_rows = read_csv(&lines_csv);
    let max_feed = lines_rows
        .iter()
        .filter(|r| (2..=6).contains(&r.line))
        .map(|r| r.feed_mm_s)
        .fold(0.0, f64::max);
    assert!(max_feed > 50.0 * 1.01, "max feed {max_feed} mm/s");
    assert!(max_feed <= 75.0 * 1.01, "max feed {max_feed} mm/s");
    check_stream(
        &env,
        &lines_csv,
        &env.moves(LINES, [0.0; 6]),
        "lines --record",
    );
}

#[test]
fn sigterm_stops_on_the_path_then_exits_0() {
    let env = Env::new("term", &[]);
    let mut daemon = env.start_daemon("kerfd");
    let (mut record, recorded) = env.start_record("record.csv");
    let program = env.write("lines.ngc", LINES);
    let mut run = env.spawn_run("run", &program, None);
    // At speed on the first line.
    env.wait_status("speed", |s| state(s) == "running" && position(s)[0] > 20.0);
    daemon.signal("TERM");
    let status = wait(&mut daemon, 1);
    assert!(status.success(), "kerfd: {status}: {}", daemon.stderr());
    let status = wait(&mut run, 1);
    assert!(
        !status.success(),
        "kerf run exited 0 though the daemon stopped"
    );
    // The recorder sees the stream end (no gap) and stops.
    let _ = wait(&mut record, 1);
    assert!(!record.stderr().contains("lost"), "{}", record.stderr());
    let rows = check_stream(&env, &recorded, &env.moves(LINES, [0.0; 6]), "record");
    // Stopped before the program's end (the origin), and at rest.
    let last = rows.last().unwrap();
    assert!(last.position != [0.0; 6], "{last:?}");
    let before = &rows[rows.len() - 2];
    let step_mm = (0..3)
        .map(|i| (last.position[i] - before.position[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let speed_mm_s = step_mm / (env.config.period_us as f64 * 1e-6);
    assert!(
        speed_mm_s < 0.5,
        "still moving at {speed_mm_s} mm/s: {last:?}"
    );
}

#[test]
fn status_without_and_with_a_daemon() {
    let env = Env::new("st", &[]);
    // Every command that talks to a daemon: exit 1, naming the machine and how to start
    // a daemon.
    let program = env.write("part.ngc", PART);
    let program = program.to_str().unwrap();
    for (subcommand, args) in [
        ("status", &[][..]),
        ("status", &["--json"]),
        ("hold", &[]),
        ("resume", &[]),
        ("abort", &[]),
        ("override", &["50"]),
        ("run", &[program]),
        ("record", &["--out", "/dev/null", "--cycles", "1"]),
    ] {
        let o = env.kerf(subcommand, args);
        assert_eq!(o.status.code(), Some(1), "{subcommand} {args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&env.machine) && err.contains("kerfd"),
            "{subcommand} {args:?}: {err}"
        );
    }

    let _daemon = env.start_daemon("kerfd");
    let s = env.status();
    assert_eq!(s["machine"].as_str(), Some(env.machine.as_str()));
    assert_eq!(state(&s), "idle");
    assert_eq!(s["line"].as_u64(), Some(0));
    assert_eq!(position(&s), [0.0; 6]);
    assert_eq!(s["override_pct"].as_f64(), Some(100.0));
    assert_eq!(s["queued_moves"].as_u64(), Some(0));
    assert_eq!(s["queued_s"].as_f64(), Some(0.0));
    // The daemon answers once its cycle runs (every port is up by then), and it keeps
    // running.
    let first = cycles(&s);
    assert!(first > 0, "{s}");
    env.wait_status("cycles", |s| cycles(s) > first);
    assert!(s["overruns"].as_u64().is_some());
    assert!(s["rt"].is_boolean());
    assert!(s["fault"].is_null());
    assert_eq!(s["program_id"].as_u64(), Some(0));
    assert_eq!(s["program_done"].as_bool(), Some(false));
    assert_eq!(program_end(&s), "none");
    assert_eq!(s["moves_received"].as_u64(), Some(0));
    assert_eq!(
        s["window_items"].as_u64(),
        Some(u64::from(env.config.daemon.move_window))
    );
    assert_eq!(s["rejected"].as_u64(), Some(0));
    assert_eq!(s["period_us"].as_f64(), Some(1000.0));
    let o = env.kerf("status", &[]);
    assert!(o.status.success());
    let line = String::from_utf8_lossy(&o.stdout);
    assert!(
        line.starts_with(&format!("{}: idle", env.machine)),
        "{line}"
    );
}

/// An abort while `kerf run` is still streaming a program much longer than the daemon's
/// window and queue ends the program for everyone at once (issue 25): the daemon says
/// aborted, takes nothing more of it, and `kerf run` stops sending and exits 2.
#[test]
fn an_abort_while_kerf_run_still_streams_ends_the_program_for_the_client() {
    let env = Env::new(
        "abort_stream",
        &[
            ("queue_segments = 4096", "queue_segments = 64"),
            ("move_window = 4096", "move_window = 64"),
        ],
    );
    let _daemon = env.start_daemon("kerfd");
    // 600 exact-stop steps of 0.5 mm: a minute of motion, far more than 64 + 64 items
    // (`kerf run` simulates the whole program before it sends it: kept short for that).
    let mut program = String::from("G21 G90 G61\n");
    for k in 0..600 {
        let x = if k % 2 == 0 { 0.5 } else { 0.0 };
        program.push_str(&format!("G1 X{x} F600\n"));
    }
    program.push_str("M2\n");
    let path = env.write("long.ngc", &program);
    let mut run = env.spawn_run("run-long", &path, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    let o = env.kerf("abort", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let status = wait(&mut run, 1);
    assert_eq!(status.code(), Some(2), "{}", run.stderr());
    assert!(run.stderr().contains("aborted"), "{}", run.stderr());
    let s = env.wait_status("rest after the abort", |s| state(s) != "running");
    assert_eq!(program_end(&s), "aborted", "{s}");
    assert_eq!(state(&s), "idle", "{s}");
    // Nothing more of it is taken or moves (what `kerf run` sent before it saw the abort
    // was taken and dropped).
    let received = s["moves_received"].as_u64().unwrap();
    env.wait_cycles(200);
    let later = env.status();
    assert_eq!(later["moves_received"].as_u64().unwrap(), received);
    assert_eq!(position(&later), position(&s));
    assert!(received <= 601, "{received} items of a 601-item program");
}
