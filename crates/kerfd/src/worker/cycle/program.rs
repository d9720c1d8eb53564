//! Programs in the cycle: the next one begun at the machine's position, planned items fed
//! to the motion core, a program ended or its dropped rest drained.

use super::*;

impl Cycle {
    /// Starts the next program if its beginning is in the ring (it waits while the
    /// drives are being enabled, and is refused while a fault is latched).
    pub(super) fn begin_next(&mut self) {
        let Ok(RtItem::Begin { program_id, start }) = self.items.peek().copied() else {
            // Anything but a beginning while no program runs is the rest of an aborted
            // or refused program: dropped.
            while let Ok(item) = self.items.peek() {
                if matches!(item, RtItem::Begin { .. }) {
                    break;
                }
                let _ = self.items.pop();
            }
            return;
        };
        let fault = self.stage.fault().copied();
        if fault.is_none() && !self.stage.ready() {
            return;
        }
        let _ = self.items.pop();
        if let Some(f) = fault {
            self.program = Some(ProgramRun {
                id: program_id,
                aborted: false,
                cycle: 0,
                refusal: Some(Refusal::Faulted(f)),
                dropped: true,
                planned: 0,
            });
            return;
        }
        self.interp.next_program();
        self.tracker.clear();
        let aborted = self.pending_abort.contains(&program_id);
        if aborted {
            for slot in self.pending_abort.iter_mut().filter(|s| **s == program_id) {
                *slot = 0;
            }
        }
        let mut run = ProgramRun {
            id: program_id,
            aborted,
            cycle: 0,
            refusal: None,
            dropped: self.shutting_down || aborted,
            planned: 0,
        };
        // Programs start on a homed machine, off the limit switches, at rest.
        let manual = if self.manual.active() {
            Some(Refusal::ManualMotion)
        } else {
            self.manual.blocks_programs().map(|(i, on_limit)| {
                let axis = kerf_plan::AXIS_NAMES[i];
                if on_limit {
                    Refusal::OnLimitSwitch(axis)
                } else {
                    Refusal::NotHomed(axis)
                }
            })
        };
        if let Some(r) = manual
            && !aborted
        {
            run.refusal = Some(r);
            run.dropped = true;
            self.setpoint.line = 0;
            self.program = Some(run);
            return;
        }
        for (i, (&s, &p)) in start.iter().zip(self.setpoint.position.iter()).enumerate() {
            // A start that is not a number is refused too.
            let at_machine = (s - p).abs() <= START_TOL;
            if !at_machine && !aborted {
                run.refusal = Some(Refusal::WrongStart {
                    axis: kerf_plan::AXIS_NAMES[i],
                    start: s,
                    actual: p,
                });
                run.dropped = true;
                break;
            }
        }
        self.setpoint.line = 0;
        self.program = Some(run);
    }

    /// Drops the items of a program that must not move; `true` once its end was taken.
    pub(super) fn drain_dropped(&mut self) -> bool {
        loop {
            match self.items.peek() {
                Ok(RtItem::Begin { .. }) => return true,
                Ok(RtItem::End(_)) => {
                    let _ = self.items.pop();
                    return true;
                }
                Ok(RtItem::Planned(_) | RtItem::Move(_)) => {
                    let _ = self.items.pop();
                }
                Err(_) => return false,
            }
        }
    }

    /// Feeds the interpolator from the ring; returns whether the motion may step.
    pub(super) fn feed(&mut self) -> bool {
        let items = &mut self.items;
        let tracker = &mut self.tracker;
        let queued = &mut self.queued;
        let machine = &mut self.machine;
        let aborted = self.interp.aborted();
        // Nothing queued (not even a running segment): a full tracker cannot empty.
        let mut queue_empty = self.interp.core().queued() == 0;
        let mut refusal = None;
        let mut pending = false;
        let mut planned = 0u64;
        let behind = self
            .planner_behind
            .as_ref()
            .is_some_and(|b| b.load(Ordering::Relaxed));
        let result = self.interp.feed(
            || {
                loop {
                    let Ok(item) = items.peek() else {
                        pending = true;
                        return if behind {
                            Poll::Planning
                        } else {
                            Poll::Pending
                        };
                    };
                    match *item {
                        // The next program's beginning: this one ended without its end (cannot
                        // happen: the planning worker always ends a program before the next).
                        RtItem::Begin { .. } => return Poll::End,
                        // Programmed moves go to the tracker until the next planned item,
                        // by the rule `kerf sim` follows too.
                        RtItem::Move(m) => match tracker.taking(queue_empty, aborted) {
                            Taking::Wait => return Poll::Full,
                            Taking::Track => tracker.add(&m),
                            Taking::Untracked => {}
                        },
                        RtItem::Planned(p) => {
                            if let Planned::Segment(seg, _) = &p {
                                queued.push(kerf_pipeline::segment_time_s(seg));
                                queue_empty = false;
                            }
                            planned += 1;
                            let _ = items.pop();
                            return Poll::Ready(p);
                        }
                        RtItem::End(r) => {
                            refusal = r;
                            let _ = items.pop();
                            return Poll::End;
                        }
                    }
                    let _ = items.pop();
                }
            },
            machine,
        );
        if let Some(p) = self.program.as_mut() {
            p.planned += planned;
            if let Some(r) = refusal {
                p.refusal = Some(r);
            }
        }
        match result {
            Ok(started) => {
                self.starved = pending && started && !self.interp.source_ended();
                started
            }
            Err(RunError::Rejected { line }) => {
                if let Some(p) = self.program.as_mut() {
                    p.refusal.get_or_insert(Refusal::Core { line });
                }
                self.interp.apply(OperatorEvent::Abort);
                true
            }
            Err(_) => true,
        }
    }

    pub(super) fn end_program(&mut self) {
        if self.paused_at.take().is_some() {
            // Ended during a pause the operator jogged in: the motion core rests where
            // the axes are.
            self.resume_after_return = false;
            self.manual.abort();
            self.interp.core_mut().reset_to(self.setpoint.position);
        }
        if let Some(p) = self.program.take() {
            self.last_program = (p.id, p.refusal, p.aborted);
            self.ended_this_cycle = true;
        }
        self.starved = false;
        self.queued.keep_last(0);
    }
}
