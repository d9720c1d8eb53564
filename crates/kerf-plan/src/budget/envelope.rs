//! The tangential budget `(a, j)` at one design speed under the jerk-limited envelope:
//! the acceleration a ramp has left at each speed below the design speed, and the jerk
//! the axes leave with it.

use std::cell::Cell;

use super::quickest::quickest_budget;
use crate::search::falsi_max;

/// Speed intervals of [`envelope_budget`]: the speeds `vd·(1 − (1 − k/N)²)`, denser near
/// `vd`, where the bound `sqrt(2j(vd − v))` on the acceleration changes fastest. Each
/// interval is covered conservatively, which loses jerk against the continuous envelope:
/// on an arc of 10 mm at 100 mm/s (this mill) 8 intervals give 28,000 mm/s³, 32 give
/// 32,300 and 64 give 32,800 (a continuous envelope about 33,300). 64: fewer leave the
/// rough design measure coarse enough that a raised limit can make a program slower
/// (`kerf-pipeline`'s `monotonic.rs`). Their count costs little: most intervals are
/// passed over (see [`envelope_budget`]).
const ENVELOPE_INTERVALS: usize = 64;
/// Relative width at which [`envelope_jerk`]'s root search stops: finer than a
/// 24-step bisection (`2⁻²⁴ ≈ 6e-8` of its bracket).
const ENVELOPE_REL: f64 = 1e-9;
/// Steps at most of that search (regula falsi, Illinois variant: it converges in about
/// ten where a bisection takes 24, and never leaves its bracket).
const ENVELOPE_STEPS: usize = 60;

/// The tangential budget `(a, j)` at design speed `vd` under the jerk-limited envelope
/// (ramps at the acceleration available at each speed), given the largest
/// tangential acceleration `accel_at(v)` the axes allow at speed `v` (`None`: none, the
/// centripetal terms take everything) and the largest jerk `jerk_at(v, a)` at speed `v`
/// with tangential acceleration `a`. Both never increase with `v` (the centripetal terms
/// grow with it), and `jerk_at` never increases with `a`.
///
/// The motion core runs each section at speeds at most the section's speed limit, which
/// is at most `vd` of each of its segments, with a jerk at most `j`, and starts and ends
/// it at `a = 0` except where it carries a speed-up across the boundary (kerf-motion's
/// `carry_target`): it does so only with `v + a²/2j` at the boundary within the speed
/// limits of both sections, each with its own jerk (`v + a²/2j` never falls while the
/// path speeds up with a jerk at most `j`). So wherever the path accelerates with `a > 0`
/// at speed `v`, the speed still rises by at least `a²/2j` before the acceleration is
/// back to zero, and `v + a²/2j` is within the limit of the section it is in; wherever
/// it decelerates it was higher by as much since the last `a = 0`: `v + a²/2j ≤ vd`, that
/// is `|a| ≤ sqrt(2j(vd − v))`. The full `a` and the highest speed never come together;
/// checking the full `a` at `vd` would ask for more than any profile uses, and on a
/// curve, where the centripetal terms grow with `v²` and `v·a`, cost much of the
/// acceleration (the dense circle: 980 mm/s² at 100 mm/s against about 1,800). A
/// hold's stop, which may cross into later sections, keeps to the same bound (the motion
/// core checks its peak speed against each section's limit).
///
/// The speeds `[0, vd]` are cut into [`ENVELOPE_INTERVALS`]; on `[v_k, v_k+1]` the bounds
/// are taken at `v_k+1` (the centripetal terms grow with `v`) with the acceleration
/// `a_k = min(a, sqrt(2j·d_k))`, `d_k = vd − v_k` (the envelope falls with `v`), a
/// conservative cover of the interval. The jerk `j` fits the acceleration `a` when
/// (1) `a_k ≤ accel_at(v_k+1)` on every interval, that is `j ≤ accel_at(v_k+1)²/2d_k`
/// where `a` exceeds it; and (2) `j ≤ jerk_at(v_k+1, a_k)` on every interval. As
/// `jerk_at` falls with its acceleration, `jerk_at(v, min(a, x)) = max(jerk_at(v, a),
/// jerk_at(v, x))`, so (2) holds on interval `k` exactly for `j ≤ max(J_k(a), E_k)` with
/// `J_k(a) = jerk_at(v_k+1, a)` (the full acceleration) and `E_k` the largest `j` with
/// `j ≤ jerk_at(v_k+1, sqrt(2j·d_k))` (the envelope alone, [`envelope_jerk`]), which does
/// not depend on `a`. The largest jerk is then `min(cap, min_k max(J_k(a), E_k))`,
/// the same as solving `j ≤ T(j)` over all the intervals at once (by bisection,
/// 24 × 64 evaluations per acceleration), but cheap: `J_k(a)` grows as `k` falls, so
/// the intervals are taken from the top speed down until `J_k(a)` reaches the least
/// value found (no lower interval can then lower it), and `E_k` is solved for only where
/// it is below that value (one evaluation tells), once per design speed.
pub(super) fn envelope_budget(
    vd: f64,
    accel_at: &dyn Fn(f64) -> Option<f64>,
    jerk_at: &dyn Fn(f64, f64) -> f64,
) -> Option<(f64, f64)> {
    if !(vd > 0.0 && vd.is_finite()) {
        return None;
    }
    const N: usize = ENVELOPE_INTERVALS;
    // Interval k: speeds [v[k], v[k + 1]], distance to vd at its start d[k].
    let v: [f64; N + 1] = std::array::from_fn(|k| {
        let x = 1.0 - k as f64 / N as f64;
        vd * (1.0 - x * x)
    });
    let d: [f64; N] = std::array::from_fn(|k| vd - v[k]);
    // The acceleration room per interval, made non-increasing in k (it is, up to the
    // rounding of `accel_at`; the running minimum is the conservative side).
    let mut room = [0.0; N];
    for k in 0..N {
        let r = accel_at(v[k + 1])?;
        room[k] = if k == 0 { r } else { r.min(room[k - 1]) };
    }
    // The acceleration caps of (1): where `a > room[k]`, that is on a suffix of the
    // intervals, `j ≤ room[k]²/2d_k`; their minimum over each suffix.
    let mut cap_from = [f64::INFINITY; N + 1];
    for k in (0..N).rev() {
        cap_from[k] = cap_from[k + 1].min(room[k] * room[k] / (2.0 * d[k]));
    }
    // The largest acceleration used anywhere: the room on the first interval.
    let a_hi = room[0];
    // E_k, solved for on first need (NaN: not yet), and a lower bound on it (a jerk
    // found within the envelope bound of interval k).
    let env: [Cell<f64>; N] = std::array::from_fn(|_| Cell::new(f64::NAN));
    let env_floor: [Cell<f64>; N] = std::array::from_fn(|_| Cell::new(0.0));
    let least = Cell::new(N);
    let jerk_for = |a: f64| -> f64 {
        let first_short = room.partition_point(|&r| r >= a);
        let mut best = cap_from[first_short];
        // A first bound from the interval with the least E known (the one that most
        // often ends up binding), so that most others are passed over at once.
        let k_least = least.get();
        if k_least < N {
            let full = jerk_at(v[k_least + 1], a);
            if full.is_nan() {
                return full;
            }
            best = best.min(full.max(env[k_least].get()));
        }
        for k in (0..N).rev() {
            // max(J_k(a), E_k) < best only if E_k < best: passed over, without an
            // evaluation, where E_k is known not to be.
            let known = env[k].get();
            if known >= best || env_floor[k].get() >= best {
                continue;
            }
            let full = jerk_at(v[k + 1], a);
            if full.is_nan() {
                return full;
            }
            if full >= best {
                // J_k(a) only grows below: no lower interval can lower `best`.
                break;
            }
            let e = if known.is_nan() {
                // Is `best` itself within the envelope bound of this interval? (Not
                // asked of an infinite bound: `jerk_at` of an infinite acceleration is
                // no answer, a 0·∞ on a straight piece.)
                if best.is_finite() && best <= jerk_at(v[k + 1], (2.0 * best * d[k]).sqrt()) {
                    env_floor[k].set(best);
                    continue;
                }
                // Is `J_k(a)` outside it? Then E_k < J_k(a) and the interval gives
                // `J_k(a)` (E_k itself is not needed).
                if full > jerk_at(v[k + 1], (2.0 * full.max(0.0) * d[k]).sqrt()) {
                    best = full;
                    continue;
                }
                let e = envelope_jerk(v[k + 1], d[k], full.max(0.0), best, jerk_at);
                env[k].set(e);
                if k_least >= N || e < env[k_least].get() {
                    least.set(k);
                }
                e
            } else {
                known
            };
            best = best.min(full.max(e));
        }
        best
    };
    quickest_budget(vd, a_hi, jerk_for)
}

/// `E`, the largest jerk `j` with `j ≤ jerk_at(v, sqrt(2j·d))` ([`envelope_budget`]'s
/// envelope bound of one interval), given `lo`, a jerk known to satisfy it, and `hi`, one
/// known not to (possibly infinite; `jerk_at(v, 0)` bounds `E` too). The condition holds
/// at 0 and stops holding once (the right side falls as `j` grows): regula falsi on
/// `j − jerk_at(v, sqrt(2j·d))` ([`falsi_max`]), which returns a jerk that satisfies it.
fn envelope_jerk(v: f64, d: f64, lo: f64, hi: f64, jerk_at: &dyn Fn(f64, f64) -> f64) -> f64 {
    let gap = |j: f64| j - jerk_at(v, (2.0 * j.max(0.0) * d).sqrt());
    if !hi.is_finite() {
        // `E ≤ jerk_at(v, 0)`: a finite bracket.
        let top = jerk_at(v, 0.0);
        if top.is_nan() || top <= lo {
            return lo;
        }
        if !top.is_finite() || gap(top) <= 0.0 {
            return top;
        }
        return falsi_max(lo, top, ENVELOPE_REL, ENVELOPE_STEPS, gap);
    }
    falsi_max(lo, hi, ENVELOPE_REL, ENVELOPE_STEPS, gap)
}
