//! The real-time cycle: commands and planned items in, one setpoint out per period, with
//! the drive side and the black box.

mod by_hand;
mod commands;
mod manual;
mod program;
mod report;

pub use manual::ManualStatus;
pub(crate) use manual::{Manual, simulated_switches};

use super::*;
use kerf_drive::safety::Check;
use kerf_geom::PerAxis;

use super::fieldbus::{BusCounters, BusReport, BusTrip, Fieldbus, MachineDrive, Recovered};

/// A program the cycle is running.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ProgramRun {
    id: u64,
    aborted: bool,
    cycle: u64,
    refusal: Option<Refusal>,
    /// Set when the program must not move at all (it starts elsewhere).
    dropped: bool,
    /// Planned items (segments, dwells) taken for the motion so far.
    planned: u64,
}

/// The setpoint of one cycle as the daemon publishes it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleOutput {
    /// Cycle number since the daemon started (1 for the first).
    pub seq: u64,
    /// The setpoint.
    pub setpoint: Setpoint,
    /// Per-axis velocity, by the backward difference of the positions, per s.
    pub velocity: PerAxis<f64>,
    /// The program this setpoint belongs to (0: none).
    pub program_id: u64,
    /// Cycles of that program so far (its program time is this × period); 0 while the
    /// program waits for its lookahead window.
    pub program_cycle: u64,
    /// What the machine is doing.
    pub state: u32,
    /// Periods since the start in which no cycle ran (see [`Cycle::missed`]).
    pub missed_periods: u64,
}

impl CycleOutput {
    /// Writes this cycle into the published message (`time_ns`: the cycle's deadline on
    /// CLOCK_MONOTONIC); the message's other fields (version, axes) stay.
    pub fn fill(&self, msg: &mut SetpointMsg, time_ns: u64) {
        msg.state = self.state;
        msg.seq = self.seq;
        msg.time_ns = time_ns;
        msg.program_id = self.program_id;
        msg.program_cycle = self.program_cycle;
        msg.position_mm_deg = self.setpoint.position;
        msg.velocity_mm_deg_s = self.velocity;
        msg.feed_mm_s = self.setpoint.feed_mm_s;
        msg.line = self.setpoint.line;
        msg.missed_periods = self.missed_periods;
    }
}

/// Commands taken per cycle at most (the rest wait for the next cycle).
pub(crate) const COMMANDS_PER_CYCLE: usize = 8;

/// The ends of the rings that carry black-box dumps out of the cycle and their rings back.
pub struct DumpRings {
    /// Finished dumps, to the thread that writes them.
    pub dumps: rtrb::Producer<Dump>,
    /// Rings written and given back.
    pub spares: rtrb::Consumer<Box<Recorder>>,
}

/// The other ends of [`DumpRings`], for the thread that writes the dumps.
pub struct DumpWriterRings {
    /// Finished dumps.
    pub dumps: rtrb::Consumer<Dump>,
    /// Where written rings go back.
    pub spares: rtrb::Producer<Box<Recorder>>,
}

/// The two rings between the cycle and the dump writer (a dump is two boxes at most:
/// one being written, one waiting).
pub fn dump_rings() -> (DumpRings, DumpWriterRings) {
    let (dumps_tx, dumps_rx) = rtrb::RingBuffer::new(2);
    let (spares_tx, spares_rx) = rtrb::RingBuffer::new(2);
    (
        DumpRings {
            dumps: dumps_tx,
            spares: spares_rx,
        },
        DumpWriterRings {
            dumps: dumps_rx,
            spares: spares_tx,
        },
    )
}

/// The drive stage of `config`'s machine, the safety layer and the black box: with an
/// `[ethercat]` table, each axis's drive on the bus (its process-data image); else a
/// simulated drive per axis whose motor stands at `position` at power-up.
pub fn drive_stage(
    config: &Config,
    position: PerAxis<f64>,
) -> Result<DriveStage<MachineDrive>, String> {
    let setups = config.drive_configs();
    let sims = config.axis_setups();
    let mut images = match config.ethercat() {
        Some(ec) => Some(kerf_ethercat::bus::Bus::drive_images(ec).map_err(|e| e.to_string())?),
        None => None,
    };
    let mut axes: [Option<AxisDrive<MachineDrive>>; 6] = [None, None, None, None, None, None];
    for (i, (slot, setup)) in axes.iter_mut().zip(setups.iter()).enumerate() {
        let Some(setup) = setup else { continue };
        let name = kerf_plan::AXIS_NAMES[i];
        if let Some(images) = images.as_mut() {
            let image = images
                .get_mut(i)
                .and_then(Option::take)
                .ok_or_else(|| format!("axis {name}: no drive on the EtherCAT bus"))?;
            *slot = Some(AxisDrive {
                drive: MachineDrive::Ethercat(image),
                scale: setup.scale,
                enable_timeout_cycles: setup.enable_timeout_cycles,
            });
            continue;
        }
        // The simulated motor's power-up position: the caller's plus the configured one.
        let start = position[i] + sims[i].map_or(0.0, |s| s.sim.start_units);
        let counts = setup
            .scale
            .to_counts(start)
            .map_err(|e| format!("axis {name}: the start position: {e}"))?;
        let sim = kerf_drive::sim::SimConfig {
            initial_position_counts: f64::from(counts),
            ..setup.sim
        };
        let mut drive = SimDrive::new(sim);
        // A drive that homes itself (CiA 402 homing mode) gets its homing objects.
        if let Some(h) = config.sim_homing(i) {
            drive.set_homing_config(h);
        }
        *slot = Some(AxisDrive {
            drive: MachineDrive::Sim(drive),
            scale: setup.scale,
            enable_timeout_cycles: setup.enable_timeout_cycles,
        });
    }
    DriveStage::new(axes, config.safety_config(), config.recorder_capacity())
        .map_err(|e| e.to_string())
}

/// The real-time cycle: commands and planned items in, one setpoint out per period;
/// allocation-free once built.
///
/// After the motion core's step, the drive stage (`kerf_drive::stage`) checks the setpoint
/// and sends it to the drives; what the cycle publishes is what the drives were sent.
/// Programs wait until every drive is enabled, and start from the drives' actual
/// positions; a trip of the safety layer drops the running program, the drives ramp to
/// rest on the quick stop and the motion core rests where they stopped; programs are
/// refused until `kerf reset` clears the fault.
pub struct Cycle {
    interp: Interpolator,
    tracker: Tracker,
    period_s: f64,
    items: rtrb::Consumer<RtItem>,
    commands: rtrb::Consumer<CycleCommand>,
    status: rtrb::Producer<Snapshot>,
    program: Option<ProgramRun>,
    /// The last program's id, why it stopped early, and whether it was aborted.
    last_program: (u64, Option<Refusal>, bool),
    /// The last program ended in this cycle (a safety trip in the same cycle is its).
    ended_this_cycle: bool,
    /// Programs to abort when they begin (their abort came before their beginning); 0 =
    /// free slot.
    pending_abort: [u64; PENDING_ABORTS],
    /// The feed override in force, percent.
    override_pct: f64,
    /// Commands taken from the command ring and applied since the start.
    commands_applied: u64,
    /// Periods in which no cycle ran, since the start.
    missed_periods: u64,
    cycles: u64,
    /// The last setpoint of the motion core (the machine's position between programs).
    setpoint: Setpoint,
    /// The position sent to the drives in the last cycle.
    sent: PerAxis<f64>,
    starved: bool,
    shutting_down: bool,
    shut_down: bool,
    /// Estimated motion time of the queued segments.
    queued: QueuedTime,
    stage: DriveStage<MachineDrive>,
    /// The EtherCAT bus, when the drives are on one.
    bus: Option<Fieldbus>,
    /// A reset waiting for the bus to come back to OP.
    bus_reset_tag: Option<u64>,
    /// The host time at which this cycle was to start (`CLOCK_MONOTONIC`, ns): the
    /// distributed clocks' measurement is against it.
    cycle_start_ns: u64,
    dump_rings: DumpRings,
    /// A finished dump the dump ring had no room for.
    dump_waiting: Option<Dump>,
    /// The reset asked for (its tag) and the last reset's outcome.
    reset_tag: Option<u64>,
    last_reset: Option<(u64, Result<(), ResetRefused>)>,
    /// Injected faults still to apply.
    stall_left: u32,
    step: Option<(usize, f64)>,
    /// Cycles since a shutdown asked the drives to power off.
    disable_wait: u32,
    /// Whether any drive keeps its own time (see [`Cycle::missed`]).
    drives_keep_time: bool,
    /// The machine around the axes: spindle, coolant, tool changer, I/O, pauses.
    machine: Machine,
    /// The machine's fault was passed to the drive stage (it latches once).
    machine_fault_tripped: bool,
    /// Whether the feed override was enabled (M48–M50) in the last cycle.
    feed_override_enabled: bool,
    /// The last wait on an input seen ended (its sequence number) and the program it
    /// ended in.
    input_result: (u64, u64),
    /// Jogging, homing and the axes' switches.
    manual: Manual,
    /// Where the running program paused, when the operator has jogged since: the program
    /// goes on only once the axes are back there.
    paused_at: Option<PerAxis<f64>>,
    /// Cycle start was pressed while the axes were away from `paused_at`: the way back
    /// runs, then the program resumes.
    resume_after_return: bool,
    /// The drives' actual positions of the last cycle (machine coordinates).
    actual: PerAxis<f64>,
    /// Set while the planning thread works through messages it has received (see
    /// [`Cycle::watch_planner`]); without it a program's motion starts only with a full
    /// queue or its end.
    planner_behind: Option<Arc<AtomicBool>>,
}

impl Cycle {
    /// A cycle for the machine of `config`; the simulated drives' motors stand at
    /// `position` at power-up, and the motion core starts where the drives report once
    /// they are enabled.
    pub fn new(
        config: &Config,
        position: PerAxis<f64>,
        items: rtrb::Consumer<RtItem>,
        commands: rtrb::Consumer<CycleCommand>,
        status: rtrb::Producer<Snapshot>,
        dump_rings: DumpRings,
    ) -> Result<Self, String> {
        let limits = kerf_config::machine_limits(config);
        let capacity = config.daemon.queue_segments as usize;
        let mut stage = drive_stage(config, position)?;
        let mut manual = Manual::new(config, &limits, position)?;
        // An absolute encoder's axis knows its machine coordinates from the start.
        for (i, offset) in manual.absolute_offsets().iter().enumerate() {
            if let Some(o) = offset {
                stage.set_offset(i, *o);
            }
        }
        for (i, on) in manual.soft_limits().iter().enumerate() {
            stage.set_soft_limits(i, *on);
        }
        let start = stage.command();
        manual.rest_at(&start);
        let mut core = MotionCore::new(limits.period_s, capacity);
        core.set_position(start);
        let machine = Machine::new(crate::machine::machine_config(config)?)
            .map_err(|e| format!("the machine's configuration: {e}"))?;
        Ok(Cycle {
            interp: Interpolator::new(core),
            tracker: Tracker::with_capacity(kerf_pipeline::tracked_moves(capacity)),
            period_s: limits.period_s,
            items,
            commands,
            status,
            program: None,
            last_program: (0, None, false),
            ended_this_cycle: false,
            pending_abort: [0; PENDING_ABORTS],
            override_pct: 100.0,
            commands_applied: 0,
            missed_periods: 0,
            cycles: 0,
            setpoint: Setpoint {
                position: start,
                ..Setpoint::default()
            },
            sent: start,
            starved: false,
            shutting_down: false,
            shut_down: false,
            queued: QueuedTime::with_capacity(capacity),
            stage,
            bus: None,
            bus_reset_tag: None,
            cycle_start_ns: 0,
            dump_rings,
            dump_waiting: None,
            reset_tag: None,
            last_reset: None,
            stall_left: 0,
            step: None,
            disable_wait: 0,
            drives_keep_time: config
                .drive_configs()
                .iter()
                .flatten()
                .any(|d| d.kind.keeps_time()),
            machine,
            machine_fault_tripped: false,
            feed_override_enabled: true,
            input_result: (0, 0),
            manual,
            actual: start,
            paused_at: None,
            resume_after_return: false,
            planner_behind: None,
        })
    }

    /// Lets a program's motion start before the queue is full while `behind` says the
    /// planning thread is still working through what it has received
    /// ([`PlanningCounters::behind`]): once the queue holds
    /// [`kerf_pipeline::START_LEAD_S`] of motion and its lookahead has settled, the
    /// segments still to come change nothing of the motion ahead (see
    /// [`kerf_pipeline::Interpolator::feed`]).
    pub fn watch_planner(&mut self, behind: Arc<AtomicBool>) {
        self.planner_behind = Some(behind);
    }

    /// The drive stage (for tests: its black box and drives).
    pub fn stage(&self) -> &DriveStage<MachineDrive> {
        &self.stage
    }

    /// The machine around the axes (for tests: its outputs and spindle).
    pub fn machine(&self) -> &Machine {
        &self.machine
    }

    /// Brings the EtherCAT bus of `config` (if any) to OP: the last step before the first
    /// period, as from OP on the drives' process-data watchdog expects a frame every
    /// period. On the cycle thread.
    pub fn start_bus(&mut self, config: &Config) -> Result<(), String> {
        self.bus = Fieldbus::start(config)?;
        Ok(())
    }

    /// The EtherCAT bus's exchange counters, when the drives are on one.
    pub fn bus_counters(&self) -> Option<BusCounters> {
        self.bus.as_ref().map(Fieldbus::counters)
    }

    /// The EtherCAT bus as the status shows it, when the drives are on one.
    pub fn bus_report(&self) -> Option<BusReport> {
        self.bus.as_ref().map(Fieldbus::report)
    }

    /// With distributed clocks: the host time at which the cycle's clock must start.
    pub fn first_cycle_start_ns(&self) -> Option<u64> {
        self.bus.as_ref().and_then(Fieldbus::first_cycle_start_ns)
    }

    /// Sets the host time at which the coming cycle was to start (its deadline).
    pub fn begin(&mut self, start_ns: u64) {
        self.cycle_start_ns = start_ns;
    }

    /// With distributed clocks: the correction of the next cycle's start, ns (taken
    /// once); 0 without.
    pub fn take_clock_correction_ns(&mut self) -> i64 {
        self.bus.as_mut().map_or(0, Fieldbus::take_correction_ns)
    }

    /// Whether a reset must first bring the EtherCAT bus (if any) back to OP.
    pub(crate) fn bus_needs_recovery(&self) -> bool {
        self.bus.as_ref().is_some_and(Fieldbus::needs_recovery)
    }

    /// Periods the cycle did not run (its deadline was missed). A drive that keeps its own
    /// time (a fieldbus drive) got no setpoint in each: the drive side runs a cycle
    /// without one (the drives hold; the safety layer counts them, at most
    /// `stall_cycles + 1`, enough to trip). The simulated drives have no clock of their
    /// own: their time is the cycle's, and a late cycle delays them with it, so nothing
    /// was missed. Every missed period is counted in the setpoints (`missed_periods`).
    /// Allocation-free.
    pub fn missed(&mut self, periods: u64) {
        self.missed_periods += periods;
        if !self.drives_keep_time {
            return;
        }
        let n = periods.min(u64::from(self.stage.safety().config().stall_cycles) + 1);
        for _ in 0..n {
            // The periods are gone: no frame went out in them, and none is sent now to
            // make up (that would only make this cycle later still).
            self.drive_cycle(None, false);
        }
    }

    /// `true` once a shutdown has brought the machine to rest.
    pub(crate) fn shut_down(&self) -> bool {
        self.shut_down
    }

    /// Runs one period: takes commands and planned items without blocking, steps the
    /// motion, and returns the setpoint. Never allocates, locks or blocks.
    pub fn run(&mut self) -> CycleOutput {
        self.cycles += 1;
        self.ended_this_cycle = false;
        let mut commands = [None; COMMANDS_PER_CYCLE];
        for slot in commands.iter_mut() {
            match self.commands.pop() {
                Ok(c) => *slot = Some(c),
                Err(_) => break,
            }
        }
        // The machine's models advance one period; the spindle is watched while the
        // last setpoint fed.
        let feeding = self.setpoint.feed_mm_s > 0.0 && !self.setpoint.rapid;
        // The inputs and the spindle drive's speed of the last exchange.
        if let Some(bus) = self.bus.as_ref() {
            bus.receive_machine(&mut self.machine);
        }
        self.machine.cycle(feeding);
        self.check_hard_limits();
        if self.program.is_none() {
            self.begin_next();
        }
        let previous = self.sent;
        // Feeding comes before the commands, as in `kerf sim`, where an event applies
        // after the cycle's feeding and before its step.
        let mut started = match self.program {
            Some(p) if !p.dropped => self.feed(),
            _ => false,
        };
        if started && self.program.is_some_and(|p| p.planned == 0) && self.interp.source_ended() {
            // Nothing of the program was planned (refused at its first move, or empty):
            // it ends without a moving cycle.
            started = false;
            self.end_program();
        }
        for c in commands.iter().flatten() {
            self.apply(*c);
        }
        let mut program_id = self.last_program.0;
        let mut program_cycle = 0;
        self.apply_feed_override_enable();
        let mut previous = previous;
        let manual_moves = self.manual.active() && self.stage.ready();
        if self.paused_at.is_some() {
            // A paused program whose axes the operator jogged: the motion core stays where
            // the program paused, the axes move by hand (or stand where they were jogged).
            if manual_moves {
                self.manual_step();
            }
            self.finish_return();
            if let Some(p) = self.program.as_mut() {
                p.cycle += 1;
                program_id = p.id;
                program_cycle = p.cycle;
            }
            started = false;
        } else if !started && self.program.is_none() && manual_moves {
            for (i, d) in self.manual_step().iter().enumerate() {
                // Homing redefined the axis's coordinates: no motion.
                previous[i] += d;
            }
        }
        if started {
            let mut sp = Setpoint::default();
            self.interp.step(&mut sp);
            self.interp.fire_synced(&mut self.machine);
            self.tracker.track(&mut sp);
            self.setpoint = sp;
            // Forget the estimated times of the segments the core has finished.
            self.queued.keep_last(self.interp.core().queued());
            if let Some(p) = self.program.as_mut() {
                p.cycle += 1;
                program_id = p.id;
                program_cycle = p.cycle;
            }
            if self.interp.finished() {
                self.end_program();
            }
        } else {
            // At rest (idle, or a program waiting for its lookahead window).
            self.setpoint.feed_mm_s = 0.0;
            if let Some(p) = self.program {
                program_id = p.id;
                if p.dropped && self.drain_dropped() {
                    self.end_program();
                }
            }
        }
        self.check_machine();
        // The drive side: the setpoint (unless an injected stall withholds it, or an
        // injected step moves it) goes through the safety layer to the drives.
        let setpoint = if self.stall_left > 0 {
            self.stall_left -= 1;
            None
        } else {
            let mut p = self.setpoint.position;
            if let Some((axis, mm)) = self.step.take() {
                p[axis] += mm;
            }
            Some(p)
        };
        self.drive_cycle(setpoint, true);
        let position = self.sent;
        let mut velocity = [0.0; 6];
        for (v, (p, q)) in velocity
            .iter_mut()
            .zip(position.iter().zip(previous.iter()))
        {
            *v = (p - q) / self.period_s;
        }
        if self.shutting_down && self.program.is_none() && self.interp.core().is_idle() {
            // At rest: the drives are powered off (the brakes hold), then the cycle ends.
            if self.disable_wait == 0 {
                self.stage.request_disable();
            }
            self.disable_wait += 1;
            self.shut_down = self.stage.disabled() || self.disable_wait > DISABLE_WAIT_CYCLES;
        }
        let state = self.state();
        self.report(state);
        let mut sp = self.setpoint;
        sp.position = position;
        CycleOutput {
            seq: self.cycles,
            setpoint: sp,
            velocity,
            program_id,
            program_cycle,
            state: state.as_u32(),
            missed_periods: self.missed_periods,
        }
    }

    /// One cycle of the drive side with `setpoint` (`None`: a missed cycle); `exchange`:
    /// whether the fieldbus (if any) exchanges in it.
    fn drive_cycle(&mut self, setpoint: Option<PerAxis<f64>>, exchange: bool) {
        if let Some(bus) = self.bus.as_mut() {
            if bus.inputs_stale() {
                self.stage.feedback_stale();
            }
            if !exchange {
                bus.skipped();
            }
        }
        let out = self.stage.cycle(&StageInput {
            setpoint,
            line: self.setpoint.line,
            time_s: self.cycles as f64 * self.period_s,
        });
        // The outputs just written go out, the inputs for the next cycle come back.
        if exchange && let Some(bus) = self.bus.as_mut() {
            let line = self.setpoint.line;
            // The machine's outputs and the spindle's setpoint go out with the drives'.
            let spindle = bus.send_machine(&self.machine, &self.stage);
            let fault = match bus.exchange(&mut self.stage, self.cycle_start_ns) {
                Some(BusTrip::Missed { in_row, limit }) => {
                    self.stage.trip_fieldbus(in_row, limit, line)
                }
                Some(BusTrip::LeftOp { position, code }) => {
                    self.stage.trip_subdevice(position, code, line)
                }
                None => None,
            };
            let fault = fault.or_else(|| {
                let (check, value, limit) = spindle?.check();
                self.stage.trip_machine(check, value, limit, line)
            });
            let recovered = bus.recover();
            if let Some(f) = fault {
                self.safety_stop(f);
            }
            match (recovered, self.bus_reset_tag) {
                (Some(Recovered::Done), Some(tag)) => {
                    self.bus_reset_tag = None;
                    self.reset_tag = Some(tag);
                    self.stage.request_reset();
                }
                (Some(Recovered::Refused(why)), Some(tag)) => {
                    self.bus_reset_tag = None;
                    self.last_reset = Some((tag, Err(why)));
                }
                _ => {}
            }
        }
        self.actual = out.actual;
        for (i, homed) in out.homed_by_drive.iter().enumerate() {
            if let Some(p) = *homed {
                // The drive redefined its coordinates: the axis rests where it reports.
                self.setpoint.position[i] = p;
                self.sent[i] = p;
                self.manual.drive_homed(i, p);
            }
        }
        if self.bus.is_none() {
            // The simulated machine's switches follow its motors.
            let mut drive = out.actual;
            for (i, d) in drive.iter_mut().enumerate() {
                *d -= self.stage.offset(i);
            }
            self.manual.simulate_switches(&drive, &mut self.machine);
        }
        if let Some(p) = out.enabled_at {
            self.rest_at(p);
        }
        if let Some(f) = out.tripped {
            self.safety_stop(f);
        }
        if self.stage.fault().is_some() {
            // The drives follow the quick stop; the motion core rests where they are.
            self.rest_at(out.command);
        }
        if let Some(r) = out.reset
            && let Some(tag) = self.reset_tag.take()
        {
            if r.is_ok() {
                // The drives are back: the machine's own fault (if any) clears with them.
                self.machine.reset();
                self.machine_fault_tripped = false;
                // An axis on a hard limit switch may now be jogged off it.
                self.manual.after_reset(self.machine.io());
            }
            self.last_reset = Some((tag, r));
        }
        self.sent = out.command;
        while let Ok(ring) = self.dump_rings.spares.pop() {
            self.stage.return_spare(ring);
        }
        if self.dump_waiting.is_none() {
            self.dump_waiting = self.stage.take_dump();
        }
        if let Some(d) = self.dump_waiting.take()
            && let Err(rtrb::PushError::Full(d)) = self.dump_rings.dumps.push(d)
        {
            self.dump_waiting = Some(d);
        }
    }

    /// The motion core (and every axis's manual mover) drops everything and rests at
    /// `position`.
    fn rest_at(&mut self, position: PerAxis<f64>) {
        self.interp.core_mut().reset_to(position);
        self.manual.rest_at(&position);
        self.setpoint.position = position;
        self.setpoint.feed_mm_s = 0.0;
    }

    /// A fault of the machine (the spindle, the tool changer) latches in the drive stage
    /// once, as any fault: the axes stop on the quick stop and the program is dropped.
    fn check_machine(&mut self) {
        use kerf_drive::machine::MachineFault as F;
        let Some(fault) = self.machine.fault() else {
            return;
        };
        if self.machine_fault_tripped {
            return;
        }
        self.machine_fault_tripped = true;
        let line = match fault.line() {
            0 => self.setpoint.line,
            l => l,
        };
        // A spindle on outputs without feedback has no actual speed to report: 0.
        let rpm = |actual: Option<f64>| actual.unwrap_or(0.0);
        let (check, value, limit) = match fault {
            F::SpindleNotAtSpeed {
                commanded_rpm,
                actual_rpm,
                ..
            } => (Check::SpindleAtSpeed, rpm(actual_rpm), commanded_rpm),
            F::SpindleOutOfBand {
                commanded_rpm,
                actual_rpm,
                ..
            } => (Check::SpindleBand, rpm(actual_rpm), commanded_rpm),
            F::SpindleNotStopped { actual_rpm, .. } => {
                (Check::SpindleAtSpeed, rpm(actual_rpm), 0.0)
            }
            F::OrientTimeout { timeout_s, .. } => (Check::SpindleOrient, timeout_s, timeout_s),
            F::ToolChangeTimeout { tool, waited_s, .. } => {
                (Check::ToolChange, f64::from(tool), waited_s)
            }
            _ => (Check::SpindleAtSpeed, 0.0, 0.0),
        };
        if let Some(f) = self.stage.trip_machine(check, value, limit, line) {
            self.safety_stop(f);
        }
    }

    /// The feed override applies while enabled (M48, M50); disabled, the motion runs at
    /// 100 %.
    fn apply_feed_override_enable(&mut self) {
        let enabled = self.machine.feed_override_enabled();
        if enabled == self.feed_override_enabled {
            return;
        }
        self.feed_override_enabled = enabled;
        self.interp
            .apply(OperatorEvent::Override(self.feed_override_factor()));
    }

    /// The feed override in force, as a factor: the operator's while enabled (M48, M50),
    /// else 1.
    fn feed_override_factor(&self) -> f64 {
        if self.feed_override_enabled {
            self.override_pct / 100.0
        } else {
            1.0
        }
    }

    /// The safety layer tripped: the program is dropped (its rest is refused), the
    /// motion core forgets its queue.
    fn safety_stop(&mut self, fault: Fault) {
        self.manual.abort();
        self.machine
            .end_program(kerf_drive::machine::EndCause::Fault);
        if let Some(p) = self.program.as_mut() {
            p.refusal = Some(Refusal::Safety(fault));
            self.interp.apply(OperatorEvent::Abort);
            self.interp.next_program();
            self.tracker.clear();
            self.end_program();
        } else if self.ended_this_cycle && self.last_program.1.is_none() {
            // The setpoint of the program's last cycle tripped: the program did not
            // finish, whatever its motion reported.
            self.last_program.1 = Some(Refusal::Safety(fault));
        }
    }
}

/// Programs the cycle remembers to abort when they begin (one moving, one received and
/// waiting, one being received, and a spare).
pub(crate) const PENDING_ABORTS: usize = 4;

/// How far (mm or degrees, any axis) a program may start from the machine's position.
pub(crate) const START_TOL: f64 = 1e-6;

/// Cycles a shutdown waits for the drives to power off before the cycle ends anyway.
pub(crate) const DISABLE_WAIT_CYCLES: u32 = 1000;

/// The estimated motion times of the segments in the motion queue, in push order, and
/// their sum: preallocated for the whole queue, so that it never allocates.
pub(crate) struct QueuedTime {
    times_s: std::collections::VecDeque<f64>,
    sum_s: f64,
}

impl QueuedTime {
    fn with_capacity(segments: usize) -> Self {
        QueuedTime {
            times_s: std::collections::VecDeque::with_capacity(segments),
            sum_s: 0.0,
        }
    }

    /// Adds a pushed segment's time (never beyond the reserved capacity).
    fn push(&mut self, t_s: f64) {
        if self.times_s.len() < self.times_s.capacity() {
            self.times_s.push_back(t_s);
            self.sum_s += t_s;
        }
    }

    /// Forgets all but the `n` segments pushed last (the core has finished the others).
    fn keep_last(&mut self, n: usize) {
        while self.times_s.len() > n {
            if let Some(t) = self.times_s.pop_front() {
                self.sum_s -= t;
            }
        }
        if self.times_s.is_empty() {
            self.sum_s = 0.0;
        }
    }
}
