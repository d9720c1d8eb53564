//! The memo key of a segment's limits: the exact bits of every input the computation
//! reads, so that a memo hit returns exactly what the computation would.

use kerf_geom::Curve;

use crate::PlannedSegment;
use crate::memo::{KEY_WORDS, Key};

/// Tags of [`limits_key`]'s first word.
const KEY_HELIX: u64 = 1;
const KEY_TRANSITION: u64 = 2;

/// The memo key of [`super::segment_limits_pair`] for `seg` (with the planner's fixed machine
/// limits): the exact bits of every input the computation reads. `None` for segments not
/// worth memoising (lines: their limits are a few divisions) or whose inputs do not fit a
/// key (transitions with rotary axes).
pub(crate) fn limits_key(
    seg: &PlannedSegment,
    feed_scale: f64,
    boost_scale: Option<f64>,
    run_mm: f64,
) -> Option<Key> {
    let mut key = [0u64; KEY_WORDS];
    let mut n = 0;
    let mut push = |x: f64| {
        key[n] = x.to_bits();
        n += 1;
    };
    // What every kind reads besides its shape.
    let common = |push: &mut dyn FnMut(f64)| {
        push(seg.length_mm);
        push(seg.feed_mm_s);
        push(run_mm);
        push(feed_scale);
        push(boost_scale.map_or(0.0, |_| 1.0));
        push(boost_scale.unwrap_or(0.0));
    };
    match &seg.curve {
        Curve::Line { .. } => return None,
        Curve::Helix(h) => {
            // What `arc::weights` reads (`curvature` is radius and sweep per length).
            push(f64::from_bits(KEY_HELIX));
            push(h.radius_mm);
            push(h.sweep_rad);
            push(h.rise_mm);
            push(h.length_mm);
            for i in 0..3 {
                push(h.axis[i]);
            }
            for i in 0..3 {
                push(h.drift_mm_per_rad[i]);
            }
            for i in 0..3 {
                push(seg.abc_end_deg[i] - seg.abc_start_deg[i]);
            }
            common(&mut push);
        }
        Curve::Transition(t) => {
            if seg.abc_poly.is_some() {
                return None;
            }
            // `bounds::transition_bounds` reads the coefficients of degree 1 and up (the
            // derivatives, the plane); the rest only whether it is a smoothed piece.
            push(f64::from_bits(KEY_TRANSITION));
            for c in &t.coef[1..] {
                for i in 0..3 {
                    push(c[i]);
                }
            }
            push(if seg.move_count > 1 { 1.0 } else { 0.0 });
            common(&mut push);
        }
    }
    Some(key)
}
