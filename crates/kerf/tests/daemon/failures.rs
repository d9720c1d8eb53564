//! Failures on either side: a planner or daemon killed mid-stream, malformed moves, injected
//! drive faults and a safety trip.

use super::*;

#[test]
fn planner_killed_mid_stream() {
    // A small motion queue and window, so that the planner process is still streaming
    // (held back by flow control) when it is killed.
    let env = Env::new(
        "pk",
        &[
            ("queue_segments = 4096", "queue_segments = 64"),
            ("move_window = 4096", "move_window = 64"),
        ],
    );
    let _daemon = env.start_daemon("kerfd");
    let (record, recorded) = env.start_record("record.csv");
    let long = cam_program(20, 1000, 0.05, 6000.0);
    let total_moves = env.moves(&long, [0.0; 6]).len() as u64;
    let program = env.write("long.ngc", &long);
    let mut run = env.spawn_run("run", &program, None);
    let s = env.wait_status("motion", |s| state(s) == "running" && moved(s));
    assert!(
        s["moves_received"].as_u64().unwrap() + 1000 < total_moves,
        "the planner was not streaming any more: {s}"
    );
    run.signal("KILL");
    let _ = wait(&mut run, 1);

    let mut states = Vec::new();
    let s = env.wait_status("rest after the planner died", |s| {
        states.push(state(s).to_string());
        program_end(s) != "running"
    });
    assert_eq!(program_end(&s), "refused", "{s}");
    let fault = s["fault"].as_str().unwrap_or("");
    assert!(fault.contains("planner process"), "{s}");
    let s = env.wait_status("idle", |s| state(s) != "running" && state(s) != "starved");
    assert_eq!(state(&s), "idle", "{s}");
    for st in &states {
        assert!(
            ["running", "starved", "idle"].contains(&st.as_str()),
            "state {st} while coming to rest: {states:?}"
        );
    }
    // At rest at the end of a programmed move.
    let stop = position(&s);
    let all_moves = env.moves(&long, [0.0; 6]);
    let at_move_end = all_moves.iter().any(|m| {
        let e = m.path.end();
        (e.x - stop[0]).abs() < 1e-6 && (e.y - stop[1]).abs() < 1e-6 && (e.z - stop[2]).abs() < 1e-6
    });
    assert!(at_move_end, "stopped at {stop:?}, not at the end of a move");

    // The next program starts where the machine is.
    let next = env.write("next.ngc", LINES);
    env.run_ok("next", &next, None);
    let s = env.status();
    assert_eq!(program_end(&s), "finished", "{s}");
    env.wait_cycles(300);
    stop_record(record);
    let mut moves = all_moves;
    moves.extend(env.moves(LINES, stop));
    check_stream(&env, &recorded, &moves, "record");
}

#[test]
fn daemon_killed_then_restarted_without_clean_up() {
    let env = Env::new("dk", &[]);
    let mut daemon = env.start_daemon("kerfd");
    let (mut record, recorded) = env.start_record("record.csv");
    let cam = cam_program(4, 600, 0.05, 3000.0);
    let program = env.write("cam.ngc", &cam);
    let mut run = env.spawn_run("run", &program, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    daemon.signal("KILL");
    let _ = wait(&mut daemon, 1);
    let status = wait(&mut run, 1);
    assert!(!status.success(), "kerf run exited 0 after the daemon died");
    let err = run.stderr();
    assert!(
        err.contains("stopped") && err.contains(&env.machine),
        "{err}"
    );
    // The recorder sees the stream stall (not a gap) and stops.
    let status = wait(&mut record, 1);
    assert!(!status.success());
    assert!(!record.stderr().contains("lost"), "{}", record.stderr());
    let rows = read_csv(&recorded);
    check_limits(&env, &rows, "record before the kill");
    check_path(
        &env,
        &rows,
        &env.moves(&cam, [0.0; 6]),
        "record before the kill",
    );

    // A new daemon with the same configuration, no clean-up in between.
    let mut daemon = env.start_daemon("kerfd-again");
    let s = env.status();
    assert_eq!(state(&s), "idle", "{s}");
    let (record, recorded) = env.start_record("record-again.csv");
    let part = env.write("part.ngc", PART);
    let run_csv = env.path("run-again.csv");
    env.run_ok("run-again", &part, Some(&run_csv));
    env.wait_cycles(300);
    stop_record(record);
    let sim = env.sim(&part, "part-sim.csv");
    assert!(fs::read(&sim).unwrap() == fs::read(&run_csv).unwrap());
    check_stream(&env, &recorded, &env.moves(PART, [0.0; 6]), "record again");
    // SIGINT at rest: exit 0.
    daemon.signal("INT");
    let status = wait(&mut daemon, 1);
    assert!(status.success(), "kerfd: {status}: {}", daemon.stderr());
}

/// Turns a valid move message into a bad one.
type Spoil = fn(&mut kerf_proto::MoveMsg);

/// A program published straight into the moves service: BEGIN at the machine's position,
/// one valid line, then `bad` (a message made from a second line), then END.
fn inject(env: &Env, program_id: u64, bad: impl FnOnce(&mut kerf_proto::MoveMsg)) -> [f64; 3] {
    let start = position(&env.status());
    let text = "G21 G90 G64 P0.01\nG1 X12 Y3 F3000\nG1 X20 Y10\nM2\n";
    let moves = env.moves(text, start);
    assert_eq!(moves.len(), 2);
    let node = kerfd::ipc::node(&format!("test-{}-{program_id}", std::process::id())).unwrap();
    let service = kerfd::ipc::open_moves(&node, &env.machine).unwrap();
    let publisher = kerfd::ipc::move_publisher(&service).unwrap();
    let mut second = kerf_proto::MoveMsg::from_move(program_id, 2, &moves[1]);
    bad(&mut second);
    for msg in [
        kerf_proto::MoveMsg::begin(program_id, start, 0),
        kerf_proto::MoveMsg::from_move(program_id, 1, &moves[0]),
        second,
        kerf_proto::MoveMsg::end(program_id, 2),
    ] {
        publisher.send_copy(msg).unwrap();
    }
    // The publisher stays until the daemon has ended the program (a vanished sender is
    // a fault of its own).
    env.wait_status("the injected program to end", |s| {
        s["program_id"].as_u64() == Some(program_id) && program_end(s) != "running"
    });
    let e = moves[0].path.end();
    [e.x, e.y, e.z]
}

#[test]
fn malformed_and_non_finite_moves_are_refused() {
    let env = Env::new("inj", &[]);
    let _daemon = env.start_daemon("kerfd");
    let (record, recorded) = env.start_record("record.csv");
    let mut moves = Vec::new();
    let base = (std::process::id() as u64) << 20;
    let cases: [(&str, Spoil); 6] = [
        ("non-finite end", |m| m.end_mm[1] = f64::NAN),
        ("wrong version", |m| m.version = 999),
        ("unknown kind", |m| m.kind = 77),
        ("outside the travel", |m| m.end_mm[0] = 5000.0),
        ("zero feed", |m| m.feed_mm_min = 0.0),
        ("sequence gap", |m| m.seq = 5),
    ];
    for (n, (what, bad)) in cases.into_iter().enumerate() {
        let before = env.status();
        let start = position(&before);
        moves.extend(env.moves("G21 G90 G64 P0.01\nG1 X12 Y3 F3000\nM2\n", start));
        let id = base + n as u64 + 1;
        let valid_end = inject(&env, id, bad);
        let s = env.wait_status("rest", |s| state(s) != "running");
        assert_eq!(program_end(&s), "refused", "{what}: {s}");
        assert!(
            s["rejected"].as_u64().unwrap() > before["rejected"].as_u64().unwrap(),
            "{what}: {s}"
        );
        assert!(
            s["fault"].as_str().is_some_and(|f| !f.is_empty()),
            "{what}: {s}"
        );
        let p = position(&s);
        for i in 0..3 {
            assert!(
                (p[i] - valid_end[i]).abs() < 1e-9,
                "{what}: at rest at {p:?}, not at the end of the valid line {valid_end:?}"
            );
        }
        // The next normal program runs.
        let back = env.write(&format!("back{n}.ngc"), "G21 G90\nG1 X0 Y0 Z0 F3000\nM2\n");
        moves.extend(env.moves("G21 G90\nG1 X0 Y0 Z0 F3000\nM2\n", p));
        env.run_ok(&format!("back{n}"), &back, None);
        let s = env.status();
        assert_eq!(program_end(&s), "finished", "{what}: {s}");
        assert_eq!(position(&s), [0.0; 6], "{what}");
    }
    env.wait_cycles(300);
    stop_record(record);
    let text = read_text(&recorded);
    assert!(
        !text.to_ascii_lowercase().contains("nan"),
        "NaN in the recording"
    );
    check_stream(&env, &recorded, &moves, "record");
}

/// `kerf plot INPUT --out SVG`, to completion.
fn env_plot(input: &Path, svg: &Path) -> Output {
    Command::new(KERF)
        .arg("plot")
        .arg(input)
        .arg("--out")
        .arg(svg)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// Sends a fault injection through the control service (accepted by `kerfd --test-faults`
/// only); the daemon's answer.
fn inject_fault(env: &Env, injection: kerfd::worker::Injection) -> kerf_proto::Response {
    let mut client = kerf::client::Client::connect(&env.machine).expect("the daemon answers");
    let code = injection.code().expect("a code for the injection");
    client
        .request(kerf_proto::ControlCommand::Inject { code })
        .expect("an answer")
}

#[test]
fn a_drive_fault_injected_mid_program_is_latched_reported_dumped_and_reset() {
    use kerfd::worker::Injection;
    let env = Env::new(
        "fault",
        &[(
            "[daemon]",
            "[safety]\ndump_dir = \"blackbox\"\nrecorder_seconds = 2.0\n[daemon]",
        )],
    );
    let _daemon = env.start_daemon_with("kerfd", &["--test-faults"]);
    let program = env.write("cam.ngc", &cam_program(20, 200, 0.5, 3000.0));
    let mut run = env.spawn_run("run", &program, None);
    env.wait_status("the program to move", |s| {
        state(s) == "running" && s["line"].as_u64().unwrap_or(0) > 20
    });
    let r = inject_fault(&env, Injection::DriveFault(1));
    assert_eq!(r.reason, kerf_proto::REASON_OK, "{}", r.message());

    // `kerf run` fails and says why.
    let status = wait(&mut run, 2);
    assert_eq!(status.code(), Some(2), "{}", run.stderr());
    let err = run.stderr();
    assert!(
        err.contains("the safety layer stopped the machine")
            && err.contains("drive_fault on axis Y: the drive reports error 0x4310")
            && err.contains("black box: "),
        "{err}"
    );

    // Latched, reported with the check, axis, value, line and the black-box file.
    let s = env.wait_status("the fault's black box", |s| s["safety"]["dump"].is_string());
    assert_eq!(state(&s), "fault");
    assert_eq!(s["drives"], "stopped");
    let safety = &s["safety"];
    assert_eq!(safety["check"], "drive_fault");
    assert_eq!(safety["axis"], "y");
    assert_eq!(safety["drive_error_code"], 0x4310);
    assert!(safety["line"].as_u64().unwrap() > 20, "{s}");
    let text = String::from_utf8(env.kerf("status", &[]).stdout).unwrap();
    assert!(
        text.contains("fault: drive_fault on axis Y") && text.contains("black box: "),
        "{text}"
    );
    // The black box: 2 s of cycles, the motion before the trip and the stop to rest.
    let dump = PathBuf::from(safety["dump"].as_str().unwrap());
    assert!(
        dump.starts_with(env.dir.join("blackbox").canonicalize().unwrap()),
        "{dump:?}"
    );
    let csv = read_text(&dump);
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        &header[..5],
        &["sequence", "time_s", "state", "x_cmd_mm", "x_act_mm"]
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // Consecutive cycles, the last 2 s of them (or all since the start, if fewer).
    let seq: Vec<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(seq.windows(2).all(|w| w[1] == w[0] + 1));
    assert!(
        rows.len() == 2000 || (rows.len() < 2000 && seq[0] == 1),
        "{}",
        rows.len()
    );
    assert!(rows.iter().all(|r| r.len() == header.len()));
    assert!(rows.iter().any(|r| r[2] == "running"));
    assert_eq!(rows.last().unwrap()[2], "stopped");
    let moving = rows
        .windows(2)
        .filter(|w| w[0][2] == "running" && w[0][3] != w[1][3])
        .count();
    assert!(moving > 10, "the X axis moved before the trip");

    // Nothing runs while the fault is latched.
    let refused = env.kerf("run", &[program.to_str().unwrap()]);
    assert_eq!(refused.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&refused.stderr);
    assert!(msg.contains("is in fault"), "{msg}");
    // A reset is refused while the drive's fault persists …
    let reset = env.kerf("reset", &[]);
    assert_eq!(reset.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&reset.stderr);
    assert!(
        msg.contains("the drive of axis Y still reports a fault"),
        "{msg}"
    );
    assert_eq!(env.status()["safety"]["check"], "drive_fault");
    // … and accepted once it is gone.
    let r = inject_fault(&env, Injection::ClearDriveFault(1));
    assert_eq!(r.reason, kerf_proto::REASON_OK, "{}", r.message());
    let reset = env.kerf("reset", &[]);
    assert!(
        reset.status.success(),
        "{}",
        String::from_utf8_lossy(&reset.stderr)
    );
    let s = env.status();
    assert_eq!(
        (state(&s), &s["safety"], &s["drives"]),
        ("idle", &Value::Null, &Value::from("running"))
    );

    // `kerf dump` copies the black box to a file of the user's.
    let out = env.path("box.csv");
    let dumped = env.kerf("dump", &["--out", out.to_str().unwrap()]);
    assert!(
        dumped.status.success(),
        "{}",
        String::from_utf8_lossy(&dumped.stderr)
    );
    let csv = read_text(&out);
    assert!(csv.starts_with("sequence,time_s,state,x_cmd_mm"), "{csv}");
    assert!(csv.lines().count() > 100, "{}", csv.lines().count());
    // `kerf plot` draws the fault's black box: X, Y, Z, each commanded against actual
    // and the following error, the stop shaded.
    let svg = env.path("fault.svg");
    let plotted = env_plot(&dump, &svg);
    assert!(
        plotted.status.success(),
        "{}",
        String::from_utf8_lossy(&plotted.stderr)
    );
    let svg = read_text(&svg);
    assert_eq!(svg.matches(r#"class="envelope""#).count(), 9);
    assert!(svg.contains("Y: following error") && svg.contains("#f6d0d0"));

    // And the machine runs programs again, from where the quick stop left it.
    let short = env.write("short.ngc", "G21 G91 G1 X1 Y1 F600\nM2\n");
    env.run_ok("after", &short, None);
    assert_eq!(program_end(&env.status()), "finished");
}

#[test]
fn fault_injection_is_refused_without_test_faults() {
    let env = Env::new("noinj", &[]);
    let _daemon = env.start_daemon("kerfd");
    let r = inject_fault(&env, kerfd::worker::Injection::DriveFault(0));
    assert_eq!(r.reason, kerf_proto::REASON_NOT_ALLOWED);
    assert!(r.message().contains("--test-faults"), "{}", r.message());
    let s = env.status();
    assert_eq!((state(&s), &s["safety"]), ("idle", &Value::Null));
}

#[test]
fn run_record_keeps_the_setpoints_up_to_a_safety_trip() {
    use kerfd::worker::Injection;
    let env = Env::new(
        "triprec",
        &[(
            "[daemon]",
            "[safety]\ndump_dir = \"blackbox\"\nrecorder_seconds = 1.0\n[daemon]",
        )],
    );
    let _daemon = env.start_daemon_with("kerfd", &["--test-faults"]);
    let text = cam_program(4, 200, 0.5, 3000.0);
    let program = env.write("cam.ngc", &text);
    let sim_csv = env.sim(&program, "sim.csv");
    let sim = read_csv(&sim_csv);
    // A recording of a failed run is the diagnosis: it replaces what was there.
    let csv = env.path("run.csv");
    fs::write(&csv, "an older recording\n").unwrap();
    let mut run = env.spawn_run("run", &program, Some(&csv));
    env.wait_status("the program to move", |s| {
        state(s) == "running" && s["line"].as_u64().unwrap_or(0) > 20
    });
    // A 1 mm step of Y on its way to the drive: a velocity trip (the setpoint never
    // reaches the drive; the quick stop does).
    let r = inject_fault(&env, Injection::Step(1, Injection::STEP_MM));
    assert_eq!(r.reason, kerf_proto::REASON_OK, "{}", r.message());

    let status = wait(&mut run, 2);
    assert_eq!(status.code(), Some(2), "{}", run.stderr());
    let err = run.stderr();
    assert!(
        err.contains("the safety layer stopped the machine") && err.contains("velocity on axis Y"),
        "{err}"
    );
    assert!(!err.contains("recording"), "{err}");
    let s = env.wait_status("the fault's black box", |s| s["safety"]["dump"].is_string());
    assert_eq!(s["safety"]["check"], "velocity", "{s}");

    // Every row of the program up to the trip: the header, the row at t = 0, then one per
    // cycle. Up to the cycle before the trip, the same bytes as `kerf sim`'s CSV (the
    // daemon = sim up to the trip). The last row is the cycle of the trip as the stream
    // published it: the line being run, the position the drives got (the first step of the
    // quick stop, within the limits) and no feed (the motion core rests where the drives
    // stop).
    let rows = read_csv(&csv);
    assert!(rows.len() > 100, "{} rows", rows.len());
    assert!(
        rows.len() < sim.len(),
        "{} rows of {}",
        rows.len(),
        sim.len()
    );
    let (trip, before) = rows.split_last().unwrap();
    let (recorded, simulated) = (read_text(&csv), read_text(&sim_csv));
    let recorded = recorded.lines().collect::<Vec<_>>();
    let simulated = simulated.lines().collect::<Vec<_>>();
    let n = recorded.len() - 1;
    assert!(recorded[..n] == simulated[..n], "the rows before the trip");
    let at_trip = &sim[before.len()];
    assert_eq!(trip.t, at_trip.t);
    assert_eq!((trip.line, trip.feed_mm_s), (at_trip.line, 0.0));
    assert_ne!(trip.position, at_trip.position);
    check_limits(&env, &rows, "the recording up to the trip");
    assert_eq!(
        trip.line as u64,
        s["safety"]["line"].as_u64().unwrap(),
        "{s}"
    );
}
