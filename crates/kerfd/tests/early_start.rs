//! When the daemon's cycle opens a program's motion, measured from what it sends out every
//! period. The planning worker and the cycle run in one thread, the worker handed a few
//! of the program's messages between two cycles: a planner slower than the cycle fills
//! the queue, as on code slow to plan (a dense surface whose every vertex is a corner).
//!
//! - While the planning thread says it is behind (`PlanningCounters::behind`), the motion
//!   starts before the program's end has arrived and the queue is full, once 1 s of motion
//!   is queued and the lookahead has settled, and the setpoints are those of the same
//!   program handed over whole before the first cycle (which starts with its end).
//! - While it is not behind (a client sending slower than the daemon plans), the motion
//!   waits for the program's end, as the protocol says, with the same setpoints again.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use kerf_config::Config;
use kerf_geom::PerAxis;

mod common;

/// The bundled machine (1 kHz, 4,096-segment queue), homed at start.
fn config() -> Config {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/kerf.toml");
    let text = kerf_testkit::config_text::without_homing(&std::fs::read_to_string(root).unwrap());
    Config::from_toml_str(&text, "kerf.toml").expect("the test machine")
}

/// A rough finishing pass: 400 moves of 0.3 mm along X, each vertex 0.03 to 0.06 mm off
/// the row in Y (beyond the 0.01 mm tolerance, so every one is a corner), at F3000.
fn rough_pass() -> String {
    let mut text = String::from("G21 G90 G64 P0.01\nG1 X0 Y0 Z0 F3000\n");
    for k in 1..=400 {
        let off = [0.03, -0.05, 0.06, -0.04][k % 4];
        text.push_str(&format!("X{:.3} Y{off:.3}\n", 0.3 * k as f64));
    }
    text.push_str("M2\n");
    text
}

/// How the motion of one run went.
struct Run {
    /// The positions sent while the program moved, from its first cycle on.
    positions: Vec<PerAxis<f64>>,
    /// Messages handed to the planning worker when the program's first cycle ran.
    handed_at_start: usize,
    messages: usize,
}

/// Runs `text`, handing the planning worker `per_cycle` messages before each cycle
/// (`None`: all before the first), with the planning thread's `behind` flag as given.
fn run(text: &str, per_cycle: Option<usize>, behind: bool) -> Run {
    let config = config();
    let mut w = common::wire(&config, 1 << 16);
    w.cycle.watch_planner(Arc::new(AtomicBool::new(behind)));
    let messages =
        common::program_messages(&config, 1, [0.0; 6], text, kerf_gcode::Dialect::LinuxCnc);
    let total = messages.len();
    let mut messages = messages.into_iter();
    let mut handed = 0;
    let mut out = Run {
        positions: Vec::new(),
        handed_at_start: 0,
        messages: total,
    };
    for _ in 0..200_000 {
        for _ in 0..per_cycle.unwrap_or(usize::MAX) {
            let Some(m) = messages.next() else { break };
            assert!(w.planning.handle(m), "the planning worker stopped");
            handed += 1;
        }
        let o = w.cycle.run();
        if o.program_cycle > 0 {
            if out.positions.is_empty() {
                out.handed_at_start = handed;
            }
            out.positions.push(o.setpoint.position);
        } else if !out.positions.is_empty() {
            // At rest after the program.
            return out;
        }
    }
    panic!("the program did not end");
}

#[test]
fn a_planner_behind_starts_the_motion_early_with_the_setpoints_of_a_full_start() {
    let text = rough_pass();
    let whole = run(&text, None, true);
    assert_eq!(whole.handed_at_start, whole.messages);
    // The motion is long enough for the question: more than the 1 s lead.
    assert!(whole.positions.len() > 3000, "{}", whole.positions.len());
    for per_cycle in [1, 2, 5] {
        let behind = run(&text, Some(per_cycle), true);
        assert!(
            behind.handed_at_start < behind.messages / 2,
            "{per_cycle} a cycle: the motion started after {} of {} messages",
            behind.handed_at_start,
            behind.messages
        );
        assert_eq!(
            behind.positions.len(),
            whole.positions.len(),
            "{per_cycle} a cycle"
        );
        if let Some(k) =
            (0..whole.positions.len()).find(|&k| behind.positions[k] != whole.positions[k])
        {
            panic!(
                "{per_cycle} a cycle: setpoint {k} of the motion differs: {:?} against {:?}",
                behind.positions[k], whole.positions[k]
            );
        }
        // A client that sends slowly, the planner idle: the motion waits for the end (the
        // program's M2, the message before END).
        let trickle = run(&text, Some(per_cycle), false);
        assert!(
            trickle.handed_at_start + 1 >= trickle.messages,
            "{per_cycle} a cycle: the motion started after {} of {} messages",
            trickle.handed_at_start,
            trickle.messages
        );
        assert!(trickle.positions == whole.positions, "{per_cycle} a cycle");
    }
}
