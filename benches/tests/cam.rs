//! The CAM benchmark's measuring tools against closed forms worked out by hand: the
//! time-optimal lower bound on lines, circles and a blended corner, the time at the
//! programmed feed, and the corpus's programs against the geometry they were written from.

use std::f64::consts::{FRAC_PI_2, PI, SQRT_2, TAU};

mod common;
use common::{assert_rel, circle, line};

use kerf_benches::bound::{self, BoundMachine};
use kerf_benches::{cam, measure};
use kerf_geom::Vec3;

/// The small mill of issue 11 (the bound needs only velocity, acceleration, tolerance).
const MILL: BoundMachine = BoundMachine {
    velocity_mm_s: [200.0, 200.0, 100.0],
    acceleration_mm_s2: [2000.0, 2000.0, 1000.0],
    tolerance_mm: 0.01,
};

const DS_MM: f64 = 0.002;

#[test]
fn straight_line_takes_the_trapezoid_time() {
    // 100 mm along X at 50 mm/s, 2,000 mm/s²: accelerating takes v/a = 0.025 s over
    // v²/2a = 0.625 mm, twice; the rest at the feed: t = L/v + v/a.
    let b = bound::lower_bound(&[line([0.0; 3], [100.0, 0.0, 0.0], 50.0)], &MILL, DS_MM);
    assert_rel(b.time_s, 100.0 / 50.0 + 50.0 / 2000.0, 1e-4, "trapezoid");
    // Along Z the axis limits bind: 100 mm/s and 1,000 mm/s² (feed 200 mm/s asked).
    let b = bound::lower_bound(&[line([0.0; 3], [0.0, 0.0, -50.0], 200.0)], &MILL, DS_MM);
    assert_rel(b.time_s, 50.0 / 100.0 + 100.0 / 1000.0, 1e-4, "Z trapezoid");
}

#[test]
fn short_line_takes_the_triangle_time() {
    // 1 mm at 100 mm/s cannot reach the feed (v²/a = 5 mm > 1 mm): t = 2 √(L/a).
    let b = bound::lower_bound(&[line([0.0; 3], [1.0, 0.0, 0.0], 100.0)], &MILL, DS_MM);
    assert_rel(b.time_s, 2.0 * (1.0f64 / 2000.0).sqrt(), 1e-4, "triangle");
    // At 45° in XY both axes accelerate at 2,000 mm/s²: the path at 2,000 √2.
    let d = 10.0 / SQRT_2;
    let b = bound::lower_bound(&[line([0.0; 3], [d, d, 0.0], 1000.0)], &MILL, DS_MM);
    assert_rel(
        b.time_s,
        2.0 * (10.0 / (2000.0 * SQRT_2)).sqrt(),
        1e-4,
        "diagonal triangle",
    );
}

#[test]
fn circle_speed_limit_is_centripetal_with_tangential_help() {
    // On a circle of radius r at angle φ (tangent (−sin φ, cos φ), curvature vector
    // −(cos φ, sin φ)/r), axis accelerations are −sin φ s̈ − cos φ v²/r and
    // cos φ s̈ − sin φ v²/r. With both limited to a, the largest v² for which some s̈
    // fits is a r (|sin φ| + |cos φ|): a r where the normal is along an axis (v = √(a r)),
    // a r √2 at 45°.
    let (a, r) = (2000.0, 3.0);
    for deg in [0.0, 10.0, 30.0, 45.0, 60.0, 90.0, 135.0, 200.0, 300.0] {
        let phi = f64::to_radians(deg);
        let t = Vec3::new(-phi.sin(), phi.cos(), 0.0);
        let k = -Vec3::new(phi.cos(), phi.sin(), 0.0) / r;
        let x = bound::max_speed_squared(&t, &k, 1e6, &MILL);
        let want = a * r * (phi.sin().abs() + phi.cos().abs());
        // Where one axis carries all the tangent, the velocity limit is reached first
        // only above 200 mm/s; here √(a r √2) is 92 mm/s.
        assert_rel(x, want, 1e-9, &format!("v² at {deg}°"));
    }
}

#[test]
fn fast_circle_runs_at_the_centripetal_limit() {
    // Radius 2 mm at a feed far above what the acceleration allows: where the normal is
    // along X (φ = 0, π) the speed is √(a r) = 63.2 mm/s; one turn in steady motion takes
    // between 2πr / √(a r √2) (the highest limit everywhere) and 2πr / √(a r).
    let (a, r) = (2000.0f64, 2.0f64);
    let b = bound::lower_bound(&[circle(r, 4.0, 1000.0)], &MILL, DS_MM);
    let turn = TAU * r;
    // The third turn (s from 2 to 3 turns): at its start and half-way the normal is ±X.
    for s in [2.0 * turn, 2.5 * turn] {
        let i = b.s_mm.iter().position(|&x| x >= s).unwrap();
        assert_rel(
            b.speed_mm_s[i],
            (a * r).sqrt(),
            2e-3,
            "speed where the normal is X",
        );
    }
    let (i0, i1) = (
        b.s_mm.iter().position(|&x| x >= 2.0 * turn).unwrap(),
        b.s_mm.iter().position(|&x| x >= 3.0 * turn).unwrap(),
    );
    let t_turn: f64 = (i0..i1)
        .map(|i| 2.0 * (b.s_mm[i + 1] - b.s_mm[i]) / (b.speed_mm_s[i] + b.speed_mm_s[i + 1]))
        .sum();
    assert!(
        t_turn > turn / (a * r * SQRT_2).sqrt() && t_turn < turn / (a * r).sqrt(),
        "one turn {t_turn} s"
    );
}

#[test]
fn slow_circle_takes_the_feed_time_plus_one_ramp() {
    // Radius 10 mm at 50 mm/s: centripetal 250 mm/s², far under the limits; speeding up
    // where the tangent is along Y costs v/(2a) at each end: t = 2πr/v + v/a.
    let b = bound::lower_bound(&[circle(10.0, 1.0, 50.0)], &MILL, DS_MM);
    assert_rel(
        b.time_s,
        TAU * 10.0 / 50.0 + 50.0 / 2000.0,
        2e-4,
        "slow circle",
    );
}

#[test]
fn right_angle_corner_passes_at_the_blend_speed() {
    // 10 mm along X, then 10 mm along Y, 50 mm/s, tolerance 0.01 mm. The largest circular
    // blend whose middle is 0.01 mm from the vertex: R = ε cos 45° / (1 − cos 45°)
    // = 0.0241 mm, tangent length R tan 45° = R. Its speed at its ends (normal along one
    // axis) is √(a R) = 6.95 mm/s.
    let (a, v, eps) = (2000.0f64, 50.0f64, 0.01f64);
    let c = (PI / 4.0).cos();
    let r = eps * c / (1.0 - c);
    let pieces = [
        line([0.0; 3], [10.0, 0.0, 0.0], v),
        line([10.0, 0.0, 0.0], [10.0, 10.0, 0.0], v),
    ];
    let b = bound::lower_bound(&pieces, &MILL, DS_MM / 10.0);
    let corner = (a * r).sqrt();
    let lowest = b
        .s_mm
        .iter()
        .zip(&b.speed_mm_s)
        .filter(|(s, _)| (5.0..15.0).contains(*s))
        .map(|(_, v)| *v)
        .fold(f64::INFINITY, f64::min);
    assert_rel(lowest, corner, 2e-3, "corner speed");
    // Each leg (10 − R): 0 → v → corner speed at a, the rest at v; the arc (R π/2)
    // between √(a R) and √(a R √2).
    let leg = 10.0 - r;
    let ramps = v * v / (2.0 * a) + (v * v - corner * corner) / (2.0 * a);
    let leg_s = v / a + (v - corner) / a + (leg - ramps) / v;
    let arc = r * FRAC_PI_2;
    let (lo, hi) = (
        2.0 * leg_s + arc / (a * r * SQRT_2).sqrt(),
        2.0 * leg_s + arc / corner,
    );
    assert!(
        b.time_s > lo * (1.0 - 1e-4) && b.time_s < hi * (1.0 + 1e-4),
        "corner time {} not in [{lo}, {hi}]",
        b.time_s
    );
}

#[test]
fn feed_time_caps_the_feed_by_the_axis_velocities() {
    let config = measure::machine().unwrap();
    let machine = measure::bound_machine(&config);
    // Z at F12000 (200 mm/s) runs at Z's 100 mm/s; X at F3000 at the feed.
    let text = "G21 G90 G17 G94 F12000\nG1 Z-30\nG1 X40 F3000\nM2\n";
    let moves = measure::programmed_moves("t", text, &config).unwrap();
    let t = measure::feed_times(&moves, &machine);
    assert_rel(t[0].0, 30.0 / 100.0, 1e-12, "Z line");
    assert_rel(t[1].0, 40.0 / 50.0, 1e-12, "X line");
    // A full circle of radius 10 at F24000 (400 mm/s): at angle φ the speed is
    // 200 / max(|sin φ|, |cos φ|), so t = (r/200) ∫ max(|sin|, |cos|) dφ = (r/200) 4√2.
    let text = "G21 G90 G17 G94 F24000\nG2 X0 Y0 I10 J0\nM2\n";
    let moves = measure::programmed_moves("t", text, &config).unwrap();
    let t = measure::feed_times(&moves, &machine);
    assert_rel(t[0].0, 10.0 / 200.0 * 4.0 * SQRT_2, 1e-3, "fast circle");
}

#[test]
fn corpus_programs_follow_their_geometry() {
    let config = measure::machine().unwrap();
    for p in cam::corpus() {
        let moves = measure::programmed_moves(&p.name, &p.text, &config).unwrap();
        assert!(!moves.is_empty(), "{}", p.name);
        // Printed coordinates are rounded to at least 3 decimals.
        let rounding = 0.0005 * 3f64.sqrt() + 1e-9;
        assert!(
            moves[0].path.start().norm() < 1e-12,
            "{} starts at the origin",
            p.name
        );
        assert!(p.pieces[0].shape.start().norm() < 1e-12, "{}", p.name);
        for w in p.pieces.windows(2) {
            assert!(
                (w[0].shape.end() - w[1].shape.start()).norm() < 1e-9,
                "{}",
                p.name
            );
        }
        let end = moves.last().unwrap().path.end();
        let exact_end = p.pieces.last().unwrap().shape.end();
        assert!(
            (end - exact_end).norm() < rounding,
            "{}: end {end:?}",
            p.name
        );
        // Same length within 0.1 % (a chord of the dense circle is 1.3e-7 shorter than
        // its arc; the rasters' rows are sampled every 0.05 mm).
        let programmed: f64 = moves
            .iter()
            .map(|m| match m.path {
                kerf_geom::Path::Line(l) => (l.end - l.start).norm(),
                kerf_geom::Path::Arc(a) => {
                    let h = (a.end - a.start).dot(&a.axis);
                    ((a.start - a.center).norm() * a.sweep_rad).hypot(h)
                }
            })
            .sum();
        let exact: f64 = p.pieces.iter().map(|q| q.shape.length_mm()).sum();
        assert_rel(programmed, exact, 1e-3, &p.name);
    }
}

#[test]
fn kerf_is_never_faster_than_the_bounds_nor_the_bounds_than_the_feed() {
    // Small programs only (debug build): Kerf's run must take at least the jerk-limited
    // bound, that at least the acceleration-limited one, and that, from rest to rest, at
    // least the time at the feed.
    let config = measure::machine().unwrap();
    for p in [cam::pocket(1), cam::s_chain(3), cam::dense_circle(4, 360)] {
        let row = measure::measure(&p, &config, true).unwrap();
        let jerk_s = row.jerk_s.unwrap();
        assert!(row.bound_s > row.feed_time_s, "{}: {row:?}", p.name);
        assert!(jerk_s > row.bound_s, "{}: {row:?}", p.name);
        assert!(row.kerf.time_s >= jerk_s, "{}: {row:?}", p.name);
        assert!(row.kerf.max_deviation_mm <= 0.01, "{}: {row:?}", p.name);
    }
}

#[test]
fn raster_surfaces_carry_their_own_derivatives() {
    // The bound follows a row through ∂z/∂x and ∂²z/∂x² as each surface states them:
    // checked against central differences of z itself.
    let h = 1e-4;
    let gentle: fn(f64, f64) -> (f64, f64, f64) = cam::gentle_surface;
    for (name, f) in [
        ("gentle", gentle),
        ("curved", cam::curved_surface),
        ("wavy", cam::wavy_surface),
    ] {
        assert!(f(0.0, 0.0).0.abs() < 1e-15, "{name}: zero at the origin");
        for k in 0..400 {
            let (x, y) = (0.1 * k as f64, 0.5 * (k % 6) as f64);
            let (z, zx, zxx) = f(x, y);
            let (zm, zp) = (f(x - h, y).0, f(x + h, y).0);
            assert!((zx - (zp - zm) / (2.0 * h)).abs() < 1e-6, "{name} at {x}");
            assert!(
                (zxx - (zp - 2.0 * z + zm) / (h * h)).abs() < 1e-4,
                "{name} at {x}"
            );
        }
    }
}
