//! The planning thread: takes messages off the moves service, applies the stream rules
//! that span programs, and hands the rest to the planning worker.

use super::*;
use crate::control::lock_fates;

/// The planning thread's loop (public for the throughput bench in `benches/`).
pub fn planning_thread(
    config: &Config,
    machine: &str,
    window: usize,
    ready: Ready,
    stop: Arc<AtomicBool>,
    counters: PlanningCounters,
    items: rtrb::Producer<RtItem>,
) -> Result<(), String> {
    let setup = || -> Result<_, ipc::IpcError> {
        let node = ipc::node("kerfd-planning")?;
        let service = ipc::create_moves(&node, machine, window)?;
        let subscriber = ipc::move_subscriber(&service, window)?;
        Ok((node, service, subscriber))
    };
    let (_node, service, subscriber) = match setup() {
        Ok(ports) => {
            let _ = ready.send(Ok(None));
            ports
        }
        Err(e) => {
            let message = e.to_string();
            let _ = ready.send(Err(StartError::Ipc(e)));
            return Err(message);
        }
    };
    let mut planning = Planning::new(config, items, stop.clone(), &counters);
    let mut intake = Intake {
        check: StreamCheck::new(),
        current: 0,
        dropping: false,
    };
    let mut last_message = Instant::now();
    let mut last_sender_check = Instant::now();
    loop {
        if stop.load(Ordering::Acquire) {
            return Ok(());
        }
        let mut got = false;
        loop {
            let msg: MoveMsg = match subscriber.receive() {
                Ok(Some(sample)) => *sample,
                Ok(None) => {
                    counters.behind.store(false, Ordering::Relaxed);
                    break;
                }
                Err(e) => return Err(format!("receiving moves: {e:?}")),
            };
            // Behind: a second message waited while the first was planned (a client that
            // sends one at a time, slower than the planning, never sets it).
            counters.behind.store(got, Ordering::Relaxed);
            got = true;
            if let Some(incoming) = take_message(&msg, &mut intake, &counters)
                && !planning.handle(incoming)
            {
                return Ok(());
            }
            if planning.dropping() && intake.check.program_id().is_some() {
                // The program was refused: it is over, its rest is dropped.
                intake.check.reset();
                intake.dropping = true;
            }
            if intake.check.program_id().is_none() {
                counters.open.store(0, Ordering::Release);
            }
            // An abort of the open program drops the rest of it at once.
            if !abort_open(&mut planning, &mut intake, &counters) {
                return Ok(());
            }
        }
        if !abort_open(&mut planning, &mut intake, &counters) {
            return Ok(());
        }
        let now = Instant::now();
        if got {
            last_message = now;
            continue;
        }
        if planning.in_program()
            && now.duration_since(last_message) > SENDER_CHECK_AFTER
            && now.duration_since(last_sender_check) > SENDER_CHECK_AFTER
        {
            last_sender_check = now;
            ipc::clean_dead_nodes();
            if service.dynamic_config().number_of_publishers() == 0 {
                intake.check.reset();
                counters.open.store(0, Ordering::Release);
                if !planning.handle(Incoming::SenderGone) {
                    return Ok(());
                }
            }
        }
        std::thread::sleep(POLL);
    }
}

/// The planning thread's side of the stream rules that span programs: the stream check
/// of the open program and the program whose items count in `moves_received`.
pub(crate) struct Intake {
    check: StreamCheck,
    /// The open program, or the one stopped early whose rest is being dropped; 0 none.
    current: u64,
    /// The current program stopped early: its further items and END are dropped.
    dropping: bool,
}

/// A message refused without touching the open program: counted, logged, dropped.
pub(crate) fn refuse_alone(counters: &PlanningCounters, why: &StreamError) {
    counters.refused.fetch_add(1, Ordering::AcqRel);
    tracing::warn!("message refused: {why}");
}

/// Applies the stream rules that span programs to one message and returns what the
/// planning worker gets of it (`None`: refused or dropped here, see PROTOCOL.md's stream
/// rules 1, 2 and 6).
pub(crate) fn take_message(
    msg: &MoveMsg,
    intake: &mut Intake,
    counters: &PlanningCounters,
) -> Option<Incoming> {
    let id = msg.program_id;
    let open = intake.check.program_id();
    if msg.kind == kerf_proto::KIND_BEGIN {
        if let Some(open) = open {
            let why = StreamError::UnexpectedBegin { open, found: id };
            refuse_alone(counters, &why);
            lock_fates(counters).begin(id, Some(why.to_string()));
            return None;
        }
        if id != 0 && lock_fates(counters).knows(id) {
            refuse_alone(counters, &StreamError::RepeatedId { program_id: id });
            return None;
        }
        return match intake.check.check(msg) {
            Ok(Resolved::Begin {
                program_id,
                start_mm_deg,
                ..
            }) => {
                counters.received.store(0, Ordering::Release);
                counters.open.store(program_id, Ordering::Release);
                intake.current = program_id;
                intake.dropping = false;
                lock_fates(counters).begin(program_id, None);
                Some(Incoming::Begin {
                    program_id,
                    start: start_mm_deg,
                })
            }
            Ok(_) => None,
            Err(why) => {
                refuse_alone(counters, &why);
                lock_fates(counters).begin(id, Some(format!("message refused: {why}")));
                None
            }
        };
    }
    let item = msg.kind != kerf_proto::KIND_END;
    if intake.dropping && open.is_none() && id == intake.current {
        // The rest of a program stopped early: taken (for its client's flow control) and
        // dropped, up to its END.
        if item {
            counters.received.fetch_add(1, Ordering::AcqRel);
        } else {
            intake.dropping = false;
        }
        return None;
    }
    match open {
        Some(open) if open == id => {}
        Some(open) => {
            refuse_alone(
                counters,
                &StreamError::WrongProgram {
                    expected: open,
                    found: id,
                },
            );
            return None;
        }
        None => {
            refuse_alone(counters, &StreamError::NoBegin { program_id: id });
            return None;
        }
    }
    if item {
        counters.received.fetch_add(1, Ordering::AcqRel);
    }
    Some(match intake.check.check(msg) {
        Ok(Resolved::Move(m)) => Incoming::Move(m),
        Ok(Resolved::Event(e)) => Incoming::Event(e),
        Ok(Resolved::End { .. }) => {
            lock_fates(counters).received(id);
            Incoming::End
        }
        Ok(Resolved::Begin { .. }) => return None,
        Err(e) => {
            intake.check.reset();
            intake.dropping = true;
            Incoming::Rejected(e)
        }
    })
}

/// Ends the open program if the control thread asked for its abort. Returns `false` if
/// the worker must stop.
pub(crate) fn abort_open(
    planning: &mut Planning,
    intake: &mut Intake,
    counters: &PlanningCounters,
) -> bool {
    let id = counters.abort.swap(0, Ordering::AcqRel);
    if id == 0 || id != intake.current || intake.check.program_id() != Some(id) {
        return true;
    }
    intake.check.reset();
    intake.dropping = true;
    counters.open.store(0, Ordering::Release);
    planning.abort()
}
