//! The control thread: answers requests on the control service with the latest snapshot
//! of the cycle and turns commands into items of the command ring.

use super::*;
use crate::dump_writer::DumpWriter;
use crate::status::{axes_mask, idle_snapshot, status_msg};

/// The control thread's ends of the rings: commands to the cycle, its status snapshots,
/// and the black-box rings it fills.
pub(crate) struct ControlPorts {
    pub(crate) commands: rtrb::Producer<CycleCommand>,
    pub(crate) status: rtrb::Consumer<Snapshot>,
    pub(crate) dumps: worker::DumpWriterRings,
}

/// The control thread's loop; `test_faults` accepts the fault injections of the tests.
pub(crate) fn control_thread(
    config: &Config,
    shared: Shared,
    test_faults: bool,
    ready: Ready,
    ports: ControlPorts,
) -> Result<(), String> {
    let machine = config.machine.as_str();
    let Shared {
        stop,
        shutdown,
        done,
        counters,
        overruns,
        rt_ok,
        ..
    } = shared;
    let ControlPorts {
        mut commands,
        status,
        mut dumps,
    } = ports;
    let setup = || -> Result<_, StartError> {
        let node = ipc::node("kerfd-control")?;
        let service = ipc::create_control(&node, machine)?;
        // The control service has one server slot: taken means a live daemon serves the
        // machine (a dead one's was removed with its node).
        let server = service
            .server_builder()
            .create()
            .map_err(|_| StartError::AlreadyRunning(machine.to_string()))?;
        // The wake-ups: a client's request wakes this thread, an answer wakes the client.
        let events = ipc::create_control_events(&node, machine)?;
        let woken = events.request.listener_builder().create().map_err(|e| {
            StartError::Ipc(ipc::IpcError::refused("cannot listen for requests", e))
        })?;
        let answered = events
            .answer
            .notifier_builder()
            .create()
            .map_err(|e| StartError::Ipc(ipc::IpcError::refused("cannot notify answers", e)))?;
        Ok((node, service, server, events, woken, answered))
    };
    let (_node, _service, server, _events, woken, answered) = match setup() {
        Ok(ports) => {
            let _ = ready.send(Ok(None));
            ports
        }
        Err(e) => {
            let message = e.to_string();
            let _ = ready.send(Err(e));
            return Err(message);
        }
    };

    // The waits for the cycle and for requests are short: end them on time.
    if let Err(e) = kerf_rt::fine_timer_slack() {
        tracing::warn!(
            "the control thread's timer slack stays at its default ({e}): answers may come up to 50 µs later"
        );
    }
    let period_ns = config.period_us as u64 * 1000;
    let axes_mask = axes_mask(config);
    let window = config.daemon.move_window as u64;
    let mut writer = DumpWriter::new(config);
    let mut requests = Requests {
        test_faults,
        reset_patience: reset_patience(config),
        dump_patience: dump_patience(config),
        hold_requested: false,
        next_tag: 1,
        pushed: 0,
        inputs: machine::SimInputs::of(config),
        manual: worker::Manual::new(config, &kerf_config::machine_limits(config), [0.0; 6])?,
    };
    let apply_patience = apply_patience(config);
    let mut view = CycleView {
        ring: status,
        latest: idle_snapshot(),
        counters: counters.clone(),
    };
    let mut rt_flag = 0u32;
    let mut shutdown_sent = false;
    // Requests wait until the cycle has run once: by then every port (moves, setpoints)
    // is up, so a client that got an answer can open them all (`kerfd` is ready when
    // `kerf status` answers).
    let mut cycle_runs = false;
    let mut saved_tool = machine::load_tool(&config.state_file()).unwrap_or(0);
    let mut tools = machine::ToolLengths::of(config);
    let mut state_warned = false;
    loop {
        cycle_runs |= view.pull();
        writer.take(&mut dumps, None);
        if view.latest.state != MachineState::Holding && view.latest.program_done {
            // The program is over: a hold asked for during it is void.
            requests.hold_requested = false;
        }
        let tool = view.latest.machine.tool_in_spindle;
        if cycle_runs && tool != saved_tool {
            // The tool in the spindle survives a restart: written as soon as it changes.
            match machine::save_tool(&config.state_file(), tool) {
                Ok(()) => saved_tool = tool,
                Err(e) => {
                    if !state_warned {
                        tracing::error!(
                            "cannot keep the tool in the spindle (T{tool}) in {}: {e}; after a restart the daemon will not know it",
                            config.state_file().display()
                        );
                        state_warned = true;
                    }
                }
            }
        }
        while cycle_runs && let Ok(Some(active)) = server.receive() {
            let request = *active.payload();
            let (reason, message, fate) = requests.carry_out(
                &request,
                &mut commands,
                &mut view,
                &mut writer,
                &mut dumps,
                &counters,
            );
            // The answer carries the status after the request: wait until the cycle has
            // applied every command pushed so far.
            let applied = poll_cycle(&mut view, apply_patience, |s| {
                (s.commands_applied >= requests.pushed).then_some(())
            });
            if applied.is_none() {
                tracing::warn!(
                    "the real-time cycle did not apply a command within {apply_patience:?}"
                );
            }
            let mut msg = status_msg(
                &view.latest,
                &counters,
                rt_flag,
                overruns.load(Ordering::Acquire),
                window,
                axes_mask,
                period_ns,
            );
            tools.refresh(config);
            machine::fill_status(&mut msg, &view.latest.machine, config, &tools);
            msg.input_result_program = view.latest.input_result_program;
            if view.latest.drives.fault.is_some()
                && let Some(path) = writer.fault_path()
            {
                msg.set_fault_dump(&path.display().to_string());
            }
            let mut response = Response::new(request.id, reason, &message, msg);
            response.program_fate = fate;
            let _ = active.send_copy(response);
            // Wakes the clients waiting for an answer (each looks whether it is its own).
            let _ = answered.notify();
        }
        if rt_flag == 0 && rt_ok.load(Ordering::Acquire) {
            rt_flag = 1;
        }
        if shutdown.load(Ordering::Acquire) && !shutdown_sent {
            shutdown_sent = commands.push(CycleCommand::Shutdown).is_ok();
            // The program being received ends too: the planning thread drops its rest and
            // ends it, so that the cycle can come to rest and stop.
            counters
                .abort
                .store(counters.open.load(Ordering::Acquire), Ordering::Release);
        }
        if view.latest.shut_down || stop.load(Ordering::Acquire) {
            done.store(true, Ordering::Release);
            stop.store(true, Ordering::Release);
            return Ok(());
        }
        // Until the next look: a request's notification ends the wait at once.
        if woken.timed_wait(|_| {}, POLL).is_err() {
            std::thread::sleep(POLL);
        }
    }
}

/// What the control thread keeps between requests.
struct Requests {
    /// Fault injections are accepted (`kerfd --test-faults`).
    test_faults: bool,
    reset_patience: Duration,
    dump_patience: Duration,
    /// A hold was asked for and neither resumed nor made void by the program's end.
    hold_requested: bool,
    /// The tag of the next reset or dump.
    next_tag: u64,
    /// Commands pushed to the cycle so far: an answer waits until the cycle has applied
    /// its command, so that its status is the status after the request.
    pushed: u64,
    /// Which inputs an operator (or a test) may set: the simulated ones.
    inputs: machine::SimInputs,
    /// The machine's axes as jogging sees them: the checks of a jog request.
    manual: worker::Manual,
}

impl Requests {
    /// Carries out one request: the answer's reason, message and program fate.
    fn carry_out(
        &mut self,
        request: &kerf_proto::Request,
        commands: &mut rtrb::Producer<CycleCommand>,
        view: &mut CycleView,
        writer: &mut DumpWriter,
        dumps: &mut worker::DumpWriterRings,
        counters: &PlanningCounters,
    ) -> (u32, String, u32) {
        let mut fate = kerf_proto::PROGRAM_FATE_UNKNOWN;
        let pushed = &mut self.pushed;
        let mut push = |commands: &mut rtrb::Producer<CycleCommand>, c: CycleCommand| {
            let answer = push_command(commands, c);
            if answer.0 == REASON_OK {
                *pushed += 1;
            }
            answer
        };
        let (reason, message) = match request.command() {
            Err(e) => (e.reason(), e.to_string()),
            Ok(ControlCommand::Status) => (REASON_OK, String::new()),
            Ok(ControlCommand::Program { program_id }) => {
                let f = lock_fates(counters).get(program_id);
                fate = f.code;
                (REASON_OK, f.reason)
            }
            Ok(ControlCommand::Hold) => {
                let latest = &view.latest;
                // No program yet (id 0) or the last one is over: nothing to hold.
                if latest.state == MachineState::Idle
                    && (latest.program_done || latest.program_id == 0)
                {
                    (
                        REASON_NOT_ALLOWED,
                        "nothing to hold: no program is running".to_string(),
                    )
                } else {
                    self.hold_requested = true;
                    push(commands, CycleCommand::Hold)
                }
            }
            Ok(ControlCommand::Resume) => {
                let held = self.hold_requested || view.latest.state == MachineState::Holding;
                if held || view.latest.waits_for_operator() {
                    self.hold_requested = false;
                    push(commands, CycleCommand::Resume)
                } else {
                    (
                        REASON_NOT_ALLOWED,
                        "nothing to resume: not holding, and no pause waits for cycle start"
                            .to_string(),
                    )
                }
            }
            Ok(ControlCommand::Switch { switch, on }) => {
                if switch == kerf_proto::Switch::SingleBlock {
                    counters.single_block.store(on, Ordering::Release);
                }
                push(commands, CycleCommand::Switch(switch, on))
            }
            Ok(ControlCommand::SpindleOverride { percent }) => {
                push(commands, CycleCommand::SpindleOverride(percent))
            }
            Ok(ControlCommand::SetInput {
                analog,
                index,
                value,
            }) => match self.inputs.check(analog, index) {
                Ok(()) => push(
                    commands,
                    CycleCommand::SetInput {
                        analog,
                        index: index as u8,
                        value,
                    },
                ),
                Err(why) => (REASON_NOT_ALLOWED, why),
            },
            Ok(ControlCommand::Abort) => {
                self.hold_requested = false;
                // Every program not yet over ends: the one moving, and the one being
                // received (which the planning thread stops taking at once). The plain
                // abort is for the moving one even when the fates have forgotten it
                // (256 BEGINs since, refused ones included); aborting it twice is
                // harmless.
                let open = counters.open.load(Ordering::Acquire);
                let unfinished = lock_fates(counters).unfinished();
                counters.abort.store(open, Ordering::Release);
                let mut answer = push(commands, CycleCommand::Abort);
                for id in unfinished {
                    if answer.0 == REASON_OK {
                        answer = push(commands, CycleCommand::AbortProgram(id));
                    }
                }
                answer
            }
            Ok(ControlCommand::Override { percent }) => {
                push(commands, CycleCommand::Override(percent))
            }
            Ok(ControlCommand::Jog { axis, jog, speed }) => {
                let axis = usize::from(axis);
                let latest = &view.latest;
                let position = latest.position[axis];
                match manual_refusal(latest, "jog", latest.waits_for_operator()).map_or_else(
                    || {
                        let m = &latest.manual;
                        let bit = 1u32 << axis;
                        let released = match (m.limit_released & bit, m.min_limit_switches & bit) {
                            (0, _) => 0,
                            (_, 0) => 1,
                            _ => -1,
                        };
                        self.manual
                            .check_jog(axis, jog, speed, position, m.homed & bit != 0, released)
                            .err()
                    },
                    Some,
                ) {
                    Some(why) => (REASON_NOT_ALLOWED, why),
                    None => push(commands, CycleCommand::Jog { axis, jog, speed }),
                }
            }
            Ok(ControlCommand::JogStop { axis }) => {
                push(commands, CycleCommand::JogStop(usize::from(axis)))
            }
            Ok(ControlCommand::Home { axes }) => {
                let latest = &view.latest;
                let missing = (0..6).find(|i| axes & (1 << i) != 0 && !self.manual.has_axis(*i));
                if let Some(i) = missing {
                    (
                        REASON_NOT_ALLOWED,
                        format!("this machine has no axis {}", kerf_geom::AXIS_NAMES[i]),
                    )
                } else if let Some(why) = manual_refusal(latest, "home", false) {
                    (REASON_NOT_ALLOWED, why)
                } else if latest.manual.jogging != 0 {
                    (
                        REASON_NOT_ALLOWED,
                        "cannot home: an axis is jogging".to_string(),
                    )
                } else {
                    push(commands, CycleCommand::Home(axes))
                }
            }
            Ok(ControlCommand::Reset) => {
                let tag = self.next_tag;
                self.next_tag += 1;
                match push(commands, CycleCommand::Reset(tag)) {
                    (REASON_OK, _) => {
                        wait_reset(view, writer, dumps, tag, self.reset_patience)
                    }
                    refused => refused,
                }
            }
            Ok(ControlCommand::Dump) => {
                let tag = self.next_tag;
                self.next_tag += 1;
                match push(commands, CycleCommand::Dump(tag)) {
                    (REASON_OK, _) => {
                        let waited = wait_dump(view, writer, dumps, tag, self.dump_patience);
                        match waited {
                            Ok(path) => (REASON_OK, path.display().to_string()),
                            Err(e) => (REASON_NOT_ALLOWED, e),
                        }
                    }
                    refused => refused,
                }
            }
            Ok(ControlCommand::Inject { code }) => match worker::Injection::from_code(code) {
                _ if !self.test_faults => (
                    REASON_NOT_ALLOWED,
                    "fault injection is for tests only: this kerfd was not started with --test-faults".to_string(),
                ),
                Some(i) => push(commands, CycleCommand::Inject(i)),
                None => (
                    kerf_proto::REASON_BAD_VALUE,
                    format!("unknown injection code {code}"),
                ),
            },
        };
        (reason, message, fate)
    }
}

/// Why a jog or homing (`what`) is refused in the machine's present state, if it is: a
/// fault latched, a program running (unless `paused_ok` and it waits for cycle start),
/// homing under way.
fn manual_refusal(latest: &Snapshot, what: &str, paused_ok: bool) -> Option<String> {
    if latest.drives.fault.is_some() {
        return Some(format!(
            "cannot {what}: a fault is latched; clear it with `kerf reset`"
        ));
    }
    if latest.drives.phase != kerf_drive::stage::Phase::Active {
        return Some(format!("cannot {what}: the drives are not enabled yet"));
    }
    let program_runs = latest.program_id != 0 && !latest.program_done;
    let idle = matches!(latest.state, MachineState::Idle | MachineState::Manual);
    let paused = paused_ok && latest.state == MachineState::Paused;
    if !paused && (program_runs || !idle) {
        return Some(format!(
            "cannot {what} while a program runs ({}): jog when the machine is idle or the program waits for cycle start, home when it is idle",
            latest.state.as_str()
        ));
    }
    if latest.manual.homing != 0 {
        return Some(format!("cannot {what}: the machine is homing"));
    }
    None
}

pub(crate) fn lock_fates(counters: &PlanningCounters) -> std::sync::MutexGuard<'_, fates::Fates> {
    // A panic while holding the lock leaves a consistent table: take it anyway.
    counters
        .fates
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The control thread's view of the cycle: the snapshots it reports, the latest one, and
/// what they tell of each program's end (recorded in the fates; a program refused when
/// it would start is counted as refused).
pub(crate) struct CycleView {
    ring: rtrb::Consumer<Snapshot>,
    latest: Snapshot,
    counters: PlanningCounters,
}

impl CycleView {
    /// Takes every snapshot the cycle reported; `true` if there was one.
    pub(crate) fn pull(&mut self) -> bool {
        let mut got = false;
        while let Ok(s) = self.ring.pop() {
            self.observe(&s);
            self.latest = s;
            got = true;
        }
        got
    }

    pub(crate) fn observe(&self, s: &Snapshot) {
        if s.program_id == 0 || !s.program_done {
            return;
        }
        let (code, reason) = match (s.aborted, s.refusal) {
            (true, _) => (
                kerf_proto::PROGRAM_FATE_ABORTED,
                "aborted: the motion stopped on the path and the rest of the program was dropped"
                    .to_string(),
            ),
            (false, Some(r)) => (kerf_proto::PROGRAM_FATE_REFUSED, r.to_string()),
            (false, None) => (kerf_proto::PROGRAM_FATE_FINISHED, String::new()),
        };
        let changed = lock_fates(&self.counters).end(s.program_id, code, reason);
        if changed
            && !s.aborted
            && matches!(
                s.refusal,
                Some(Refusal::WrongStart { .. } | Refusal::Faulted(_))
            )
        {
            // Its BEGIN was refused when the program would have started.
            self.counters.refused.fetch_add(1, Ordering::AcqRel);
        }
    }
}

/// How long an answer waits for the cycle to apply its command: 100 periods, at least
/// 100 ms.
pub(crate) fn apply_patience(config: &Config) -> Duration {
    Duration::from_micros(u64::from(config.period_us) * 100).max(Duration::from_millis(100))
}

/// How long a reset may take: on an EtherCAT bus, bringing it back to OP (each subdevice's
/// state changes within `state_timeout_ms`); a fault reset and then the enable sequence
/// (four transitions), each within the drives' enable timeout; and a second more.
pub fn reset_patience(config: &Config) -> Duration {
    let bus = config.ethercat().map_or(Duration::ZERO, |b| {
        Duration::from_millis(u64::from(b.state_timeout_ms))
    });
    let period = Duration::from_micros(u64::from(config.period_us));
    let max_enable_cycles = config
        .drive_configs()
        .iter()
        .flatten()
        .map(|d| d.enable_timeout_cycles)
        .max()
        .unwrap_or(1);
    period.saturating_mul(max_enable_cycles.saturating_mul(5).saturating_add(16))
        + bus
        + Duration::from_secs(1)
}

/// How long a black-box dump may take: the copy, a chunk per cycle, the writing, and a
/// second more.
pub fn dump_patience(config: &Config) -> Duration {
    let period = Duration::from_micros(u64::from(config.period_us));
    let cycles = config.recorder_capacity() / kerf_drive::stage::DUMP_CHUNK + 16;
    period.saturating_mul(u32::try_from(cycles).unwrap_or(u32::MAX)) + Duration::from_secs(2)
}

/// Polls the cycle every [`APPLY_POLL`] (the latest status snapshot into `latest`) until
/// `outcome` has an answer, at most `patience`; `None` if it ran out.
pub(crate) fn poll_cycle<T>(
    view: &mut CycleView,
    patience: Duration,
    mut outcome: impl FnMut(&Snapshot) -> Option<T>,
) -> Option<T> {
    let deadline = Instant::now() + patience;
    loop {
        view.pull();
        if let Some(answer) = outcome(&view.latest) {
            return Some(answer);
        }
        if Instant::now() > deadline {
            return None;
        }
        std::thread::sleep(APPLY_POLL);
    }
}

/// How often a request waiting for the cycle (a command to be applied, a reset, a dump)
/// looks at its snapshots: the cycle applies a command at its next period, so the answer
/// waits at most this much longer than the cycle took. Only while a request waits.
pub(crate) const APPLY_POLL: Duration = Duration::from_micros(20);

/// Waits for the outcome of reset `tag` (the status snapshots carry it), writing the
/// dumps that come out meanwhile.
pub(crate) fn wait_reset(
    view: &mut CycleView,
    writer: &mut DumpWriter,
    dumps: &mut worker::DumpWriterRings,
    tag: u64,
    patience: Duration,
) -> (u32, String) {
    let outcome = poll_cycle(view, patience, |s| {
        writer.take(dumps, None);
        match s.reset {
            Some((t, Ok(()))) if t == tag => Some((REASON_OK, String::new())),
            Some((t, Err(e))) if t == tag => Some((REASON_NOT_ALLOWED, e.to_string())),
            _ => None,
        }
    });
    outcome.unwrap_or_else(|| {
        (
            REASON_NOT_ALLOWED,
            "reset: no outcome from the real-time cycle in time".to_string(),
        )
    })
}

/// Waits for dump `tag` and writes it; its file.
pub(crate) fn wait_dump(
    view: &mut CycleView,
    writer: &mut DumpWriter,
    dumps: &mut worker::DumpWriterRings,
    tag: u64,
    patience: Duration,
) -> Result<std::path::PathBuf, String> {
    poll_cycle(view, patience, |_| writer.take(dumps, Some(tag))).unwrap_or_else(|| {
        Err("dump: the black box did not come out of the real-time cycle in time".to_string())
    })
}

pub(crate) fn push_command(
    commands: &mut rtrb::Producer<CycleCommand>,
    c: CycleCommand,
) -> (u32, String) {
    match commands.push(c) {
        Ok(()) => (REASON_OK, String::new()),
        Err(_) => (
            REASON_NOT_ALLOWED,
            "the command queue is full; try again".to_string(),
        ),
    }
}
