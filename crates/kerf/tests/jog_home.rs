//! Multi-process tests of homing and jogging (issue 29) through the daemon `kerfd` and the
//! commands that talk to it, on the bundled example machine (which homes on simulated
//! switches and refuses programs until it is homed):
//!
//! - a new user's setup: programs refused until homed, an unhomed jog at the reduced
//!   speed, `kerf home --all` to the home position, jogs to a point and by a step that end
//!   exactly there, then the program runs;
//! - a continuous jog whose client is killed stops by the daemon's dead man's switch,
//!   within the dead-man time plus a jerk-limited stop of what the axis had reached;
//! - bad jogs are refused with the reason and nothing moves.
//!
//! Every test writes its own machine configuration (a copy of `config/kerf.toml` with a
//! machine name unique to the test and this process, and its own state file) into its own
//! directory; child processes live in [`Proc`] guards. What is asserted is measured from
//! the outputs (`kerf status --json`, the commands' exit codes and words).

use std::fs;
use std::process::Output;
use std::time::{Duration, Instant};

mod common;
use common::{MACHINE_PATIENCE as PATIENCE, MachineEnv, Proc};

/// One test's machine (see [`MachineEnv`]), named `j<pid>_<tag>`; `homing`: as bundled.
fn env(tag: &str, homing: bool) -> MachineEnv {
    MachineEnv::new("kerf-jog-home-tests", "j", tag, homing)
}

/// The X position in the status.
fn x(env: &MachineEnv) -> f64 {
    env.status()["position"]["x"].as_f64().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_new_user_homes_the_example_machine_jogs_and_runs_a_program() {
    let env = env("setup", true);
    let _d = env.start_daemon("kerfd");
    let s = env.status();
    assert_eq!(s["homing_required"], true);
    assert_eq!(s["axes"]["x"]["homed"], false);
    // Before homing the machine stands where its motors powered up (config/kerf.toml's
    // [axes.*.sim] start_mm), and programs are refused before any motion.
    let x0 = x(&env);
    assert_eq!(x0, -80.0);
    let prog = env.dir.join("part.ngc");
    fs::write(&prog, "G21 G90\nG1 X10 Y5 F3000\nG0 X0 Y0\nM2\n").unwrap();
    let o = env.kerf(&["run"], &[prog.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("not homed"), "{}", stderr(&o));
    assert_eq!(x(&env), x0, "nothing moved");
    // Unhomed, a jog may not be faster than 10 % of the axis's 200 mm/s.
    let o = env.kerf(&["jog"], &["X+", "--speed", "50", "--for", "0.2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not homed"), "{}", stderr(&o));
    assert_eq!(x(&env), x0, "a refused jog does not move");
    env.kerf_ok(&["jog"], &["X", "--step", "2", "--speed", "20"]);
    assert_eq!(x(&env), x0 + 2.0);
    // Homing: Z first, then X and Y, to the home position 0, 0, 0.
    let o = env.kerf_ok(&["home"], &["--all"]);
    let told = stderr(&o);
    assert!(
        told.contains("homing Z: searching for the home switch"),
        "{told}"
    );
    assert!(told.contains("homed XYZ"), "{told}");
    let s = env.status();
    for axis in ["x", "y", "z"] {
        assert_eq!(s["axes"][axis]["homed"], true, "{axis}: {s}");
        assert_eq!(s["position"][axis], 0.0, "{axis} at its home position: {s}");
    }
    // Homed, jogs go where they are told, exactly.
    let o = env.kerf_ok(&["jog"], &["X", "--to", "12.5"]);
    assert_eq!(String::from_utf8_lossy(&o.stdout).trim(), "X 12.5000 mm");
    assert_eq!(x(&env), 12.5);
    env.kerf_ok(&["jog"], &["X-", "--step", "2.5"]);
    assert_eq!(x(&env), 10.0);
    // A target beyond the soft limits is refused with the reason, and nothing moves.
    let o = env.kerf(&["jog"], &["X", "--to", "1200"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("beyond the soft limits"),
        "{}",
        stderr(&o)
    );
    assert_eq!(x(&env), 10.0);
    // The program now runs from where the machine stands.
    fs::write(&prog, "G21 G90\nG1 X20 Y5 F3000\nG0 X0 Y0\nM2\n").unwrap();
    env.kerf_ok(&["run"], &[prog.to_str().unwrap()]);
    assert_eq!(x(&env), 0.0);
}

/// The time a jerk-limited stop from speed `v` takes at most, s (from the limits, not from
/// the code under test): 2·sqrt(v/j) when v ≤ a²/j, else v/a + a/j.
fn stop_time_s(v: f64, a: f64, j: f64) -> f64 {
    if v <= a * a / j {
        2.0 * (v / j).sqrt()
    } else {
        v / a + a / j
    }
}

#[test]
fn a_killed_jog_client_stops_the_axis_by_the_dead_mans_switch() {
    let env = env("deadman", false);
    let _d = env.start_daemon("kerfd");
    let speed = 50.0;
    let mut jog = Proc::start(
        "jog",
        &env.dir,
        env.kerf_command(&["jog"], &["X+", "--speed", "50"]),
    );
    // Wait until it moves at its speed, then kill the client without a word.
    let deadline = Instant::now() + PATIENCE;
    let mut last = x(&env);
    loop {
        std::thread::sleep(Duration::from_millis(300));
        let x = x(&env);
        if x - last > 0.0 && x > 20.0 {
            break;
        }
        last = x;
        assert!(Instant::now() < deadline, "the jog never moved");
        assert!(
            jog.try_wait().is_none(),
            "kerf jog exited: {}",
            jog.stderr()
        );
    }
    jog.signal("KILL");
    let _ = jog.wait_within(PATIENCE);
    let x_killed = x(&env);
    // It comes to rest by itself: within the dead-man time (100 ms, [jog] deadman_ms) at
    // the jog's speed plus the stop from it (X: 2000 mm/s², 50000 mm/s³), measured from
    // a position read after the kill.
    let deadline = Instant::now() + PATIENCE;
    loop {
        let s = env.status();
        if s["axes"]["x"]["jogging"] == false && s["state"] == "idle" {
            break;
        }
        assert!(Instant::now() < deadline, "the axis never stopped: {s}");
        std::thread::sleep(Duration::from_millis(20));
    }
    let x_rest = x(&env);
    let bound = speed * 0.1 + speed * stop_time_s(speed, 2000.0, 50_000.0) / 2.0;
    assert!(
        x_rest - x_killed <= bound + 1e-9,
        "moved {} mm after the kill, bound {bound}",
        x_rest - x_killed
    );
    assert!(x_rest >= x_killed);
}

#[test]
fn bad_jogs_and_homing_requests_are_refused_with_the_reason() {
    let env = env("bad", false);
    let _d = env.start_daemon("kerfd");
    let x0 = x(&env);
    for (args, words) in [
        (vec!["Q+"], "unknown axis"),
        (vec!["X"], "needs a direction"),
        (
            vec!["X+", "--speed", "1000"],
            "above axis X's velocity limit",
        ),
        (vec!["X", "--step", "0"], "other than 0"),
        (vec!["X+", "--to", "3"], "without a direction"),
        (vec!["A+"], "no axis A"),
    ] {
        let o = env.kerf(&["jog"], &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(words), "{args:?}: {}", stderr(&o));
    }
    let o = env.kerf(&["home"], &["W"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("unknown axis"), "{}", stderr(&o));
    assert_eq!(x(&env), x0, "nothing moved");
}
