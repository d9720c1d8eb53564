//! Ramp budgets of smoothed pieces at stops: where a piece starts or ends at a slow
//! junction, the speed near it is bounded by the ramp from the cap, so the curvature
//! terms are checked at that lower speed, sample by sample, and a larger tangential
//! budget may fit.

use kerf_geom::ramp::{bisect, change_distance};
use kerf_geom::{Curve, Transition, Vec3};

use super::bounds::rise_between_samples;
use super::transition_limits::axis_rate;
use super::{CURVATURE_SAFETY, PIECE_LIMIT_SAMPLES, RATE_SAFETY, TANGENT_SAFETY};
use crate::search::golden_min;
use crate::section::SectionEstimate;
use crate::timing::change_time_s;
use crate::{MachineLimits, PROFILE_SHARE, PlannedSegment};

/// Ratio of [`ramp_budget`]'s grid over the acceleration: 10 % steps (the time it
/// minimises changes little between them). The grid's points are the powers of this
/// ratio in mm/s² (fixed values, whatever the limits), so that the candidates of a
/// machine with a higher limit include those of the same machine with a lower one.
const RAMP_GRID_RATIO: f64 = 0.9;
/// Points of that grid: down to `0.9⁴⁴ ≈ 1 %` of the highest acceleration a stop from
/// the design speed can use, below which the segment's own design is better anyway.
const RAMP_GRID_POINTS: usize = 45;
/// Golden-section narrowings of [`ramp_budget`]'s refinement between the best grid
/// point's neighbours: 8 leave `0.618⁸ ≈ 2 %` of the 20 % bracket.
const RAMP_GOLDEN_STEPS: usize = 8;
/// Speed intervals per sample in [`ramp_budget`]'s envelope check: the acceleration bound
/// `sqrt(2j(v_max − u))` is taken at each interval's bottom, the curvature terms at its top.
const RAMP_ENVELOPE_INTERVALS: usize = 8;
/// Halvings for the speed at which a piece's own stop begins (see [`ramp_budget`]).
const STOP_SPLIT_STEPS: usize = 30;

/// The tangential budget `(a, j)` of a smoothed piece (a [`Transition`] without rotary
/// motion, designed at `seg.v_max_mm_s`) that is entered at most at `cap_start` or left
/// at most at `cap_end`, with the quickest stop from `v_max` (by [`change_time_s`], the
/// time lost against running on at `v_max`, judged in `section`, the estimate of the
/// motion-core section the segment before runs in, as the motion core would: with the
/// least limits of the section and the piece when the budget joins it
/// ([`SectionEstimate::takes_curve`]), else after that section slows to a speed from
/// which the piece can stop), if that is quicker than its own design: ramps at the
/// acceleration the limits leave at each speed.
///
/// Why a higher budget is safe there: the motion core keeps the path acceleration within
/// `a` on the segment and passes its junctions at most at their caps, so at arc length `s`
/// the speed obeys `v² ≤ cap_start² + 2as` and `v² ≤ cap_end² + 2a(L - s)` (`v²` changes
/// by at most `2a` per unit length). Near a stop the speed is low, the centripetal terms
/// `K_i v²`, `3K_i v a` and `K'_i v³` are small, and much more of each axis limit is left
/// for the ramp than at the design speed, where the segment's own budget is worked out.
/// Each sample is checked at the highest speed the bounds allow over its neighbourhood
/// (the curvature terms taken as the largest of three neighbouring samples, with the
/// safety factors of [`super::bounds::transition_bounds`]), per axis: `|t_i| a_u + |K_i| u² ≤ A_i` and
/// `|t_i| j + 3|K_i| u a_u + |K'_i| u³ ≤ J_i` at every speed `u` up to that one, within
/// [`crate::PROFILE_SHARE`], with `a_u = min(a, sqrt(2j(v_max − u)))`, the acceleration the
/// jerk-limited envelope leaves at `u` (see [`Samples::jerk_for`]): near `v_max` a ramp has
/// little acceleration left, which is where the curvature terms are largest.
///
/// Returns the budget with its loss (see [`StopLoss`]); the piece's own design, with its
/// loss, where no candidate loses less.
pub(crate) fn ramp_budget(
    window: &PieceSamples,
    seg: &PlannedSegment,
    limits: &MachineLimits,
    cap_start: f64,
    cap_end: f64,
    section: Option<SectionEstimate>,
) -> Option<(f64, f64, f64)> {
    let samples = window.bounded(seg, limits, seg.v_max_mm_s, cap_start, cap_end);
    budget_on(&samples, seg, section)
}

/// The samples of a smoothed piece ([`window_samples`]) that its ramp budgets are found
/// on, taken once for [`ramp_budget`] and [`lowered_ramp_design`].
pub(crate) struct PieceSamples(Vec<Sample>);

impl PieceSamples {
    /// The samples of `seg` if it is a smoothed piece without rotary motion with a
    /// positive, finite design speed and length, else `None`.
    pub(crate) fn of(seg: &PlannedSegment) -> Option<Self> {
        let Curve::Transition(t) = &seg.curve else {
            return None;
        };
        let v_max = seg.v_max_mm_s;
        if seg.abc_poly.is_some()
            || seg.abc_start_deg != seg.abc_end_deg
            || !(v_max > 0.0 && v_max.is_finite() && seg.length_mm > 0.0)
        {
            return None;
        }
        window_samples(t, seg.length_mm).map(Self)
    }

    /// The samples of `seg` with what bounds its speed: designed for `v_max`, entered at
    /// most at `cap_start` and left at most at `cap_end`.
    fn bounded<'a>(
        &'a self,
        seg: &PlannedSegment,
        limits: &'a MachineLimits,
        v_max: f64,
        cap_start: f64,
        cap_end: f64,
    ) -> Samples<'a> {
        Samples {
            samples: &self.0,
            limits,
            v_max,
            cap_start,
            cap_end,
            length_mm: seg.length_mm,
        }
    }
}

/// [`ramp_budget`] on `samples` (the piece's, with the speed it is designed for and its
/// caps): `seg`'s own acceleration and jerk are the budget to beat, `seg`'s length the
/// room for a stop.
fn budget_on(
    samples: &Samples<'_>,
    seg: &PlannedSegment,
    section: Option<SectionEstimate>,
) -> Option<(f64, f64, f64)> {
    let v_max = samples.v_max;
    let a_top = samples.a_top()?;
    let stop = StopLoss {
        v_max,
        length_mm: seg.length_mm,
        section,
    };
    let own = stop.loss(seg.accel_mm_s2, seg.jerk_mm_s3);
    let Some((grid_loss, a_grid, j_grid)) = best_on_grid(samples, &stop, a_top, own) else {
        return Some((seg.accel_mm_s2, seg.jerk_mm_s3, own));
    };
    // Refined between the best point's neighbours, so that the choice hardly depends on
    // where the grid's points fall.
    let cost = |a: f64| {
        let j = samples.jerk_for(a);
        if j > 0.0 && j.is_finite() {
            stop.loss(a, j)
        } else {
            f64::INFINITY
        }
    };
    let (a, loss) = golden_min(
        a_grid * RAMP_GRID_RATIO,
        (a_grid / RAMP_GRID_RATIO).min(a_top),
        RAMP_GOLDEN_STEPS,
        cost,
    );
    if loss < grid_loss {
        return Some((a, samples.jerk_for(a), loss));
    }
    Some((a_grid, j_grid, grid_loss))
}

/// Lower design speeds tried for a piece at a stop ([`lowered_ramp_design`]), as shares of
/// its design speed: a fixed grid, so that the candidates do not move with the limits.
const LOWERED_DESIGN_FACTORS: [f64; 9] = [0.95, 0.9, 0.85, 0.8, 0.75, 0.7, 0.65, 0.6, 0.5];
/// A lowered design is taken only where its estimated loss is at most this share of the
/// design speed's: the estimate leaves out how the sections around the piece really
/// form, and a margin of 5 % kept every random surface of `benches/surface_sweep.py`
/// from coming out slower (at 1.0, a lowered piece estimated 2 % quicker ran 5 ms
/// slower on one of 300).
const LOWERED_DESIGN_GAIN: f64 = 0.95;

/// A lower design speed for a smoothed piece slow at exactly one end (entered from a stop
/// at `cap_start`, or stopping at `cap_end`), where the budget the axes leave at that
/// lower speed ([`ramp_budget`] of the piece designed for it) pays for running slower:
/// `Some((v, a, j))`, else `None`. Every term of an axis's jerk bound
/// `|t_i| j + 3|K_i| v a + |K'_i| v³` but the first falls with the speed: at raster B's
/// row ends, where the curvature's rate held the budget, pieces designed 15–30 % slower
/// have 1.5 to 2.5 times the jerk for their ramps.
///
/// Each candidate speed `v` of [`LOWERED_DESIGN_FACTORS`] is priced against running at
/// the design speed `v0`, as [`StopLoss`] prices budgets: the ramp between `v0` and `v`
/// outside the piece with `outer` (the section before a stop, the segment after a start),
/// the piece at `v` instead of `v0` (`L/v − L/v0`), and the piece's own ramp with the
/// lowered budget. The piece is then a motion-core section of its own (its speed is too
/// far below its neighbours' to join them, see `kerf_geom::speeds_merge_into`), and its
/// ramp must fit within it. Taken only where the loss is at most [`LOWERED_DESIGN_GAIN`] of
/// `base_loss`, the loss of the piece's choice at `v0`. The candidates are tried from the
/// fastest down, until the loss first rises (each costs a budget search, the planner's
/// largest cost on raster B).
///
/// Safe for the same reason as [`ramp_budget`]: the motion core never runs a segment
/// above its `v_max_mm_s` (a piece with a ramp budget has no boost design), and the
/// budget is found for the lowered speed.
pub(crate) fn lowered_ramp_design(
    window: &PieceSamples,
    seg: &PlannedSegment,
    limits: &MachineLimits,
    cap_start: f64,
    cap_end: f64,
    outer: (f64, f64),
    base_loss: f64,
) -> Option<(f64, f64, f64)> {
    let v0 = seg.v_max_mm_s;
    // The cap at the slow end.
    let slow = cap_start.min(cap_end);
    let mut best: Option<(f64, (f64, f64, f64))> = None;
    let mut last_loss = f64::INFINITY;
    for f in LOWERED_DESIGN_FACTORS {
        let v = f * v0;
        let samples = window.bounded(seg, limits, v, cap_start.min(v), cap_end.min(v));
        let Some((a, j, own_loss)) = budget_on(&samples, seg, None) else {
            continue;
        };
        if change_distance(slow.min(v), v, a, j) > seg.length_mm {
            continue;
        }
        let loss = time_lost(v0, v0, v, outer.0, outer.1) + seg.length_mm / v - seg.length_mm / v0
            + own_loss;
        if loss <= LOWERED_DESIGN_GAIN * base_loss && best.is_none_or(|b| loss < b.0) {
            best = Some((loss, (v, a, j)));
        }
        // The loss falls with the speed while the budget gains more than the slower run
        // costs, then rises: the first rise ends the search.
        if loss > last_loss {
            break;
        }
        last_loss = loss;
    }
    best.map(|b| b.1)
}

/// A sample of a piece for [`ramp_budget`]: the maxima over it and its two neighbours,
/// with the safety factors, and the arc lengths of that neighbourhood's ends.
struct Sample {
    tangent: [f64; 3],
    curvature: [f64; 3],
    curvature_rate: [f64; 3],
    s_lo: f64,
    s_hi: f64,
}

/// The [`PIECE_LIMIT_SAMPLES`] samples of `t` (of arc length `length_mm`): frames with
/// `dK/ds` in closed form and the arc length by the trapezoid rule on the speed, scaled
/// to `length_mm`; `None` if that scale is not finite.
fn window_samples(t: &Transition, length_mm: f64) -> Option<Vec<Sample>> {
    let n = PIECE_LIMIT_SAMPLES;
    // Frames with dK/ds in closed form, and the arc length (trapezoid on the speed).
    let frames: Vec<(Vec3, Vec3, Vec3)> = (0..=n)
        .map(|i| t.frame_rate_at_param(i as f64 / n as f64))
        .collect();
    let mut s = vec![0.0; n + 1];
    for i in 1..=n {
        let du = 1.0 / n as f64;
        s[i] = s[i - 1] + 0.5 * du * (t.speed((i - 1) as f64 * du) + t.speed(i as f64 * du));
    }
    let scale = length_mm / s[n];
    if !scale.is_finite() {
        return None;
    }
    s.iter_mut().for_each(|x| *x *= scale);
    // What the rate may rise between samples, per axis.
    let rise: [f64; 3] = std::array::from_fn(|ax| {
        let f: Vec<f64> = frames.iter().map(|f| f.2[ax]).collect();
        rise_between_samples(&f)
    });
    // Per sample: the window maxima with safety factors, and the window's extent.
    let samples = (0..=n)
        .map(|i| {
            let (ia, ib) = (i.saturating_sub(1), (i + 1).min(n));
            let mut x = Sample {
                tangent: [0.0; 3],
                curvature: [0.0; 3],
                curvature_rate: [0.0; 3],
                s_lo: s[ia],
                s_hi: s[ib],
            };
            for (tan, k, dk) in &frames[ia..=ib] {
                for ax in 0..3 {
                    x.tangent[ax] = x.tangent[ax].max(tan[ax].abs() * TANGENT_SAFETY);
                    x.curvature[ax] = x.curvature[ax].max(k[ax].abs() * CURVATURE_SAFETY);
                    x.curvature_rate[ax] =
                        x.curvature_rate[ax].max((dk[ax].abs() + rise[ax]) * RATE_SAFETY);
                }
            }
            x
        })
        .collect();
    Some(samples)
}

/// The samples of a piece with what bounds its speed: the design speed and the caps at
/// its ends.
struct Samples<'a> {
    samples: &'a [Sample],
    limits: &'a MachineLimits,
    v_max: f64,
    cap_start: f64,
    cap_end: f64,
    length_mm: f64,
}

impl Samples<'_> {
    /// The highest speed over sample `x`'s neighbourhood with path acceleration `a`.
    fn speed(&self, x: &Sample, a: f64) -> f64 {
        self.v_max
            .min((self.cap_start * self.cap_start + 2.0 * a * x.s_hi).sqrt())
            .min((self.cap_end * self.cap_end + 2.0 * a * (self.length_mm - x.s_lo)).sqrt())
    }

    /// The largest jerk the samples allow with acceleration `a`: 0 if `a` does not fit.
    /// Under the jerk-limited envelope (see [`super::envelope::envelope_budget`]): the
    /// section this piece runs in is at most `v_max` fast and has at most the jerk `j`
    /// found here, and a speed-up carried into or out of it (kerf-motion's
    /// `carry_target`) keeps `v + a²/2j` within that section's limit too, so at speed `u`
    /// the acceleration in use is at most `min(a, sqrt(2j(v_max − u)))`. Each sample's
    /// speeds `[0, v]` (`v` its highest, from the caps and `a`) are cut into
    /// [`RAMP_ENVELOPE_INTERVALS`], each covered conservatively (the curvature terms at
    /// its top, the acceleration at its bottom). Per axis and interval a jerk fits exactly
    /// when it fits with the full `a` or with the envelope alone (both in closed form), as
    /// in `envelope_budget`; the full `a` at `v` alone never gives a larger budget.
    fn jerk_for(&self, a: f64) -> f64 {
        let (limits, v_max, share) = (self.limits, self.v_max, PROFILE_SHARE);
        let mut j = f64::INFINITY;
        for x in self.samples {
            let v = self.speed(x, a);
            for k in 0..RAMP_ENVELOPE_INTERVALS {
                let n = RAMP_ENVELOPE_INTERVALS as f64;
                let (u_lo, u) = (v * k as f64 / n, v * (k + 1) as f64 / n);
                let d = (v_max - u_lo).max(0.0);
                for ax in 0..3 {
                    let Some(l) = limits.axes[ax] else {
                        if x.tangent[ax] > 0.0 || x.curvature[ax] > 0.0 {
                            return 0.0;
                        }
                        continue;
                    };
                    let (t, kc, kr) = (x.tangent[ax], x.curvature[ax], x.curvature_rate[ax]);
                    // t·min(a, sqrt(2jd)) + K u² ≤ A.
                    let room_a = share * l.acceleration_units_s2 - kc * u * u;
                    if room_a < 0.0 {
                        return 0.0;
                    }
                    if t * a > room_a {
                        j = j.min(room_a * room_a / (2.0 * d * t * t));
                    }
                    // t·j + 3K u·min(a, sqrt(2jd)) + K' u³ ≤ J.
                    let c = share * l.jerk_units_s3 - kr * u * u * u;
                    if c < 0.0 {
                        return 0.0;
                    }
                    let full = axis_rate(c - 3.0 * kc * u * a, t);
                    // t·y² + b·y ≤ c with y = sqrt(j).
                    let b = 3.0 * kc * u * (2.0 * d).sqrt();
                    let envelope = if t > 0.0 || b > 0.0 {
                        let y = 2.0 * c / (b + (b * b + 4.0 * t * c).sqrt());
                        y * y
                    } else {
                        f64::INFINITY
                    };
                    j = j.min(full.max(envelope));
                }
            }
        }
        j
    }

    /// The axes' acceleration over the largest tangent component, if positive and finite.
    fn a_top(&self) -> Option<f64> {
        let mut a_top = f64::INFINITY;
        for ax in 0..3 {
            if let Some(l) = self.limits.axes[ax] {
                let w = self
                    .samples
                    .iter()
                    .map(|x| x.tangent[ax])
                    .fold(0.0, f64::max);
                if w > 0.0 {
                    a_top = a_top.min(PROFILE_SHARE * l.acceleration_units_s2 / w);
                }
            }
        }
        (a_top > 0.0 && a_top.is_finite()).then_some(a_top)
    }
}

/// The time a jerk-limited change of speed from `v_from` down to `v_to` with `a` and `j`
/// loses against running on at `v_ref` over the same distance: its duration less its
/// distance at `v_ref`.
fn time_lost(v_ref: f64, v_from: f64, v_to: f64, a: f64, j: f64) -> f64 {
    let t = change_time_s(v_from - v_to, a, j);
    t - 0.5 * (v_from + v_to) * t / v_ref
}

/// How budgets are compared: by the time the stop from `v_max` loses against running on
/// at `v_max` (a ramp's duration less its distance at `v_max`), where they run: within
/// `section`, at the lesser of each limit (a budget that trades acceleration for jerk
/// would otherwise lower the acceleration of every ramp of the section).
struct StopLoss {
    v_max: f64,
    length_mm: f64,
    section: Option<SectionEstimate>,
}

impl StopLoss {
    /// The time a change of speed from `v_from` to `v_to` with `a` and `j` loses against
    /// running on at `v_max`.
    fn lost(&self, v_from: f64, v_to: f64, a: f64, j: f64) -> f64 {
        time_lost(self.v_max, v_from, v_to, a, j)
    }

    /// The time a stop with budget `(a, j)` loses where the piece runs.
    fn loss(&self, a: f64, j: f64) -> f64 {
        let v_max = self.v_max;
        match self.section {
            Some(s) if s.takes_curve(v_max, (a, j)) => {
                self.lost(v_max, 0.0, a.min(s.least.0), j.min(s.least.1))
            }
            // A budget the section would not take starts a section of its own at the
            // piece's start, passed with zero acceleration: the section before slows to
            // the speed from which the piece can stop within its length, and the piece
            // stops from there.
            Some(SectionEstimate {
                least: (sec_a, sec_j),
                ..
            }) => {
                let fits = |v: f64| 0.5 * v * change_time_s(v, a, j) <= self.length_mm;
                let v_b = if fits(v_max) {
                    v_max
                } else {
                    bisect(0.0, v_max, STOP_SPLIT_STEPS, fits)
                };
                self.lost(v_max, v_b, sec_a, sec_j) + self.lost(v_b, 0.0, a, j)
            }
            None => self.lost(v_max, 0.0, a, j),
        }
    }
}

/// The grid point with the least loss below `own` (the loss of the piece's own design):
/// `(loss, a, j)`. The grid starts at the highest acceleration a stop from `v_max` can
/// reach with the most jerk the samples allow (`jerk_for` does not rise with `a`): a
/// jerk-limited change of speed `v` peaks at `sqrt(v·j)`, so a higher budget only costs
/// jerk, and a grid tied to the axes' acceleration could lie wholly above what a short
/// piece's stop wants. `a_top` itself stays a candidate with its grid below it: whether a
/// budget joins the section before depends on its acceleration.
fn best_on_grid(
    samples: &Samples<'_>,
    stop: &StopLoss,
    a_top: f64,
    own: f64,
) -> Option<(f64, f64, f64)> {
    let j_most = samples.jerk_for(0.0);
    let a_reach = if j_most.is_finite() && j_most > 0.0 {
        (samples.v_max * j_most).sqrt() / RAMP_GRID_RATIO
    } else {
        a_top
    };
    // The first power of the ratio at or below the reach (`a_top` and `a_reach` are
    // positive and finite).
    let first_k = (a_reach.ln() / RAMP_GRID_RATIO.ln()).ceil();
    let mut best: Option<(f64, f64, f64)> = None;
    let below_top = (0..RAMP_GRID_POINTS).map(|k| a_top * RAMP_GRID_RATIO.powi(k as i32));
    let below_reach = (0..RAMP_GRID_POINTS).map(|k| RAMP_GRID_RATIO.powf(first_k + k as f64));
    // Where `a_top` is above the reach, both grids: the loss has several local minima
    // (a budget joins the section before or not), and each grid alone can miss one.
    let candidates = below_top.chain(below_reach.filter(|_| a_reach < a_top));
    // Without a section to join, the loss is one ramp's and falls as the jerk rises, and
    // `jerk_for(a)` is at most `j_most`: a point whose loss even with `j_most` does not
    // beat the best so far is passed over without its `jerk_for` (the same choice, for a
    // fraction of the work).
    let monotone = stop.section.is_none() && j_most.is_finite() && j_most > 0.0;
    for a in candidates {
        if monotone && stop.loss(a, j_most) >= best.map_or(own, |b| b.0) {
            continue;
        }
        let j = samples.jerk_for(a);
        if !(j > 0.0 && j.is_finite()) {
            continue;
        }
        let loss = stop.loss(a, j);
        if loss < own && best.is_none_or(|b| loss < b.0) {
            best = Some((loss, a, j));
        }
    }
    best
}
