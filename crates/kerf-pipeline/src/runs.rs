//! The offline runs: [`run`] (planning inline), [`run_parallel`] and [`run_stream`] (a
//! planning thread), [`run_planned`] (segments planned beforehand), each with its source.

use std::collections::VecDeque;

use kerf_geom::Move;
use kerf_motion::Setpoint;
use kerf_motion::monitor::LimitMonitor;
use kerf_plan::{MachineLimits, PlanError};

use crate::plan_step::PlanStep;
use crate::runner::{Runner, Source};
use crate::{Input, Planned, Poll, RunError, RunOptions, Sink, Summary};

/// The source of [`run`]: plans each input when the run asks for the next item.
struct Inline<I> {
    inputs: I,
    step: PlanStep,
    ready: VecDeque<Planned>,
    taken: VecDeque<Move>,
    error: Option<PlanError>,
}

impl<I: Iterator<Item = Input>> Source for Inline<I> {
    fn poll(&mut self) -> Poll {
        loop {
            if let Some(p) = self.ready.pop_front() {
                return Poll::Ready(p);
            }
            if self.error.is_some() {
                return Poll::End;
            }
            let Some(input) = self.inputs.next() else {
                self.step.finish(&mut self.ready);
                return match self.ready.pop_front() {
                    Some(p) => Poll::Ready(p),
                    None => Poll::End,
                };
            };
            if let Err(e) = self.step.input(&input, &mut self.taken, &mut self.ready) {
                self.error = Some(e);
                return Poll::End;
            }
        }
    }

    fn next_move(&mut self) -> Option<Move> {
        self.taken.pop_front()
    }

    fn take_error(&mut self) -> Option<PlanError> {
        self.error.take()
    }
}

/// Runs `moves` from rest at the origin; calls `sink(t, setpoint)` for every row, starting
/// with the row at t = 0. Returns what was measured.
pub fn run<I, F>(
    moves: I,
    limits: &MachineLimits,
    options: &RunOptions,
    sink: F,
) -> Result<Summary, RunError>
where
    I: IntoIterator,
    I::Item: Into<Input>,
    F: FnMut(f64, &Setpoint),
{
    let runner = Runner::new(limits, options, sink);
    let mut source = Inline {
        inputs: moves.into_iter().map(Into::into),
        step: PlanStep::new(limits, options.feed_override),
        ready: VecDeque::new(),
        taken: VecDeque::new(),
        error: None,
    };
    runner.run(&mut source)
}

/// Segments per message from the planning thread of [`run_parallel`].
const BATCH: usize = 256;

/// Moves per message at most from the planning thread of [`run_stream`] (a smoothing
/// window may take thousands of moves before it yields a segment).
const MOVES_PER_BATCH: usize = 4096;

/// A batch from the planning thread: the moves it took since the previous batch, in
/// program order, and the planned segments, each with the number of moves the planner had
/// taken when it produced the segment (so that the deviation check sees the same moves as
/// in [`run`]); or the error that stopped planning.
type Batch = Result<(Vec<Move>, Vec<Planned>), PlanError>;

/// [`run`] with the planner on a second thread: the same setpoints, bit for bit (the
/// feeding policy only depends on the order of the segments), in less wall time when a
/// second core is free. For programs held in memory; see [`run_stream`] for streams.
pub fn run_parallel<F>(
    moves: &[Move],
    limits: &MachineLimits,
    options: &RunOptions,
    sink: F,
) -> Result<Summary, RunError>
where
    F: FnMut(f64, &Setpoint),
{
    run_stream(moves.iter().copied(), limits, options, None, sink)
}

/// The source of [`run_stream`]: batches from the planning thread.
struct Batches {
    rx: std::sync::mpsc::Receiver<Batch>,
    items: std::vec::IntoIter<Planned>,
    pending: VecDeque<Move>,
    error: Option<PlanError>,
}

impl Source for Batches {
    fn poll(&mut self) -> Poll {
        loop {
            if let Some(p) = self.items.next() {
                return Poll::Ready(p);
            }
            match self.rx.recv() {
                Ok(Ok((moves, items))) => {
                    self.pending.extend(moves);
                    self.items = items.into_iter();
                }
                Ok(Err(e)) => {
                    self.error = Some(e);
                    return Poll::End;
                }
                Err(_) => return Poll::End,
            }
        }
    }

    fn next_move(&mut self) -> Option<Move> {
        self.pending.pop_front()
    }

    fn take_error(&mut self) -> Option<PlanError> {
        self.error.take()
    }
}

/// [`run_parallel`] over a stream of moves (`kerf sim` reads them from the program file
/// while the motion runs): memory does not grow with the program, only with the queue
/// capacity. With a `monitor` every setpoint is checked as it is produced, and the run
/// stops at the first one that breaks a limit with [`RunError::Fault`] (the sink has
/// already seen that setpoint). The monitor keeps what it measured (its peaks) for the
/// caller; it is given every setpoint from the row at t = 0 on.
pub fn run_stream<I, F>(
    moves: I,
    limits: &MachineLimits,
    options: &RunOptions,
    monitor: Option<&mut LimitMonitor>,
    sink: F,
) -> Result<Summary, RunError>
where
    I: Iterator + Send,
    I::Item: Into<Input>,
    F: Sink,
{
    let (tx, rx) = std::sync::mpsc::sync_channel::<Batch>(4);
    let design_override = options.feed_override;
    std::thread::scope(|scope| {
        scope.spawn(move || {
            let mut step = PlanStep::new(limits, design_override);
            let mut taken = Vec::new();
            let mut batch = Vec::with_capacity(BATCH);
            for input in moves {
                if let Err(e) = step.input(&input.into(), &mut taken, &mut batch) {
                    let _ = tx.send(Err(e));
                    return;
                }
                if batch.len() >= BATCH || taken.len() >= MOVES_PER_BATCH {
                    let full = (
                        std::mem::take(&mut taken),
                        std::mem::replace(&mut batch, Vec::with_capacity(BATCH)),
                    );
                    if tx.send(Ok(full)).is_err() {
                        return;
                    }
                }
            }
            step.finish(&mut batch);
            let _ = tx.send(Ok((taken, batch)));
        });
        let mut runner = Runner::new(limits, options, sink);
        runner.attach(monitor)?;
        let mut source = Batches {
            rx,
            items: Vec::new().into_iter(),
            pending: VecDeque::new(),
            error: None,
        };
        // Dropping the source (and its receiver) when the run returns ends the planning
        // thread's sends (a run stopped early).
        runner.run(&mut source)
    })
}

/// The source of [`run_planned`].
struct Kept<'m, S> {
    segments: S,
    program: std::iter::Copied<std::slice::Iter<'m, Move>>,
}

impl<S: Iterator<Item = Planned>> Source for Kept<'_, S> {
    fn poll(&mut self) -> Poll {
        match self.segments.next() {
            Some(p) => Poll::Ready(p),
            None => Poll::End,
        }
    }

    fn next_move(&mut self) -> Option<Move> {
        self.program.next()
    }
}

/// [`run_stream`] for segments already planned (by the same [`Planner`] with the same
/// limits and design override, which is deterministic): each segment with the number of
/// moves the planner had taken when it produced it, and the dwells in their place. No
/// planning thread; the same setpoints as [`run_stream`] on the same input.
///
/// [`Planner`]: kerf_plan::Planner
pub fn run_planned<S, F>(
    moves: &[Move],
    segments: S,
    limits: &MachineLimits,
    options: &RunOptions,
    monitor: Option<&mut LimitMonitor>,
    sink: F,
) -> Result<Summary, RunError>
where
    S: IntoIterator<Item = Planned>,
    F: Sink,
{
    let mut runner = Runner::new(limits, options, sink);
    runner.attach(monitor)?;
    let mut source = Kept {
        segments: segments.into_iter(),
        program: moves.iter().copied(),
    };
    runner.run(&mut source)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::machine;
    use kerf_geom::{Path, PerAxis, Vec3};
    use kerf_motion::monitor::*;
    use kerf_plan::Planner;

    #[test]
    fn a_dwell_rests_at_an_exact_stop_the_same_in_every_runner() {
        // Two lines at a shallow angle (blended without the dwell), a 0.1 s dwell between.
        let limits = machine(0.001, 200.0, 2000.0, 50_000.0);
        let mv = |a: Vec3, b: Vec3| Move {
            line: 1,
            rapid: false,
            path: Path::Line(kerf_geom::Line { start: a, end: b }),
            feed_mm_min: Some(1200.0),
            abc_deg: None,
            corner: kerf_geom::CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        };
        let corner = Vec3::new(10.0, 0.0, 0.0);
        let inputs = [
            Input::Move(mv(Vec3::zeros(), corner)),
            Input::Dwell(0.1),
            Input::Move(mv(corner, Vec3::new(20.0, 2.0, 0.0))),
        ];
        let collect = |streamed: bool| {
            let mut rows: Vec<PerAxis<f64>> = Vec::new();
            let opts = RunOptions::default();
            let sink = |_: f64, sp: &Setpoint| rows.push(sp.position);
            if streamed {
                run_stream(inputs.iter().copied(), &limits, &opts, None, sink).unwrap();
            } else {
                run(inputs.iter().copied(), &limits, &opts, sink).unwrap();
            }
            rows
        };
        let rows = collect(false);
        assert_eq!(rows, collect(true));
        let at_corner = rows.iter().filter(|p| p[..3] == [10.0, 0.0, 0.0]).count();
        // The arrival row and 100 periods of rest.
        assert!((101..=102).contains(&at_corner), "{at_corner}");
        // Without the dwell the corner is blended: no setpoint is exactly on it.
        let mut blended: Vec<PerAxis<f64>> = Vec::new();
        run(
            [inputs[0], inputs[2]],
            &limits,
            &RunOptions::default(),
            |_, sp| blended.push(sp.position),
        )
        .unwrap();
        assert!(!blended.iter().any(|p| p[..3] == [10.0, 0.0, 0.0]));
        assert!(blended.len() + 90 < rows.len());
    }

    #[test]
    fn a_monitored_run_stops_at_the_first_setpoint_that_breaks_a_limit() {
        // Planned for 100 mm/s, watched by a monitor that allows only 50 mm/s: the run
        // must stop at the first setpoint faster than 50.5 mm/s, found here from the
        // setpoints of an unmonitored run of the same program.
        use kerf_geom::{CornerMode, Line};
        let planned = machine(1e-3, 100.0, 1000.0, 1e5);
        let watched = machine(1e-3, 50.0, 1000.0, 1e5);
        let mv = Move {
            line: 7,
            rapid: false,
            path: Path::Line(Line {
                start: Vec3::zeros(),
                end: Vec3::new(30.0, 0.0, 0.0),
            }),
            feed_mm_min: Some(6000.0),
            abc_deg: None,
            corner: CornerMode::ExactStop,
        };
        let mut free = Vec::new();
        run_stream(
            [mv].into_iter(),
            &planned,
            &RunOptions::default(),
            None,
            |_, sp: &Setpoint| free.push(sp.position[0]),
        )
        .unwrap();
        let first = free
            .windows(2)
            .position(|w| (w[1] - w[0]) / 1e-3 > 50.0 * LIMIT_MARGIN)
            .expect("the program runs faster than 50 mm/s")
            + 1;
        let mut monitor = LimitMonitor::at_rest(&watched, &[0.0; 6]);
        let mut seen = Vec::new();
        let result = run_stream(
            [mv].into_iter(),
            &planned,
            &RunOptions::default(),
            Some(&mut monitor),
            |t, sp: &Setpoint| seen.push((t, sp.position[0], sp.line)),
        );
        let Err(RunError::Fault(v)) = result else {
            panic!("no fault: {result:?}");
        };
        assert_eq!(
            (v.sample, v.axis, v.quantity),
            (first as u64, 0, Quantity::Velocity)
        );
        // The sink saw every setpoint up to and including the offending one, no more.
        assert_eq!(seen.len(), first + 1);
        assert_eq!(seen.last().unwrap().1, free[first]);
        assert_eq!(seen.last().unwrap().2, 7);
        // The same from planned segments.
        let mut planner = Planner::new(planned);
        let mut segs = Vec::new();
        planner.push(&mv, &mut segs).unwrap();
        planner.finish(&mut segs);
        let mut monitor = LimitMonitor::at_rest(&watched, &[0.0; 6]);
        let mut rows = 0;
        let result = run_planned(
            &[mv],
            segs.into_iter().map(|s| Planned::Segment(s, 1)),
            &planned,
            &RunOptions::default(),
            Some(&mut monitor),
            |_, _: &Setpoint| rows += 1,
        );
        assert_eq!(result, Err(RunError::Fault(v)));
        assert_eq!(rows, first + 1);
    }
}
