//! The streaming planner: moves in program order in, [`PlannedSegment`]s out, one move
//! behind (a corner is decided once both of its moves are known). It routes dense
//! polylines to the smoother ([`crate::run`]), blends the other corners
//! ([`crate::blend`]), inserts G2 transitions at joints with arcs ([`crate::transition`])
//! and sets every segment's limits ([`crate::budget`]) and end cap ([`crate::junction`]).

use kerf_geom::{CornerMode, Curve, Move, Path, Vec3};

use crate::budget::{
    PieceSamples, limits_key, lowered_ramp_design, ramp_budget, segment_limits_pair,
};
use crate::junction::junction_cap;
use crate::memo::{ArcMemo, LimitsMemo};
use crate::run::{RunState, joining_frame, line_dir, line_len, next_start_frame, turn_fits};
use crate::section::SectionEstimate;
use crate::timing::{change_time_s, reach_speed};
use crate::{
    AXIS_NAMES, DESIGN_RUN_MM, MAX_DESIGN_OVERRIDE, MIN_SEGMENT_MM, MachineLimits, PlanError,
    PlannedSegment, smooth,
};

/// Two segments continue each other in tangent when every axis' `d/ds` differs by at most
/// this: 1e-6 (1 µm per m) is rounding noise of the tangents, not a corner.
const TANGENT_MATCH: f64 = 1e-6;
/// A smoothed piece gets a ramp budget ([`ramp_budget`]) where a junction at its start or
/// end is capped below this share of its design speed: a ramp there runs at speeds low
/// enough to leave more of the axis limits than the design speed does.
const RAMP_CAP_RATIO: f64 = 0.5;

/// The move currently waiting for its successor (its end may still be blended).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pending {
    pub(crate) mv: Move,
    pub(crate) move_index: u64,
    /// Start point after the previous blend trimmed it.
    pub(crate) start: Vec3,
    /// How much the previous blend trimmed from the start, mm.
    pub(crate) start_trim: f64,
    pub(crate) abc_start: [f64; 3],
    pub(crate) abc_end: [f64; 3],
}

/// Streaming path preparation: moves in, planned segments out (one move of delay, since a
/// corner can only be blended once both sides are known).
#[derive(Debug)]
pub struct Planner {
    pub(crate) limits: MachineLimits,
    pub(crate) pending: Option<Pending>,
    /// The last produced segment, held back until its end junction cap is known.
    pub(crate) last: Option<PlannedSegment>,
    /// Corner mode at the end of `last`.
    pub(crate) last_corner: CornerMode,
    /// The programmed path `last` was cut from (`None` for corner blends).
    pub(crate) last_origin: Option<Curve>,
    /// Length of `last` before a transition trimmed its start, path units.
    pub(crate) last_full_length: f64,
    /// Speed cap at the start of `last` (its junction with the segment before), mm/s.
    pub(crate) last_start_cap: f64,
    /// The motion-core section the segment emitted just before `last` is estimated to run
    /// in.
    pub(crate) section: Option<SectionEstimate>,
    pub(crate) next_index: u64,
    pub(crate) abc_current: [f64; 3],
    /// The dense-polyline run being collected, if any.
    pub(crate) run: Option<RunState>,
    /// Scratch for smoothed pieces (kept to reuse its allocation).
    pub(crate) pieces: Vec<smooth::Emitted>,
    /// Feed override the curved segments are designed for (see
    /// [`Planner::set_design_override`]).
    pub(crate) design_override: f64,
    /// Length of the path that runs on without a corner (tangent-continuous, no exact
    /// stop) up to the end of `last`, mm.
    pub(crate) chain_mm: f64,
    /// Limits of recent curved segments by their exact inputs (bounded; see
    /// [`crate::memo`]).
    pub(crate) memo: std::cell::RefCell<LimitsMemo>,
    /// Arc-length tables of recent transitions by their coefficients (bounded).
    pub(crate) arc_memo: std::cell::RefCell<ArcMemo>,
}

/// The tolerance of the corner where a move in mode `arriving` meets one in mode
/// `leaving`, mm: the smaller of the two moves' tolerances (LinuxCNC's `tp` takes the
/// minimum too), `None` for an exact stop. An exact stop belongs to the move that ends
/// at the corner (the arriving one), as in LinuxCNC's `tp` and as G9/G09 (exact stop for
/// one block, at its end) needs; a leaving move in exact-stop mode adds no tolerance of
/// its own, so the arriving move's governs.
pub(crate) fn corner_tolerance(
    arriving: CornerMode,
    leaving: CornerMode,
    default_mm: f64,
) -> Option<f64> {
    let CornerMode::Blend { tolerance_mm, .. } = arriving else {
        return None;
    };
    let tol = tolerance_mm.unwrap_or(default_mm);
    Some(match leaving {
        CornerMode::Blend { tolerance_mm, .. } => tol.min(tolerance_mm.unwrap_or(default_mm)),
        CornerMode::ExactStop => tol,
    })
}

impl Planner {
    /// A planner for a machine; the path starts at the origin with rotary axes at 0.
    pub fn new(limits: MachineLimits) -> Self {
        Planner {
            limits,
            pending: None,
            last: None,
            last_corner: CornerMode::ExactStop,
            last_origin: None,
            last_full_length: 0.0,
            last_start_cap: 0.0,
            section: None,
            next_index: 0,
            abc_current: [0.0; 3],
            run: None,
            pieces: Vec::new(),
            design_override: 1.0,
            chain_mm: 0.0,
            memo: std::cell::RefCell::new(LimitsMemo::new()),
            arc_memo: std::cell::RefCell::new(ArcMemo::new()),
        }
    }

    /// Designs curved segments for a feed override of `factor` (clamped to 1–2): their
    /// speed limit is the programmed feed times it, where the machine allows. Straight
    /// segments are limited by the axes alone and follow any override anyway. Planning
    /// for more than 100 % costs a little tangential acceleration on curves, so a control
    /// passes the override in force when the segments are planned; segments already
    /// planned keep their limit (the motion core never exceeds it).
    pub fn set_design_override(&mut self, factor: f64) {
        self.design_override = if factor.is_finite() {
            factor.clamp(1.0, MAX_DESIGN_OVERRIDE)
        } else {
            1.0
        };
    }

    /// Adds the next move; finished segments are appended to `out`.
    pub fn push(&mut self, mv: &Move, out: &mut Vec<PlannedSegment>) -> Result<(), PlanError> {
        self.check(mv)?;
        let (abc_start, abc_end) = match mv.abc_deg {
            Some((s, e)) => (s, e),
            None => (self.abc_current, self.abc_current),
        };
        self.abc_current = abc_end;
        let index = self.next_index;
        self.next_index += 1;
        let next = Pending {
            mv: *mv,
            move_index: index,
            start: mv.path.start(),
            start_trim: 0.0,
            abc_start,
            abc_end,
        };
        let mut carried = None;
        if let Some(mut run) = self.run.take() {
            if run.joins(&next) {
                run.add(next);
                self.run = Some(run);
                self.advance_run(out);
                return Ok(());
            }
            carried = self.end_run(run, Some(&next), out);
        }
        if let Some(tol) = RunState::starts(&next, &self.limits) {
            let frame = carried.or_else(|| {
                self.pending
                    .as_ref()
                    .and_then(|p| joining_frame(p, &next, tol))
            });
            self.run = Some(RunState::new(next, tol, frame, &self.limits));
            return Ok(());
        }
        self.push_plain(next, out);
        Ok(())
    }

    /// A move through the corner-blending path (not part of a smoothed run).
    fn push_plain(&mut self, mut next: Pending, out: &mut Vec<PlannedSegment>) {
        if let Some(prev) = self.pending.take() {
            if let Some((blend, d)) = self.blend(&prev, &next) {
                let (p_start, u1) = match prev.mv.path {
                    Path::Line(l) => (l.end, (l.end - l.start).normalize()),
                    Path::Arc(_) => unreachable!("only lines are blended"),
                };
                let cut = p_start - u1 * d;
                self.emit_line(
                    &prev,
                    prev.start,
                    cut,
                    CornerMode::Blend {
                        tolerance_mm: None,
                        naive_cam_mm: None,
                    },
                    out,
                );
                let mode = CornerMode::Blend {
                    tolerance_mm: None,
                    naive_cam_mm: None,
                };
                self.emit(blend, mode, mode, None, out);
                let u2 = (next.mv.path.end() - next.start).normalize();
                next.start += u2 * d;
                next.start_trim = d;
            } else {
                self.emit_move(&prev, out);
            }
        }
        self.pending = Some(next);
    }

    /// Emits the pieces of the current run that are ready; commits the run (flushing the
    /// move before it, unblended) once it is long enough to be smoothed.
    fn advance_run(&mut self, out: &mut Vec<PlannedSegment>) {
        let Some(run) = self.run.as_mut() else { return };
        if !run.committed {
            if run.buffered.len() < smooth::MIN_RUN_MOVES {
                return;
            }
            run.committed = true;
            run.buffered.clear();
            if let Some(prev) = self.pending.take() {
                self.emit_move(&prev, out);
            }
        }
        let Some(run) = self.run.as_mut() else { return };
        let mut pieces = std::mem::take(&mut self.pieces);
        run.run.emit(false, None, &mut pieces);
        self.emit_pieces(&mut pieces, None, out);
        self.pieces = pieces;
    }

    /// Ends `run` before `next` (or at the program end); returns the frame the run ended
    /// with when `next` starts a run that must continue it.
    fn end_run(
        &mut self,
        mut run: RunState,
        next: Option<&Pending>,
        out: &mut Vec<PlannedSegment>,
    ) -> Option<smooth::EndFrame> {
        if !run.committed && run.buffered.len() < smooth::MIN_RUN_MOVES {
            for p in std::mem::take(&mut run.buffered) {
                self.push_plain(p, out);
            }
            return None;
        }
        if !run.committed {
            run.committed = true;
            if let Some(prev) = self.pending.take() {
                self.emit_move(&prev, out);
            }
        }
        let blended = matches!(run.last.mv.corner, CornerMode::Blend { .. });
        // A line that starts another run (the tolerance changed, or the turn or sag at
        // the joint is too much for this run) is not matched: the run ends on its fitted
        // frame, and the next run starts on that frame where the turn fits, so a curve
        // split into two runs stays curvature-continuous.
        let next_run = next.filter(|n| blended && RunState::starts(n, &self.limits).is_some());
        // Decisions at the joint with `next` take the smaller tolerance of the two moves.
        let corner_tol = next.map_or(run.tol, |n| {
            corner_tolerance(run.last.mv.corner, n.mv.corner, self.limits.tolerance_mm)
                .map_or(run.tol, |t| t.min(run.tol))
        });
        let end_frame = match (run.last.mv.corner, next) {
            _ if next_run.is_some() => None,
            (CornerMode::Blend { .. }, Some(n)) => {
                let first = next_start_frame(n);
                first.filter(|f| {
                    run.run
                        .last_dir()
                        .is_some_and(|d| turn_fits(d, f.tangent, run.run.last_len(), corner_tol))
                })
            }
            _ => None,
        };
        let mut pieces = std::mem::take(&mut self.pieces);
        run.run.emit(true, end_frame, &mut pieces);
        let corner = run.last.mv.corner;
        self.emit_pieces(&mut pieces, Some(corner), out);
        self.pieces = pieces;
        if let Some(n) = next_run {
            return run
                .run
                .end_frame()
                .filter(|f| turn_fits(f.tangent, line_dir(n), line_len(n), corner_tol));
        }
        end_frame
    }

    /// Turns smoothed pieces into segments; the last one takes `last_corner` when the run
    /// ends with it.
    fn emit_pieces(
        &mut self,
        pieces: &mut Vec<smooth::Emitted>,
        last_corner: Option<CornerMode>,
        out: &mut Vec<PlannedSegment>,
    ) {
        let n = pieces.len();
        for (i, e) in pieces.drain(..).enumerate() {
            let curve = match e.piece {
                smooth::Piece::Curve(tr) => Curve::Transition(tr),
                smooth::Piece::Line(p, q) => Curve::line(p, q),
            };
            let mut seg = PlannedSegment {
                abc_poly: e.abc_poly,
                move_count: e.move_count,
                blend: true,
                ..PlannedSegment::with_zero_limits(
                    curve,
                    curve.length(),
                    (e.abc_start, e.abc_end),
                    e.line,
                    e.move_index,
                    e.feed,
                )
            };
            if seg.length_mm < MIN_SEGMENT_MM {
                continue;
            }
            // Designed for the path that runs on without a corner through the piece to the
            // end of its run (at least the whole run), at most [`DESIGN_RUN_MM`]: known
            // geometry only, as for programmed arcs.
            let run_mm = (self.chain_before(&seg) + e.rest_mm)
                .max(e.design_run_mm)
                .min(DESIGN_RUN_MM);
            self.set_limits_for_run(&mut seg, run_mm);
            let corner = match last_corner {
                Some(c) if i + 1 == n => c,
                _ => CornerMode::Blend {
                    tolerance_mm: None,
                    naive_cam_mm: None,
                },
            };
            self.emit(
                seg,
                CornerMode::Blend {
                    tolerance_mm: None,
                    naive_cam_mm: None,
                },
                corner,
                None,
                out,
            );
        }
    }

    /// Ends the program: flushes every remaining segment (the last one ends at rest).
    pub fn finish(&mut self, out: &mut Vec<PlannedSegment>) {
        if let Some(run) = self.run.take() {
            self.end_run(run, None, out);
        }
        if let Some(prev) = self.pending.take() {
            self.emit_move(&prev, out);
        }
        if let Some(mut last) = self.last.take() {
            last.end_cap_mm_s = 0.0;
            self.ramp_upgrade(&mut last, None);
            self.push_out(last, out);
        }
    }

    /// What [`Planner::push`] refuses before planning `mv`: a non-finite coordinate or
    /// feed, a feed move without a positive feed, motion of an axis the machine does not
    /// have. For a check of a program without planning it (`kerf run`'s first pass).
    pub fn check(&self, mv: &Move) -> Result<(), PlanError> {
        let line = mv.line;
        let finite = |v: &Vec3| v.iter().all(|c| c.is_finite());
        let ok = match &mv.path {
            Path::Line(l) => finite(&l.start) && finite(&l.end),
            Path::Arc(a) => {
                finite(&a.start)
                    && finite(&a.end)
                    && finite(&a.center)
                    && finite(&a.axis)
                    && a.sweep_rad.is_finite()
            }
        };
        if !ok {
            return Err(PlanError::NotFinite { line });
        }
        if !mv.rapid {
            match mv.feed_mm_min {
                Some(f) if f.is_finite() && f > 0.0 => {}
                Some(f) if !f.is_finite() => return Err(PlanError::NotFinite { line }),
                _ => return Err(PlanError::ZeroFeed { line }),
            }
        }
        if let Some((s, e)) = mv.abc_deg {
            for i in 0..3 {
                if !s[i].is_finite() || !e[i].is_finite() {
                    return Err(PlanError::NotFinite { line });
                }
                if s[i] != e[i] && self.limits.axes[3 + i].is_none() {
                    return Err(PlanError::AxisNotConfigured {
                        line,
                        axis: AXIS_NAMES[3 + i],
                    });
                }
            }
        }
        Ok(())
    }

    fn emit_move(&mut self, p: &Pending, out: &mut Vec<PlannedSegment>) {
        match p.mv.path {
            Path::Line(l) => self.emit_line(p, p.start, l.end, p.mv.corner, out),
            Path::Arc(_) => {
                let curve = Curve::from_path(&p.mv.path);
                self.emit_curve(p, curve, p.mv.corner, out);
            }
        }
    }

    fn emit_line(
        &mut self,
        p: &Pending,
        start: Vec3,
        end: Vec3,
        corner: CornerMode,
        out: &mut Vec<PlannedSegment>,
    ) {
        self.emit_curve(p, Curve::line(start, end), corner, out);
    }

    fn emit_curve(
        &mut self,
        p: &Pending,
        curve: Curve,
        corner: CornerMode,
        out: &mut Vec<PlannedSegment>,
    ) {
        let xyz = curve.length();
        let rot = (0..3)
            .map(|i| (p.abc_end[i] - p.abc_start[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        // A remnant of a line between two blends is kept down to the rounding of the
        // coordinates (the motion core passes it in the time it takes): dropped below
        // `MIN_SEGMENT_MM`, it would leave the blends apart by its length, a jump that at
        // a short period can exceed the jerk limit of a slow axis.
        let rounding =
            kerf_geom::POSITION_ROUNDING_ULPS * f64::EPSILON * curve.start().norm().max(1.0);
        let keep = |l: f64| l >= MIN_SEGMENT_MM || (self.last.is_some() && l > rounding);
        let length = if keep(xyz) { xyz } else { rot };
        if !keep(length) {
            return;
        }
        let curve = if keep(xyz) {
            curve
        } else {
            Curve::line(curve.start(), curve.start())
        };
        let mut seg = PlannedSegment::with_zero_limits(
            curve,
            length,
            (p.abc_start, p.abc_end),
            p.mv.line,
            p.move_index,
            feed_of(&p.mv),
        );
        // A programmed arc is designed for the path that runs on without a corner up to
        // its end, at most [`DESIGN_RUN_MM`]: known geometry only, so that the choice
        // does not depend on the limits.
        let run_mm = (self.chain_before(&seg) + seg.length_mm).min(DESIGN_RUN_MM);
        self.set_limits_for_run(&mut seg, run_mm);
        self.emit(
            seg,
            p.mv.corner,
            corner,
            Some(Curve::from_path(&p.mv.path)),
            out,
        );
    }

    /// Appends `seg` (in mode `own`, the mode of the move it comes from, and ending in
    /// mode `corner`) after the held-back segment, deciding the junction between them.
    fn emit(
        &mut self,
        mut seg: PlannedSegment,
        own: CornerMode,
        corner: CornerMode,
        origin: Option<Curve>,
        out: &mut Vec<PlannedSegment>,
    ) {
        let full_length = seg.length_mm;
        self.chain_mm = self.chain_before(&seg) + seg.length_mm;
        // The cap at the start of `seg`: 0 after an exact stop or on an idle machine.
        let mut start_cap = 0.0;
        if let Some(mut prev) = self.last.take() {
            match corner_tolerance(self.last_corner, own, self.limits.tolerance_mm) {
                None => {
                    prev.end_cap_mm_s = 0.0;
                    self.ramp_upgrade(&mut prev, None);
                    self.push_out(prev, out);
                }
                Some(tol) => match self.transition(&prev, &seg, tol, origin.as_ref()) {
                    Some((p, mut t, s)) => {
                        prev = p;
                        seg = s;
                        prev.end_cap_mm_s = junction_cap(&prev, &t, &self.limits);
                        t.end_cap_mm_s = junction_cap(&t, &seg, &self.limits);
                        start_cap = t.end_cap_mm_s;
                        self.ramp_upgrade(&mut prev, Some(&t));
                        self.push_out(prev, out);
                        self.push_out(t, out);
                    }
                    None => {
                        prev.end_cap_mm_s = junction_cap(&prev, &seg, &self.limits);
                        start_cap = prev.end_cap_mm_s;
                        self.ramp_upgrade(&mut prev, Some(&seg));
                        self.push_out(prev, out);
                    }
                },
            }
        }
        self.last_start_cap = start_cap;
        self.last = Some(seg);
        self.last_corner = corner;
        self.last_origin = origin;
        self.last_full_length = full_length;
    }

    /// Emits a finished segment.
    fn push_out(&mut self, seg: PlannedSegment, out: &mut Vec<PlannedSegment>) {
        self.section = Some(SectionEstimate::after(self.section, &seg));
        out.push(seg);
    }

    /// Raises the tangential budget of `seg` (the held-back segment, its end cap set) where
    /// it starts or ends at a junction much slower than its design speed, to what the
    /// axis limits leave at the low speeds the ramp there runs at ([`ramp_budget`]).
    ///
    /// A piece slow only at its start keeps its budget unless raising it loses less by
    /// [`ramp_split_losses`]: raised, it runs in a motion-core section of its own, and the
    /// return to zero acceleration at its end, mid-ramp, can cost more than the raised
    /// budget gains (the dense circle: 3 ms per ramp). A piece entered at speed and slow only at its end is raised without
    /// that check, but a raised budget can split a section there too: the piece joins the
    /// section before it only if its limits pass [`kerf_geom::limits_merge`] with the
    /// section's first segment's (not much below them, nor more than `MERGE_ABOVE` = 4 ×
    /// above) and its speed limit passes [`kerf_geom::speeds_merge_into`], else it starts
    /// a section of its own ([`SectionEstimate`] follows the sections);
    /// [`ramp_budget`] prices each candidate budget by which of the two it makes.
    ///
    /// A piece slow at one end only may instead be designed for a lower speed, with the
    /// budget the axes leave there, where that is estimated to lose clearly less than
    /// the choice at its design speed ([`lowered_ramp_design`]).
    fn ramp_upgrade(&self, seg: &mut PlannedSegment, next: Option<&PlannedSegment>) {
        let slow = RAMP_CAP_RATIO * seg.v_max_mm_s;
        // Smoothed pieces only, and only without a boost design (pieces keep the
        // programmed feed), so the speed never exceeds `v_max_mm_s` at any override.
        if seg.move_count <= 1
            || seg.v_boost_mm_s > seg.v_max_mm_s
            || (self.last_start_cap >= slow && seg.end_cap_mm_s >= slow)
        {
            return;
        }
        // A piece entered at speed whose limits are like those of the section before it
        // joins it and runs at the least of their limits (the section's first segment
        // and its conservative speed decide, as in the motion core); each candidate
        // budget is judged by whether it joins (`ramp_budget`), so the section is passed
        // whether or not the piece's own budget joins it: a candidate is judged by where
        // it itself would run.
        let section = self.section.filter(|_| self.last_start_cap >= slow);
        let (cap_start, cap_end) = (self.last_start_cap, seg.end_cap_mm_s);
        let Some(window) = PieceSamples::of(seg) else {
            return;
        };
        let Some((a, j, stop_loss)) =
            ramp_budget(&window, seg, &self.limits, cap_start, cap_end, section)
        else {
            return;
        };
        let own = (seg.accel_mm_s2, seg.jerk_mm_s3);
        // The budget at the design speed, and its estimated loss.
        let ((a, j), loss) = match next {
            Some(n) if cap_end >= slow => {
                let (split, merged) = ramp_split_losses(seg, n, cap_start, (a, j));
                if (a, j) != own && split < merged {
                    ((a, j), split)
                } else {
                    (own, merged)
                }
            }
            _ => ((a, j), stop_loss),
        };
        // Or a lower design speed, whose budget may pay for the slower run: where exactly
        // one end is slow, priced with the limits of the ramp outside the piece (the
        // segment after a start, the section before a stop).
        let outer = if cap_end >= slow {
            next.map(|n| (n.accel_mm_s2, n.jerk_mm_s3))
        } else if cap_start >= slow {
            section.map(|s| s.least)
        } else {
            None
        };
        let lowered = outer.and_then(|outer| {
            lowered_ramp_design(&window, seg, &self.limits, cap_start, cap_end, outer, loss)
        });
        let (v, a, j) = lowered.unwrap_or((seg.v_max_mm_s, a, j));
        seg.v_max_mm_s = v;
        seg.v_boost_mm_s = seg.v_boost_mm_s.min(v);
        seg.end_cap_mm_s = seg.end_cap_mm_s.min(v);
        seg.accel_mm_s2 = a;
        seg.jerk_mm_s3 = j;
        seg.accel_boost_mm_s2 = a;
        seg.jerk_boost_mm_s3 = j;
    }

    /// The length of the path that runs on without a corner into `seg`: the chain ending
    /// at the held-back segment if `seg` continues it in tangent (all six axes) and the
    /// junction is not an exact stop, else 0.
    pub(crate) fn chain_before(&self, seg: &PlannedSegment) -> f64 {
        let Some(last) = &self.last else { return 0.0 };
        if matches!(self.last_corner, CornerMode::ExactStop) || seg.length_mm <= 0.0 {
            return 0.0;
        }
        let (ta, _) = last.derivatives_at(last.length_mm);
        let (tb, _) = seg.derivatives_at(0.0);
        let tangent = (0..6).all(|i| (ta[i] - tb[i]).abs() <= TANGENT_MATCH);
        if tangent { self.chain_mm } else { 0.0 }
    }

    /// Sets `v_max_mm_s`, `accel_mm_s2` and `jerk_mm_s3` of `seg` from the axis limits, a
    /// curve designed for its own length (a circular corner blend, a corner's stand-in
    /// lines).
    pub(crate) fn set_limits(&self, seg: &mut PlannedSegment) {
        self.set_limits_for_run(seg, 0.0);
    }

    /// [`Planner::set_limits`] with the design run `run_mm` (see `segment_limits`): the
    /// distance a curved segment's design speed is chosen for, at least its own length.
    pub(crate) fn set_limits_for_run(&self, seg: &mut PlannedSegment, run_mm: f64) {
        // Curved segments (not smoothed pieces, which keep the programmed feed) also get a
        // design for the highest override, which the motion core uses while the override
        // is above 100 %. Straight segments are limited by the axes alone.
        let curved = match seg.curve {
            Curve::Line { .. } => false,
            Curve::Helix(_) => true,
            Curve::Transition(_) => seg.move_count <= 1,
        };
        let boost_scale =
            (curved && seg.feed_mm_s.is_finite() && self.design_override < MAX_DESIGN_OVERRIDE)
                .then_some(MAX_DESIGN_OVERRIDE);
        let key = limits_key(seg, self.design_override, boost_scale, run_mm);
        let memo = key.as_ref().and_then(|k| self.memo.borrow().get(k));
        let ((v, a, j), boost) = memo.unwrap_or_else(|| {
            let found =
                segment_limits_pair(seg, &self.limits, self.design_override, boost_scale, run_mm);
            if let Some(k) = key {
                self.memo.borrow_mut().put(k, found);
            }
            found
        });
        seg.v_max_mm_s = v;
        seg.accel_mm_s2 = a;
        seg.jerk_mm_s3 = j;
        (
            seg.v_boost_mm_s,
            seg.accel_boost_mm_s2,
            seg.jerk_boost_mm_s3,
        ) = (v, a, j);
        if let Some((vb, ab, jb)) = boost
            && vb > v
        {
            seg.v_boost_mm_s = vb;
            seg.accel_boost_mm_s2 = ab.min(a);
            seg.jerk_boost_mm_s3 = jb.min(j);
        }
    }
}

/// The estimated losses of raising the budget of `seg`, which starts at `cap_start`
/// (slow) and runs on into `next` at speed, to `(a, j)`, and of keeping its own budget,
/// `(raised, kept)`: each ramp's time less its distance at the top speed `v`. Kept, one
/// ramp from rest to `v` with the limits the section of `seg` and `next` would have (the
/// smaller of each); raised, a ramp in `seg` to the speed `v_b` it reaches with `(a, j)`
/// plus the rest of the ramp, from `v_b` to `v`, with `next`'s limits after a return to
/// zero acceleration.
fn ramp_split_losses(
    seg: &PlannedSegment,
    next: &PlannedSegment,
    cap_start: f64,
    (a, j): (f64, f64),
) -> (f64, f64) {
    let v = seg.v_max_mm_s.min(seg.feed_mm_s);
    if !(v > 0.0 && v.is_finite()) {
        return (f64::INFINITY, 0.0);
    }
    let v0 = cap_start.min(v);
    let merged = change_time_s(
        v - v0,
        seg.accel_mm_s2.min(next.accel_mm_s2),
        seg.jerk_mm_s3.min(next.jerk_mm_s3),
    ) * (v - v0)
        / (2.0 * v);
    let v_b = v0 + reach_speed(seg.length_mm, v - v0, a, j);
    let first = change_time_s(v_b - v0, a, j) * (1.0 - (v0 + v_b) / (2.0 * v));
    let rest = change_time_s(v - v_b, next.accel_mm_s2, next.jerk_mm_s3) * (v - v_b) / (2.0 * v);
    (first + rest, merged)
}

pub(crate) fn feed_of(mv: &Move) -> f64 {
    if mv.rapid {
        f64::INFINITY
    } else {
        mv.feed_mm_min.unwrap_or(0.0) / 60.0
    }
}
