//! Helpers shared by the daemon's in-process tests (`drives.rs`, `daemon_alloc.rs`,
//! `machine.rs`).

use kerf_config::Config;
use kerf_proto::{MoveMsg, Resolved, StreamCheck};
use kerfd::worker::{Incoming, Planning};

/// Feeds program `id` (LinuxCNC text, starting at `start`) to the planning worker the way
/// the daemon's planning thread does: every item as a message through the stream check.
pub fn feed_program(
    planning: &mut Planning,
    config: &Config,
    id: u64,
    start: [f64; 6],
    text: &str,
) {
    feed_program_in(
        planning,
        config,
        id,
        start,
        text,
        kerf_gcode::Dialect::LinuxCnc,
    );
}

/// [`feed_program`] for a program in `dialect`.
pub fn feed_program_in(
    planning: &mut Planning,
    config: &Config,
    id: u64,
    start: [f64; 6],
    text: &str,
    dialect: kerf_gcode::Dialect,
) {
    let mut check = StreamCheck::new();
    let mut settings = config.settings();
    settings.start_mm_deg = start;
    let mut handle = |msg: MoveMsg| {
        let incoming = match check.check(&msg).expect("a valid message") {
            Resolved::Begin {
                program_id,
                start_mm_deg,
                ..
            } => Incoming::Begin {
                program_id,
                start: start_mm_deg,
            },
            Resolved::Move(m) => Incoming::Move(m),
            Resolved::Event(e) => Incoming::Event(e),
            Resolved::End { .. } => Incoming::End,
        };
        assert!(planning.handle(incoming), "the planning worker stopped");
    };
    handle(MoveMsg::begin(id, start, 0));
    let mut seq = 0;
    for item in kerf_gcode::Interpreter::new(text.as_bytes(), dialect, settings) {
        let item = item.expect("the program is valid");
        seq += 1;
        handle(MoveMsg::from_item(id, seq, &item));
    }
    handle(MoveMsg::end(id, seq));
}
