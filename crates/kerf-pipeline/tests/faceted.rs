//! Faceted code (flat facets of a millimetre or so meeting at a few degrees, as
//! mesh-based CAM writes) at a tolerance too small to smooth it: every facet edge gets a
//! corner blend whose widest G2 form would overlap the next edge's, so it is narrowed to
//! the room it has. Measured from the setpoints: within the tolerance and every axis limit,
//! ends exactly on the program's end, and does not slow down to a crawl at the facet edges
//! (with circular blends there, whose curvature steps meet the next edge's, it came to
//! rest at most of them).

mod common;
use common::*;
use kerf_geom::{Move, Vec3};
use kerf_motion::MachineLimits;

/// Facets of `facet_mm` in the XZ plane along X, turning by `turn_deg` at every edge, the
/// sign of the turn changing every `wave` edges (a surface of gentle waves; `wave` larger
/// than the count gives a polygon along an arc).
fn facets(count: usize, facet_mm: f64, turn_deg: f64, wave: usize, feed: f64) -> Vec<Move> {
    let mut p = Vec3::zeros();
    let mut heading = -turn_deg.to_radians() * (wave.min(count) as f64 - 1.0) / 2.0;
    let mut sign = 1.0;
    let mut moves = Vec::new();
    for k in 0..count {
        let q = p + Vec3::new(heading.cos(), 0.0, heading.sin()) * facet_mm;
        moves.push(line(k as u32 + 1, p, q, feed));
        p = q;
        if (k + 1) % wave == 0 {
            sign = -sign;
        }
        heading += sign * turn_deg.to_radians();
    }
    moves
}

/// The lowest path speed over the middle facets (not the first and last two, where the
/// run starts and stops), mm/s, after checking limits, tolerance and the end point.
fn lowest_speed(name: &str, moves: &[Move], m: &MachineLimits) -> f64 {
    let mut lowest = f64::INFINITY;
    let n = moves.len();
    run_checked(name, moves, m, |sp| {
        let k = sp.move_index as usize;
        if (2..n - 2).contains(&k) {
            lowest = lowest.min(sp.feed_mm_s);
        }
    });
    lowest
}

/// The highest constant speed at which a path can turn by `turn_deg` within one facet
/// length with a jerk of at most `jerk_mm_s3` across the path: the sideways speed `v·θ`
/// must build up in the time `L/v` the facet takes, and with the jerk at its limit
/// throughout (up, then down) a change `Δv` takes `2·sqrt(Δv/j)`, so `v·θ ≤ j·(L/v)²/4`.
/// A rough upper estimate (the turn may spread a little wider, and the axes each have
/// the jerk), independent of the planner.
fn jerk_speed(jerk_mm_s3: f64, facet_mm: f64, turn_deg: f64) -> f64 {
    (jerk_mm_s3 * facet_mm * facet_mm / (4.0 * turn_deg.to_radians())).cbrt()
}

/// The lowest speed over the middle facets must be at least this share of the lesser of
/// the feed and [`jerk_speed`]: measured 0.50 to 0.99 of it on these machines, and
/// 0.0001 to 0.002 (at rest at nearly every edge) with circular blends at the edges.
const SHARE_OF_REFERENCE: f64 = 0.3;

#[test]
fn facet_edges_are_passed_without_a_crawl() {
    for (v, a, j, period_s) in [
        (200.0, 2000.0, 50_000.0, 0.001),
        (100.0, 1000.0, 20_000.0, 0.001),
        (500.0, 5000.0, 200_000.0, 0.00025),
        (50.0, 500.0, 5000.0, 0.002),
    ] {
        for (facet_mm, turn_deg, tol) in [(1.0, 5.0, 0.01), (1.0, 8.0, 0.02), (0.5, 4.0, 0.004)] {
            for wave in [3, 7, 1000] {
                let mut m = mill(v, a, j, tol);
                m.period_s = period_s;
                let feed = 3000.0;
                let moves = facets(40, facet_mm, turn_deg, wave, feed);
                let name = format!(
                    "{v} mm/s {a} mm/s² {j} mm/s³ {period_s} s, {facet_mm} mm facets at {turn_deg}°, \
                     wave {wave}, tolerance {tol}"
                );
                let lowest = lowest_speed(&name, &moves, &m);
                let reference = (feed / 60.0).min(jerk_speed(j, facet_mm, turn_deg));
                assert!(
                    lowest >= SHARE_OF_REFERENCE * reference,
                    "{name}: down to {lowest} mm/s, reference {reference} mm/s"
                );
            }
        }
    }
}
