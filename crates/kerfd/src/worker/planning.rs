//! The planning worker: received items → checked moves → the planner → the ring of
//! planned items to the cycle.

use super::*;

/// Periods to wait between polls while the ring to the cycle is full.
pub(crate) const RING_FULL_WAIT: Duration = Duration::from_micros(200);

/// The planning worker's side of the ring to the cycle; the worker stops when `stop` is
/// set.
pub struct Planning {
    limits: MachineLimits,
    axes: Axes,
    out: rtrb::Producer<RtItem>,
    stop: Arc<AtomicBool>,
    /// Messages refused since the daemon started.
    refused: Arc<AtomicU64>,
    planner: Option<Planner>,
    /// The current program was stopped early: its remaining items are dropped until the
    /// next one begins.
    failed: bool,
    buf: Vec<PlannedSegment>,
    /// Moves taken by the planner and not yet sent to the cycle.
    taken: std::collections::VecDeque<Move>,
    /// Program index (0-based) of `taken[0]`.
    taken_base: u64,
    /// The program's modal machine state (spindle, coolant, tool), which turns its
    /// events into actions.
    actions: ProgramActions,
    /// Where the actions synchronised with the motion go among the segments.
    order: ActionOrder,
    /// What the machine can do (events it cannot are refused).
    caps: kerf_config::MachineCaps,
    /// The single-block switch, set by the control thread.
    single_block: Arc<AtomicBool>,
    /// The source line of the last block planned (for single block: a pause goes between
    /// two blocks); 0 before the first.
    last_line: u32,
}

/// Counters the planning worker shares with the control thread.
#[derive(Clone, Debug, Default)]
pub struct PlanningCounters {
    /// Items (not BEGIN or END) of the current program taken off the moves service.
    pub received: Arc<AtomicU64>,
    /// Messages refused since start.
    pub refused: Arc<AtomicU64>,
    /// The program being received (its BEGIN accepted, neither its END received nor
    /// stopped early); 0 when none.
    pub open: Arc<AtomicU64>,
    /// A program to abort, set by the control thread; the planning thread drops the rest
    /// of it (when it is the open one) and clears this.
    pub abort: Arc<AtomicU64>,
    /// What became of the last programs.
    pub fates: Arc<std::sync::Mutex<crate::fates::Fates>>,
    /// The single-block switch: while on, the planning thread puts a pause after every
    /// block it plans.
    pub single_block: Arc<AtomicBool>,
    /// The planning thread is working through a backlog of messages (set when the moves
    /// service hands it another message right after one it planned, cleared when it has
    /// none): the cycle may then start a program's motion before the queue is full
    /// ([`kerf_pipeline::Poll::Planning`]).
    pub behind: Arc<AtomicBool>,
}

impl Planning {
    /// A worker for the machine of `config`, feeding `out`.
    pub fn new(
        config: &Config,
        out: rtrb::Producer<RtItem>,
        stop: Arc<AtomicBool>,
        counters: &PlanningCounters,
    ) -> Self {
        Planning {
            limits: kerf_config::machine_limits(config),
            axes: config.axes,
            out,
            stop,
            refused: counters.refused.clone(),
            planner: None,
            failed: false,
            buf: Vec::new(),
            taken: std::collections::VecDeque::new(),
            taken_base: 0,
            actions: ProgramActions::new(),
            order: ActionOrder::new(),
            caps: config.machine_check(),
            single_block: counters.single_block.clone(),
            last_line: 0,
        }
    }

    /// `true` while a program is being received.
    pub(crate) fn in_program(&self) -> bool {
        self.planner.is_some()
    }

    /// `true` after the current program was stopped early: its remaining messages are
    /// dropped until the next program begins.
    pub fn dropping(&self) -> bool {
        self.failed
    }

    /// Drops the rest of the open program after an abort: nothing more of it is planned,
    /// and the cycle (which aborted the motion) gets its end. Returns `false` if told to
    /// stop.
    pub fn abort(&mut self) -> bool {
        if self.planner.is_none() || self.failed {
            return true;
        }
        tracing::info!("program aborted: the rest of it is dropped");
        self.buf.clear();
        self.taken.clear();
        self.failed = true;
        self.send(RtItem::End(None))
    }

    /// Handles one incoming item. Returns `false` once the worker must stop.
    pub fn handle(&mut self, item: Incoming) -> bool {
        match item {
            Incoming::Begin { program_id, start } => {
                if self.planner.is_some() && !self.failed {
                    self.fail(Refusal::Interrupted);
                }
                self.failed = false;
                self.taken.clear();
                self.taken_base = 0;
                self.actions = ProgramActions::new();
                self.order = ActionOrder::new();
                self.last_line = 0;
                self.planner = Some(Planner::new(self.limits));
                self.send(RtItem::Begin { program_id, start })
            }
            Incoming::Move(m) => {
                if self.failed || self.planner.is_none() {
                    return true;
                }
                let [wait, input] = self.actions.item(&kerf_geom::Item::Move(m));
                self.block(m.line)
                    && wait.is_none_or(|w| self.input(w))
                    && input.is_none_or(|i| self.input(i))
            }
            Incoming::Event(e) => {
                if self.failed || self.planner.is_none() {
                    return true;
                }
                if self.caps.check_event(&e).is_err() {
                    return self.refuse(Refusal::Machine {
                        line: e.line,
                        code: e.code,
                        value: e.value.unwrap_or(0.0),
                    });
                }
                let Some(input) = self.actions.event(&e) else {
                    return true;
                };
                self.block(e.line) && self.input(input)
            }
            Incoming::End => match self.planner.take() {
                Some(mut planner) if !self.failed => {
                    planner.finish(&mut self.buf);
                    self.planner = Some(planner);
                    let ok = self.flush();
                    self.planner = None;
                    ok && self.release() && self.send(RtItem::End(None))
                }
                _ => {
                    self.planner = None;
                    true
                }
            },
            Incoming::Rejected(reject) => {
                self.refused.fetch_add(1, Ordering::AcqRel);
                tracing::warn!("message refused: {reject}");
                if self.planner.is_some() && !self.failed {
                    self.fail(Refusal::Message(reject))
                } else {
                    true
                }
            }
            Incoming::SenderGone => {
                if self.planner.is_some() && !self.failed {
                    tracing::warn!("the planner process went away in the middle of a program");
                    let ok = self.fail(Refusal::SenderGone);
                    self.planner = None;
                    ok
                } else {
                    self.planner = None;
                    true
                }
            }
        }
    }

    /// A new block begins at `line`: with single block on, a pause ends the block before.
    /// Returns `false` if told to stop.
    fn block(&mut self, line: u32) -> bool {
        let previous = std::mem::replace(&mut self.last_line, line);
        if previous == 0 || previous == line || !self.single_block.load(Ordering::Acquire) {
            return true;
        }
        self.input(Input::Action(kerf_geom::machine::Action {
            line: previous,
            kind: kerf_geom::machine::ActionKind::Pause(kerf_geom::machine::PauseCode::SingleBlock),
        }))
    }

    /// Plans one input of the open program and sends what it yields: a move's segments
    /// (each after the moves taken before it), a dwell or an action after the segments
    /// before it; an action synchronised with the motion waits for the segments of the
    /// moves before it. A refused move stops the program. Returns `false` if told to stop.
    fn input(&mut self, input: Input) -> bool {
        if self.order.take_held(&input) {
            return true;
        }
        let m = match input {
            Input::Move(m) => Some(m),
            _ => None,
        };
        if let Err(r) = self.plan(&input, m.as_ref()) {
            return self.refuse(r);
        }
        if m.is_some() {
            self.order.moved();
        }
        if !self.flush() {
            return false;
        }
        let mut after = Vec::new();
        self.order.after(&input, &mut after);
        after.into_iter().all(|p| self.send(RtItem::Planned(p)))
    }

    /// Sends every held synchronised action (the path has ended at rest before them).
    fn release(&mut self) -> bool {
        let held: Vec<Planned> = self.order.release().collect();
        held.into_iter().all(|p| self.send(RtItem::Planned(p)))
    }

    /// A received move or event failed the daemon's own checks (travel, planning): the
    /// message is refused and counted like one the stream check refused, and the program
    /// stops at the end of its last valid move.
    fn refuse(&mut self, reason: Refusal) -> bool {
        self.refused.fetch_add(1, Ordering::AcqRel);
        self.fail(reason)
    }

    /// Validates and plans one input into `buf`.
    fn plan(&mut self, input: &Input, m: Option<&Move>) -> Result<(), Refusal> {
        if let Some(m) = m {
            check_move(m, &self.axes).map_err(Refusal::Travel)?;
        }
        let Some(planner) = self.planner.as_mut() else {
            return Ok(());
        };
        plan_input(planner, input, &mut self.buf).map_err(Refusal::Plan)?;
        if let Some(m) = m {
            self.taken.push_back(*m);
        }
        for seg in &self.buf {
            check_segment(seg, &self.axes).map_err(Refusal::PlannedTravel)?;
        }
        Ok(())
    }

    /// Sends the planned segments in `buf`, each after the programmed moves it needs
    /// tracked (its own, and the one after it, whose corner a blend may cut: what the
    /// cycle's tracker looks at for it), and no more: the planner may hold back 30 mm of
    /// moves or more (a smoothing run's design distance), which the cycle's tracker need
    /// not hold while the motion has not reached them.
    fn flush(&mut self) -> bool {
        let mut buf = std::mem::take(&mut self.buf);
        let mut ok = true;
        'segments: for seg in buf.drain(..) {
            let needed_to = seg.move_index + u64::from(seg.move_count);
            while self.taken_base <= needed_to
                && let Some(m) = self.taken.pop_front()
            {
                self.taken_base += 1;
                if !self.send(RtItem::Move(m)) {
                    ok = false;
                    break 'segments;
                }
            }
            let due: Vec<Planned> = self.order.before(&seg).collect();
            // The count of moves known is only used by the offline deviation check.
            let sent = due.into_iter().all(|p| self.send(RtItem::Planned(p)))
                && self.send(RtItem::Planned(Planned::Segment(seg, 0)));
            if !sent {
                ok = false;
                break;
            }
        }
        self.buf = buf;
        ok
    }

    /// Stops the current program at the end of its last valid move: the segments planned
    /// from the valid moves are sent (the planner holds back the end of the path for
    /// blending), then the end with the reason.
    fn fail(&mut self, reason: Refusal) -> bool {
        tracing::warn!("program stopped: {reason}");
        self.buf.clear();
        if let Some(planner) = self.planner.as_mut() {
            planner.finish(&mut self.buf);
        }
        // A segment planned from the valid moves that leaves the travel is dropped with
        // everything after it.
        if let Some(bad) = self
            .buf
            .iter()
            .position(|seg| check_segment(seg, &self.axes).is_err())
        {
            self.buf.truncate(bad);
        }
        self.failed = true;
        // Outputs synchronised with moves that will not run are dropped with them.
        self.order = ActionOrder::new();
        self.flush() && self.send(RtItem::End(Some(reason)))
    }

    /// Sends one item, waiting while the ring is full. Returns `false` if told to stop.
    fn send(&mut self, mut item: RtItem) -> bool {
        loop {
            match self.out.push(item) {
                Ok(()) => return true,
                Err(rtrb::PushError::Full(back)) => {
                    if self.stop.load(Ordering::Acquire) {
                        return false;
                    }
                    item = back;
                    std::thread::sleep(RING_FULL_WAIT);
                }
            }
        }
    }
}
