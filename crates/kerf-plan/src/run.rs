//! Dense-polyline runs: which feed lines are collected into a run for the smoother
//! ([`crate::smooth`]) and the frames a run starts and ends on.

use kerf_geom::{CornerMode, Curve, Path, Vec3};

use crate::planner::{Pending, feed_of};
use crate::{MIN_SEGMENT_MM, MachineLimits, smooth};

/// Shortest line that may join a run, mm: below 1 nm a line's direction is rounding
/// noise, and the turn tests of a run need it.
const MIN_RUN_LINE_MM: f64 = 1e-6;

/// A run of lines that may be smoothed (see [`smooth`]).
#[derive(Debug)]
pub(crate) struct RunState {
    pub(crate) run: smooth::Run,
    /// The moves, kept until the run is long enough to be smoothed (then it commits and
    /// they are dropped); a shorter run goes through corner blending after all.
    pub(crate) buffered: Vec<Pending>,
    pub(crate) committed: bool,
    /// The last move of the run.
    pub(crate) last: Pending,
    /// Tolerance, mm.
    pub(crate) tol: f64,
    /// The programmed tolerance (`None`: the configured one), which members must share.
    pub(crate) tol_mm: Option<f64>,
}

impl RunState {
    /// The tolerance of the run `p` would start, if it may start one.
    pub(crate) fn starts(p: &Pending, limits: &MachineLimits) -> Option<f64> {
        let CornerMode::Blend { tolerance_mm, .. } = p.mv.corner else {
            return None;
        };
        let tol = tolerance_mm.unwrap_or(limits.tolerance_mm);
        (tol > 0.0 && tol.is_finite() && smoothable(p)).then_some(tol)
    }

    pub(crate) fn new(
        p: Pending,
        tol: f64,
        start_frame: Option<smooth::EndFrame>,
        limits: &MachineLimits,
    ) -> RunState {
        let CornerMode::Blend { tolerance_mm, .. } = p.mv.corner else {
            unreachable!("checked by RunState::starts")
        };
        let xyz_limits = std::array::from_fn(|i| match limits.axes[i] {
            Some(a) => [a.velocity_units_s, a.acceleration_units_s2, a.jerk_units_s3],
            None => [f64::INFINITY; 3],
        });
        let mut run =
            smooth::Run::new(p.mv.path.start(), p.abc_start, start_frame, tol, xyz_limits);
        run.push(
            p.mv.path.end(),
            p.abc_end,
            p.mv.line,
            p.move_index,
            feed_of(&p.mv),
        );
        RunState {
            run,
            buffered: vec![p],
            committed: false,
            last: p,
            tol,
            tol_mm: tolerance_mm,
        }
    }

    /// Whether `p` continues the run: every member has the run's tolerance, at both of its
    /// ends (a move under another tolerance starts a run of its own, so a coarse run
    /// never smooths a fine move).
    pub(crate) fn joins(&self, p: &Pending) -> bool {
        // The naive-CAM tolerance (LinuxCNC G64 Q) is carried but not used by the planner:
        // only the blend tolerance decides.
        let in_run = |c: CornerMode| matches!(c, CornerMode::Blend { tolerance_mm, .. } if tolerance_mm == self.tol_mm);
        if !in_run(self.last.mv.corner)
            || !in_run(p.mv.corner)
            || !smoothable(p)
            || p.abc_start != self.run.end_abc()
            || (p.mv.path.start() - self.run.end()).norm() > MIN_SEGMENT_MM
        {
            return false;
        }
        let Some(d) = self.run.last_dir() else {
            return false;
        };
        let len = self.run.last_len().max(line_len(p));
        turn_fits(d, line_dir(p), len, self.tol)
            && rotary_turn_fits(self.run.last_abc_rate(), abc_rate(p), len, self.tol)
    }

    pub(crate) fn add(&mut self, p: Pending) {
        self.run.push(
            p.mv.path.end(),
            p.abc_end,
            p.mv.line,
            p.move_index,
            feed_of(&p.mv),
        );
        if !self.committed {
            self.buffered.push(p);
        }
        self.last = p;
    }
}

/// A feed line short enough for a run (it may move rotary axes along, but not only them).
pub(crate) fn smoothable(p: &Pending) -> bool {
    !p.mv.rapid
        && matches!(p.mv.path, Path::Line(_))
        && (MIN_RUN_LINE_MM..=smooth::MAX_SEGMENT_MM).contains(&line_len(p))
}

/// Rate of A, B, C along the XYZ length of a line, degrees per mm.
pub(crate) fn abc_rate(p: &Pending) -> [f64; 3] {
    let len = line_len(p);
    std::array::from_fn(|i| (p.abc_end[i] - p.abc_start[i]) / len)
}

/// Whether a change of rotary rate from `a` to `b` (degrees per mm) at a vertex next to a
/// segment of length `len` may lie inside a smoothed run: a smooth A(s) through the
/// vertices sags `len·Δ(dA/ds)/8` from the programmed linear interpolation, which must be
/// within [`smooth::SAG_TOL_SHARE`] of the tolerance (the same number, in degrees).
pub(crate) fn rotary_turn_fits(a: [f64; 3], b: [f64; 3], len: f64, tol: f64) -> bool {
    (0..3).all(|i| len * (b[i] - a[i]).abs() / 8.0 <= smooth::SAG_TOL_SHARE * tol)
}

pub(crate) fn line_len(p: &Pending) -> f64 {
    (p.mv.path.end() - p.mv.path.start()).norm()
}

pub(crate) fn line_dir(p: &Pending) -> Vec3 {
    (p.mv.path.end() - p.mv.path.start()).normalize()
}

/// Whether a turn from direction `a` to `b` at a vertex next to a segment of length `len`
/// may lie inside a smoothed run: at most [`smooth::MAX_TURN_RAD`], with a sag `len·θ/8`
/// within [`smooth::SAG_TOL_SHARE`] of the tolerance.
pub(crate) fn turn_fits(a: Vec3, b: Vec3, len: f64, tol: f64) -> bool {
    let theta = a.dot(&b).clamp(-1.0, 1.0).acos();
    theta <= smooth::MAX_TURN_RAD && len * theta / 8.0 <= smooth::SAG_TOL_SHARE * tol
}

/// The tangent and curvature at the start of a feed move (A, B, C move linearly along it).
pub(crate) fn next_start_frame(p: &Pending) -> Option<smooth::EndFrame> {
    let c = Curve::from_path(&p.mv.path);
    if p.mv.rapid || c.length() < MIN_SEGMENT_MM {
        return None;
    }
    let e = c.eval(0.0);
    Some(smooth::EndFrame {
        tangent: e.tangent,
        curvature: e.curvature,
        abc_d: std::array::from_fn(|i| (p.abc_end[i] - p.abc_start[i]) / c.length()),
        abc_dd: [0.0; 3],
    })
}

/// The frame at the end of `prev` if a run starting with the line `next` may continue it
/// smoothly.
pub(crate) fn joining_frame(prev: &Pending, next: &Pending, tol: f64) -> Option<smooth::EndFrame> {
    let CornerMode::Blend { tolerance_mm, .. } = prev.mv.corner else {
        return None;
    };
    // The corner takes the smaller tolerance of its two moves.
    let tol = tolerance_mm.map_or(tol, |t| t.min(tol));
    if prev.mv.rapid
        || prev.abc_end != next.abc_start
        || (prev.mv.path.end() - next.mv.path.start()).norm() > MIN_SEGMENT_MM
    {
        return None;
    }
    let c = Curve::from_path(&prev.mv.path);
    if c.length() < MIN_SEGMENT_MM {
        return None;
    }
    let e = c.eval(c.length());
    let abc_d: [f64; 3] =
        std::array::from_fn(|i| (prev.abc_end[i] - prev.abc_start[i]) / c.length());
    // The sag is judged over the first run segment only.
    (turn_fits(e.tangent, line_dir(next), line_len(next), tol)
        && rotary_turn_fits(abc_d, abc_rate(next), line_len(next), tol))
    .then_some(smooth::EndFrame {
        tangent: e.tangent,
        curvature: e.curvature,
        abc_d,
        abc_dd: [0.0; 3],
    })
}
