//! Helpers shared by the daemon's in-process tests (`drives.rs`, `daemon_alloc.rs`,
//! `machine.rs`, `manual.rs`).

#![allow(dead_code)]

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use kerf_config::Config;
use kerf_proto::{MoveMsg, Resolved, StreamCheck};
use kerfd::worker::{
    Cycle, CycleCommand, Incoming, Planning, PlanningCounters, RtItem, Snapshot, dump_rings,
};

/// The daemon's cycle and planning worker for `config`, wired as the daemon wires them
/// (the drives at 0), with the test's ends of the rings: commands in, snapshots out.
pub struct Wired {
    pub cycle: Cycle,
    pub planning: Planning,
    pub commands: rtrb::Producer<CycleCommand>,
    pub status: rtrb::Consumer<Snapshot>,
    pub counters: PlanningCounters,
}

/// [`Wired`] with a ring of `items` planned items between planning and the cycle (large
/// enough for a whole program where one thread plans it all before the cycle runs).
pub fn wire(config: &Config, items: usize) -> Wired {
    let (items_tx, items_rx) = rtrb::RingBuffer::<RtItem>::new(items);
    let (commands_tx, commands_rx) = rtrb::RingBuffer::<CycleCommand>::new(64);
    let (status_tx, status_rx) = rtrb::RingBuffer::<Snapshot>::new(1 << 16);
    let (dumps, _writer) = dump_rings();
    let cycle =
        Cycle::new(config, [0.0; 6], items_rx, commands_rx, status_tx, dumps).expect("a cycle");
    let counters = PlanningCounters::default();
    let planning = Planning::new(
        config,
        items_tx,
        Arc::new(AtomicBool::new(false)),
        &counters,
    );
    Wired {
        cycle,
        planning,
        commands: commands_tx,
        status: status_rx,
        counters,
    }
}

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
    for incoming in program_messages(config, id, start, text, dialect) {
        assert!(planning.handle(incoming), "the planning worker stopped");
    }
}

/// Program `id` (text in `dialect`, starting at `start`) as the planning thread hands it
/// to the planning worker: every item as a message through the stream check, BEGIN to END.
pub fn program_messages(
    config: &Config,
    id: u64,
    start: [f64; 6],
    text: &str,
    dialect: kerf_gcode::Dialect,
) -> Vec<Incoming> {
    let mut check = StreamCheck::new();
    let mut settings = config.settings();
    settings.start_mm_deg = start;
    let mut out = Vec::new();
    let mut take = |msg: MoveMsg| {
        out.push(match check.check(&msg).expect("a valid message") {
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
        });
    };
    take(MoveMsg::begin(id, start, 0));
    let mut seq = 0;
    for item in kerf_gcode::Interpreter::new(text.as_bytes(), dialect, settings) {
        let item = item.expect("the program is valid");
        seq += 1;
        take(MoveMsg::from_item(id, seq, &item));
    }
    take(MoveMsg::end(id, seq));
    out
}
