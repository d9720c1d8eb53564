//! Programs streamed through the daemon and run embedded: the recorded setpoints equal
//! `kerf sim`'s, programs back to back, persistent parameters, and code denser than the
//! tracker.

use super::*;

#[test]
fn run_record_and_kerf_record_equal_kerf_sim() {
    let env = Env::new("rec", &[]);
    let _daemon = env.start_daemon("kerfd");
    let cam = cam_program(5, 600, 0.05, 3000.0);
    assert!(cam.lines().count() > 3000);
    for (name, text) in [("part", PART), ("pocket", POCKET), ("cam", cam.as_str())] {
        let program = env.write(&format!("{name}.ngc"), text);
        let sim = env.sim(&program, &format!("{name}-sim.csv"));
        let (record, recorded) = env.start_record(&format!("{name}-record.csv"));
        let run_csv = env.path(&format!("{name}-run.csv"));
        env.run_ok(name, &program, Some(&run_csv));
        env.wait_cycles(300);
        stop_record(record);

        let sim_bytes = fs::read(&sim).unwrap();
        let run_bytes = fs::read(&run_csv).unwrap();
        assert!(
            sim_bytes == run_bytes,
            "{name}: kerf run --record differs from kerf sim ({} and {} bytes)",
            run_bytes.len(),
            sim_bytes.len()
        );
        let moves = env.moves(text, [0.0; 6]);
        let sim_rows = check_stream(&env, &sim, &moves, &format!("{name} sim"));
        let rec_rows = check_stream(&env, &recorded, &moves, &format!("{name} record"));
        assert_record_matches_sim(&rec_rows, &sim_rows, name);
        let s = env.status();
        assert_eq!(state(&s), "idle", "{s}");
        assert_eq!(program_end(&s), "finished", "{s}");
    }
}

#[test]
fn programs_back_to_back() {
    let env = Env::new("b2b", &[]);
    let _daemon = env.start_daemon("kerfd");
    let (record, recorded) = env.start_record("record.csv");
    let mut moves = Vec::new();

    // The first ends at the origin: the second records exactly as kerf sim.
    let part = env.write("part.ngc", PART);
    let pocket = env.write("pocket.ngc", POCKET);
    let part_csv = env.path("part-run.csv");
    let pocket_csv = env.path("pocket-run.csv");
    env.run_ok("part", &part, Some(&part_csv));
    env.run_ok("pocket", &pocket, Some(&pocket_csv));
    moves.extend(env.moves(PART, [0.0; 6]));
    moves.extend(env.moves(POCKET, [0.0; 6]));
    for (program, text, csv) in [(&part, PART, &part_csv), (&pocket, POCKET, &pocket_csv)] {
        let sim = env.sim(program, "sim.csv");
        assert!(
            fs::read(&sim).unwrap() == fs::read(csv).unwrap(),
            "{program:?}: kerf run --record differs from kerf sim"
        );
        check_stream(&env, csv, &env.moves(text, [0.0; 6]), "--record");
    }

    // The first ends elsewhere: the second starts there.
    let away = "G21 G90 G64 P0.01\nG1 X10 Y5 Z-1 F4000\nG2 X20 Y5 I5 J0\nM2\n";
    let away_path = env.write("away.ngc", away);
    env.run_ok("away", &away_path, None);
    moves.extend(env.moves(away, [0.0; 6]));
    let s = env.status();
    let here = position(&s);
    assert!(
        (here[0] - 20.0).abs() < 1e-9 && (here[1] - 5.0).abs() < 1e-9,
        "{s}"
    );
    let lines_csv = env.path("lines-run.csv");
    let lines = env.write("lines.ngc", LINES);
    env.run_ok("lines", &lines, Some(&lines_csv));
    moves.extend(env.moves(LINES, here));
    let lines_rows = read_csv(&lines_csv);
    assert_eq!(lines_rows[0].position, here);
    check_limits(&env, &lines_rows, "lines --record");
    check_path(&env, &lines_rows, &env.moves(LINES, here), "lines --record");

    env.wait_cycles(300);
    stop_record(record);
    check_stream(&env, &recorded, &moves, "record");
}

/// `kerf run --embedded --record run.csv PROGRAM` on `env`'s machine, which must succeed
/// with setpoints byte for byte `kerf sim`'s (`sim.csv`); the recorded file.
fn embedded_run_equal_to_sim(env: &Env, program: &Path) -> PathBuf {
    let run_csv = env.path("run.csv");
    let mut run = spawn(
        "run",
        &env.dir,
        KERF,
        &[
            "run",
            "--embedded",
            "--config",
            env.config_arg(),
            "--record",
            run_csv.to_str().unwrap(),
            program.to_str().unwrap(),
        ],
    );
    let status = wait(&mut run, 2);
    assert!(status.success(), "{}", run.stderr());
    let sim = env.sim(program, "sim.csv");
    assert!(
        fs::read(&sim).unwrap() == fs::read(&run_csv).unwrap(),
        "the daemon's setpoints differ from kerf sim's"
    );
    run_csv
}

#[test]
fn embedded_run_equals_kerf_sim() {
    let env = Env::new("emb", &[]);
    let program = env.write("part.ngc", PART);
    let run_csv = embedded_run_equal_to_sim(&env, &program);
    check_stream(
        &env,
        &run_csv,
        &env.moves(PART, [0.0; 6]),
        "--embedded --record",
    );
    // The daemon lived in that process only.
    assert_eq!(env.kerf("status", &[]).status.code(), Some(1));
}

#[test]
fn run_keeps_linuxcnc_persistent_parameters_in_the_parameter_file() {
    // `[gcode] parameter_file`: read at program start, written by `kerf run` after a
    // program that ended normally (LinuxCNC's .var file). `kerf sim` never writes it.
    let env = Env::new(
        "var",
        &[(
            "# parameter_file = \"kerf.var\"",
            "parameter_file = \"kerf.var\"",
        )],
    );
    let var = env.path("kerf.var");
    let _daemon = env.start_daemon("kerfd");
    let first = env.write(
        "store.ngc",
        "G21 G90\nG10 L2 P2 X3\nG0 X1 Y2\nG28.1\nG0 X0 Y0\nM2\n",
    );
    let sim_csv = env.path("store.csv");
    let o = env.kerf(
        "sim",
        &[first.to_str().unwrap(), "--out", sim_csv.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!var.exists(), "kerf sim wrote the parameter file");
    env.run_ok("run", &first, None);
    let text = read_text(&var);
    assert!(
        text.starts_with("5161\t1.000000\n5162\t2.000000\n5163\t0.000000\n"),
        "{text}"
    );
    assert!(text.contains("\n5220\t1.000000\n"), "{text}");
    assert!(text.contains("\n5241\t3.000000\n"), "{text}");
    // The next program starts with the stored G28 position and the G55 offset.
    let second = env.write("home.ngc", "G21 G90\nG28\nG55 G0 Y0\nM2\n");
    env.run_ok("run2", &second, None);
    let p = position(&env.status());
    assert!((p[0] - 1.0).abs() < 1e-6 && p[1].abs() < 1e-6, "{p:?}");
}

/// A dense CAM surface whose smoothed pieces each stand for many programmed moves fills
/// the daemon's move tracker (16 moves per queued segment and 4,096 more) before its
/// motion queue: the queue then counts as full and the motion starts (it used to wait for
/// a full queue that could never come, the machine "running" without moving), and the
/// setpoints are still `kerf sim`'s. A 16-segment queue and 0.005 mm steps make it show
/// on a short program.
#[test]
fn a_dense_surface_whose_pieces_outnumber_the_tracker_starts_and_equals_kerf_sim() {
    let env = Env::new(
        "tracker",
        &[("queue_segments = 4096", "queue_segments = 16")],
    );
    let mut text = String::from("G21 G90 G17 G94 G64 P0.01 F3000\n");
    for k in 1..=20_000 {
        let x = f64::from(k) * 0.005;
        text += &format!("G1 X{x:.4} Z{:.4}\n", 0.5 * (x / 4.0).sin());
    }
    text += "M2\n";
    let program = env.write("surface.ngc", &text);
    embedded_run_equal_to_sim(&env, &program);
}

/// A straight line of 30,000 programmed moves (steps of 0.1 µm, 3 mm) on a 16-segment
/// queue, whose tracker holds 4,352 moves: the planner's pieces stand for at most
/// `MAX_PIECE_MOVES` moves each, so the tracker always holds the running piece and the
/// next, and the motion runs through without stopping (a 2 mm piece of 20,000 moves used
/// to stop the motion at its end, X2, waiting for room in the tracker, and the daemon
/// restarted a cycle or two later than `kerf sim`, depending on how far the planning
/// thread had sent the next piece's moves). The daemon's setpoints equal `kerf sim`'s, and
/// each names the line of a move that passes within 1 µm of it, from the program's text.
#[test]
fn a_line_of_more_moves_than_the_tracker_holds_runs_through_as_in_kerf_sim() {
    let env = Env::new(
        "untracked",
        &[("queue_segments = 4096", "queue_segments = 16")],
    );
    let capacity = kerf_pipeline::tracked_moves(16);
    let steps = 30_000;
    let step_mm = 0.0001;
    assert!(steps > 4 * capacity, "the line outnumbers the tracker");
    let mut text = String::from("G21 G90 G17 G94 G64 P0.01 F3000\n");
    for k in 1..=steps {
        text += &format!("G1 X{:.4}\n", k as f64 * step_mm);
    }
    text += "M2\n";
    let program = env.write("steps.ngc", &text);
    let rows = read_csv(&embedded_run_equal_to_sim(&env, &program));
    let last = rows.last().unwrap();
    assert!((last.position[0] - 3.0).abs() < 1e-9, "ends at {last:?}");
    // Move k (line k + 1) runs from X (k - 1)·step to X k·step.
    for row in &rows[1..] {
        let x = row.position[0];
        let k = f64::from(row.line) - 1.0;
        assert!(
            (k - 1.0) * step_mm - 1e-6 <= x && x <= k * step_mm + 1e-6,
            "line {} named at X{x}",
            row.line
        );
    }
    // Moving from the first row that moves to the end, never at rest in between.
    let first = rows.iter().position(|r| r.position[0] > 0.0).unwrap();
    let end = rows.iter().position(|r| r.position[0] == 3.0).unwrap();
    for pair in rows[first - 1..=end].windows(2) {
        assert!(
            pair[1].position[0] > pair[0].position[0],
            "at rest at X{} ({} s)",
            pair[1].position[0],
            pair[1].t
        );
    }
}
