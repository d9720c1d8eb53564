//! Unit tests of the planner, measured on its output segments.

use super::*;
use kerf_geom::{Arc, Line};
use kerf_geom::{CornerMode, Curve, Move, Path, Vec3};

use kerf_testkit::machines::mill;

fn mv(path: Path, feed: f64) -> Move {
    Move {
        line: 1,
        rapid: false,
        path,
        feed_mm_min: Some(feed),
        abc_deg: None,
        corner: CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None,
        },
    }
}

fn plan(moves: &[Move]) -> Vec<PlannedSegment> {
    let mut p = Planner::new(mill());
    let mut out = Vec::new();
    for m in moves {
        p.push(m, &mut out).unwrap();
    }
    p.finish(&mut out);
    out
}

#[test]
fn diagonal_line_uses_both_axes() {
    // Along (1, 1, 0)/√2 each axis sees 1/√2 of the path: share · limit · √2.
    let line = Line {
        start: Vec3::zeros(),
        end: Vec3::new(10.0, 10.0, 0.0),
    };
    let segs = plan(&[mv(Path::Line(line), 60000.0)]);
    let s2 = std::f64::consts::SQRT_2;
    let share = PROFILE_SHARE;
    assert!((segs[0].v_max_mm_s - share * 200.0 * s2).abs() < 1e-9);
    assert!((segs[0].accel_mm_s2 - share * 2000.0 * s2).abs() < 1e-9);
    assert!((segs[0].jerk_mm_s3 - share * 50000.0 * s2).abs() < 1e-9);
    assert_eq!(segs[0].end_cap_mm_s, 0.0);
}

#[test]
fn arc_budget_respects_every_axis_under_the_jerk_limited_envelope() {
    // r = 10 at 100 mm/s: centripetal 1000 mm/s², jerk v³/r² = 10,000 mm/s³ at the feed.
    // The motion core runs from a = 0 to a = 0 with jerk ≤ j under the speed limit, so at
    // speed u it has at most a(u) = min(a, sqrt(2j(v − u))) (issue 11, item 3: the full
    // tangential acceleration and the top speed never come together). On the arc every
    // axis sees at most the norm of the in-plane vectors: the acceleration
    // sqrt((κu²)² + a(u)²) and the jerk sqrt((j + κ²u³)² + (3κu·a(u))²), which must stay
    // within the profile share of the limits at every speed up to the feed.
    let arc = Arc {
        start: Vec3::new(10.0, 0.0, 0.0),
        end: Vec3::new(-10.0, 0.0, 0.0),
        center: Vec3::zeros(),
        axis: Vec3::z(),
        sweep_rad: std::f64::consts::PI,
    };
    let segs = plan(&[mv(Path::Arc(arc), 6000.0)]);
    let s = &segs[0];
    assert!((s.v_max_mm_s - 100.0).abs() < 1e-9);
    let (k, v, a, j) = (0.1, s.v_max_mm_s, s.accel_mm_s2, s.jerk_mm_s3);
    let share = PROFILE_SHARE;
    for i in 0..=1000 {
        let u = v * i as f64 / 1000.0;
        let a_u = a.min((2.0 * j * (v - u)).sqrt());
        let acc = ((k * u * u).powi(2) + a_u * a_u).sqrt();
        assert!(acc <= share * 2000.0 + 1e-6, "u {u}: {acc}");
        let tang = j + k * k * u * u * u;
        let norm = 3.0 * k * u * a_u;
        let jerk = (tang * tang + norm * norm).sqrt();
        assert!(jerk <= share * 50000.0 + 1e-6, "u {u}: {jerk}");
    }
    // The envelope is worth having: more acceleration than the full acceleration at the
    // feed would leave, sqrt((share·2000)² − 1000²), and more than a third of the limits.
    assert!(
        a > ((share * 2000.0).powi(2) - 1000.0f64.powi(2)).sqrt(),
        "{a}"
    );
    assert!(a > 2000.0 / 3.0 && j > 50000.0 / 3.0);
}

/// Line along +X, tangent quarter arc of radius 5 (CCW), tangent line along +Y.
fn line_arc_line() -> Vec<Move> {
    let b = Vec3::new(20.0, 0.0, 0.0);
    let c = Vec3::new(25.0, 5.0, 0.0);
    vec![
        mv(
            Path::Line(Line {
                start: Vec3::zeros(),
                end: b,
            }),
            3000.0,
        ),
        mv(
            Path::Arc(Arc {
                start: b,
                end: c,
                center: Vec3::new(20.0, 5.0, 0.0),
                axis: Vec3::z(),
                sweep_rad: std::f64::consts::FRAC_PI_2,
            }),
            3000.0,
        ),
        mv(
            Path::Line(Line {
                start: c,
                end: Vec3::new(25.0, 25.0, 0.0),
            }),
            3000.0,
        ),
    ]
}

#[test]
fn g2_transitions_match_position_tangent_and_curvature() {
    let moves = line_arc_line();
    let segs = plan(&moves);
    let kinds: Vec<_> = segs
        .iter()
        .map(|s| matches!(s.curve, Curve::Transition(_)))
        .collect();
    assert_eq!(kinds, [false, true, false, true, false]);
    let origins: Vec<Curve> = moves.iter().map(|m| Curve::from_path(&m.path)).collect();
    for w in segs.windows(2) {
        // Continuous position at every joint, exactly.
        assert_eq!(w[0].curve.end(), w[1].curve.start());
    }
    let h = 1e-4;
    for k in [1, 3] {
        let (a, t, b) = (&segs[k - 1], &segs[k], &segs[k + 1]);
        // Finite differences of the transition at its ends (arc length h inside) against
        // the neighbours' exact tangent and curvature.
        let fd = |c: &Curve, s: f64| {
            let p = |x: f64| c.point_at(x);
            let d1 = (p(s + h) - p(s - h)) / (2.0 * h);
            let d2 = (p(s + h) - p(s) * 2.0 + p(s - h)) / (h * h);
            (d1, d2)
        };
        let ea = a.curve.eval(a.length_mm);
        let eb = b.curve.eval(0.0);
        let (t0, k0) = fd(&t.curve, 2.0 * h);
        let (t1, k1) = fd(&t.curve, t.length_mm - 2.0 * h);
        // Tangent: O(h·κ) from the offset; curvature: O(h·κ') and rounding.
        assert!((t0 - ea.tangent).norm() < 1e-3, "{t0} {}", ea.tangent);
        assert!((t1 - eb.tangent).norm() < 1e-3, "{t1} {}", eb.tangent);
        assert!((k0 - ea.curvature).norm() < 5e-3, "{k0} {}", ea.curvature);
        assert!((k1 - eb.curvature).norm() < 5e-3, "{k1} {}", eb.curvature);
        // Unit speed: the arc-length table is right.
        for i in 1..100 {
            let s = t.length_mm * i as f64 / 100.0;
            let (d1, _) = fd(&t.curve, s);
            assert!((d1.norm() - 1.0).abs() < 1e-6, "{}", d1.norm());
        }
        // Within the tolerance of the programmed path, measured densely.
        let dev = (0..=2000)
            .map(|i| {
                let p = t.curve.point_at(t.length_mm * i as f64 / 2000.0);
                origins
                    .iter()
                    .map(|o| o.distance_to(&p))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max);
        assert!(dev <= 0.01 && dev > 0.001, "{dev}");
        // The joint runs far faster than the curvature-step cap sqrt(0.05·J·T·r).
        let step_cap = (JUNCTION_SHARE * 50000.0 * 0.001 * 5.0).sqrt();
        assert!(a.end_cap_mm_s > 5.0 * step_cap && t.end_cap_mm_s > 5.0 * step_cap);
        assert!(t.v_max_mm_s > 5.0 * step_cap);
    }
}

#[test]
fn collinear_joint_runs_through_and_exact_stop_stops() {
    let a = Vec3::zeros();
    let b = Vec3::new(5.0, 0.0, 0.0);
    let c = Vec3::new(9.0, 0.0, 0.0);
    let d = Vec3::new(9.0, 4.0, 0.0);
    let first = mv(Path::Line(Line { start: a, end: b }), 3000.0);
    let mut second = mv(Path::Line(Line { start: b, end: c }), 3000.0);
    second.corner = CornerMode::ExactStop;
    let third = mv(Path::Line(Line { start: c, end: d }), 3000.0);
    let segs = plan(&[first, second, third]);
    assert_eq!(
        segs.len(),
        3,
        "no blend at a collinear joint or an exact stop"
    );
    assert_eq!(
        segs[0].end_cap_mm_s,
        segs[0].v_max_mm_s.min(segs[1].v_max_mm_s)
    );
    assert_eq!(segs[1].end_cap_mm_s, 0.0);
}

/// Finite differences of a curve at `s` with step `h`: (first, second derivative).
fn fd(c: &Curve, s: f64, h: f64) -> (Vec3, Vec3) {
    let p = |x: f64| c.point_at(x);
    let d1 = (p(s + h) - p(s - h)) / (2.0 * h);
    let d2 = (p(s + h) - p(s) * 2.0 + p(s - h)) / (h * h);
    (d1, d2)
}

#[test]
fn sharp_isolated_corner_stops_where_that_is_quicker() {
    // 90° between two 10 mm lines at 0.01 mm: any blend must slow nearly to a stop and
    // then crawl through it, so the corner is taken as a stop (no blend segment, a
    // near-zero cap from the kink).
    let (a, b, c) = (
        Vec3::zeros(),
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(10.0, 10.0, 0.0),
    );
    let moves = [
        mv(Path::Line(Line { start: a, end: b }), 3000.0),
        mv(Path::Line(Line { start: b, end: c }), 3000.0),
    ];
    let segs = plan(&moves);
    assert_eq!(segs.len(), 2);
    assert_eq!(segs[0].curve.end(), b);
    assert!(segs[0].end_cap_mm_s < 0.01, "{}", segs[0].end_cap_mm_s);
}

#[test]
fn isolated_corner_gets_a_g2_blend() {
    // A 10° corner between two 10 mm lines at 0.01 mm: the blend takes a few
    // millimetres at most, so the corner is isolated, and a G2 blend is quicker than
    // an arc (whose joints are curvature steps) or a stop.
    let th = 10f64.to_radians();
    let (a, b) = (Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0));
    let u2 = Vec3::new(th.cos(), th.sin(), 0.0);
    let c = b + u2 * 10.0;
    let moves = [
        mv(Path::Line(Line { start: a, end: b }), 3000.0),
        mv(Path::Line(Line { start: b, end: c }), 3000.0),
    ];
    let segs = plan(&moves);
    assert_eq!(segs.len(), 3);
    let Curve::Transition(_) = segs[1].curve else {
        panic!("expected a G2 blend, got {:?}", segs[1].curve)
    };
    assert!(segs[1].blend && !segs[0].blend && !segs[2].blend);
    for w in segs.windows(2) {
        assert_eq!(w[0].curve.end(), w[1].curve.start());
    }
    let t = &segs[1];
    let len = t.length_mm;
    // Symmetric: it takes the same distance d from both lines.
    let d = (b - t.curve.start()).norm();
    assert!((d - (t.curve.end() - b).norm()).abs() < 1e-12);
    // Tangent of the lines and zero curvature at both ends, by finite differences
    // (the curvature extrapolated to the end from 2h and 4h inside: it grows
    // linearly from zero there).
    let h = 1e-4;
    for (s, sign, u) in [(0.0, 1.0, Vec3::x()), (len, -1.0, u2)] {
        let (t1, k1) = fd(&t.curve, s + sign * 2.0 * h, h);
        let (_, k2) = fd(&t.curve, s + sign * 4.0 * h, h);
        let k_end = k1 * 2.0 - k2;
        assert!((t1 - u).norm() < 1e-3, "tangent {t1} at {s}");
        // The circular blend's curvature is 1/r ≈ 0.4 /mm, all of it a step.
        assert!(k_end.norm() < 0.01, "curvature {k_end} at {s}");
    }
    // Unit speed inside (the arc-length table is right).
    for i in 1..100 {
        let (d1, _) = fd(&t.curve, len * i as f64 / 100.0, 1e-5);
        assert!((d1.norm() - 1.0).abs() < 1e-6, "{}", d1.norm());
    }
    // Within the tolerance of the two lines, densely, and using most of it.
    let lines: Vec<Curve> = moves.iter().map(|m| Curve::from_path(&m.path)).collect();
    let dev = (0..=5000)
        .map(|i| {
            let p = t.curve.point_at(len * i as f64 / 5000.0);
            lines
                .iter()
                .map(|l| l.distance_to(&p))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    assert!(dev <= 0.01 && dev > 0.008, "{dev}");
    // The joints have no curvature step, so only the blend itself limits the speed, and
    // that is far above the circular blend's curvature-step cap sqrt(0.05·J·T·r) with
    // r (1 - cos 5°) = 0.98 · tolerance.
    let r = 0.98 * 0.01 / (1.0 - (th / 2.0).cos());
    let step_cap = (JUNCTION_SHARE * 50000.0 * 0.001 * r).sqrt();
    assert!(
        t.v_max_mm_s > 5.0 * step_cap,
        "{} vs {step_cap}",
        t.v_max_mm_s
    );
    assert_eq!(segs[0].end_cap_mm_s, t.v_max_mm_s);
    assert_eq!(t.end_cap_mm_s, t.v_max_mm_s);
    // Its limits hold at v_max: centripetal |K|v² within the axis acceleration.
    let k_peak = (0..=1000)
        .map(|i| t.curve.eval(len * i as f64 / 1000.0).curvature.norm())
        .fold(0.0, f64::max);
    assert!(k_peak * t.v_max_mm_s * t.v_max_mm_s <= 2000.0, "{k_peak}");
}
