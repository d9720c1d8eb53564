//! The CAM benchmark corpus (issue 11): generated LinuxCNC programs of the kinds CAM
//! systems write, each with the exact geometry it was written from.
//!
//! Every program starts at the origin (where `kerf sim` starts the machine), uses only
//! feed moves under `G64 P0.01`, and ends with `M2`. Its [`CamProgram::pieces`] are the
//! exact path the program approximates: the same lines, arcs and helices where the printed
//! coordinates are exact, and the smooth curve itself where the program is a dense
//! polyline of rounded points (the rasters and the 3,600-line circle). The lower bound of
//! the table is computed on that geometry (see [`crate::bound`]): rounding to 3 decimals
//! moves a point by at most 0.0009 mm, a tenth of the tolerance, and a bound on the
//! rounded vertices themselves would have to pass every rounding kink as a corner.
//!
//! Everything is computed from closed forms: the same program comes out on every run.

use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;

use kerf_geom::Vec3;

use crate::bound::{Piece, Shape};

/// A generated program and the geometry it was written from.
#[derive(Clone, Debug)]
pub struct CamProgram {
    /// Short name for the table.
    pub name: String,
    /// The program text (LinuxCNC).
    pub text: String,
    /// The exact path, from the origin, with the programmed feed.
    pub pieces: Vec<Piece>,
}

impl CamProgram {
    /// Lines of the program text.
    pub fn lines(&self) -> usize {
        self.text.lines().count()
    }
}

/// The whole corpus, in table order.
pub fn corpus() -> Vec<CamProgram> {
    let mut out = Vec::new();
    for d in [3, 4, 6] {
        out.push(raster("raster A", gentle_surface, d, 6, 20.0));
    }
    for d in [3, 4, 6] {
        out.push(raster("raster B", curved_surface, d, 3, 40.0));
    }
    out.push(raster("raster C", wavy_surface, 4, 3, 40.0));
    out.push(faceted("faceted A", gentle_surface, 6, 20.0));
    for d in [3, 4, 6] {
        out.push(dense_circle(d, 3600));
    }
    out.push(pocket(4));
    out.push(helix("helix r5 G2", 5.0, false, 3, 0.5, 3000.0));
    out.push(helix("helix r1.5 G3", 1.5, true, 6, 0.3, 3000.0));
    out.push(obround(2));
    out.push(s_chain(8));
    out
}

/// Prints `v` with `decimals` decimals, without a minus sign on a zero.
fn num(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].bytes().all(|b| b == b'0' || b == b'.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Appends the block moving to `p` with `decimals` decimals, `G1` on the `first` one
/// (modal after it).
fn g1_point(text: &mut String, first: &mut bool, p: Vec3, decimals: usize) {
    let g = if *first { "G1 " } else { "" };
    *first = false;
    let _ = writeln!(
        text,
        "{g}X{} Y{} Z{}",
        num(p.x, decimals),
        num(p.y, decimals),
        num(p.z, decimals)
    );
}

/// The program's first block: millimetres, absolute, XY plane, feed per minute, blending
/// within 0.01 mm, and the feed.
fn header(feed_mm_min: f64) -> String {
    format!("G21 G90 G17 G94 G64 P0.01 F{feed_mm_min}\n")
}

/// Distance between raster points along a row, mm.
pub const RASTER_STEP_MM: f64 = 0.05;
/// Distance between raster rows, mm.
pub const RASTER_ROW_GAP_MM: f64 = 0.5;

/// A gentle surface for raster A: `(z, ∂z/∂x, ∂²z/∂x²)` at `(x, y)`, mm. Zero at the
/// origin; slopes along X up to about 0.55, curvature radii down to about 5 mm (at the
/// feed, at most half of Z's acceleration).
pub fn gentle_surface(x: f64, y: f64) -> (f64, f64, f64) {
    let (s1, c1) = (x / 4.0).sin_cos();
    let cy = (y / 6.0).cos();
    let (s2, c2) = ((x + y) / 1.7).sin_cos();
    (
        1.5 * s1 * cy + 0.3 * s2,
        1.5 / 4.0 * c1 * cy + 0.3 / 1.7 * c2,
        -1.5 / 16.0 * s1 * cy - 0.3 / (1.7 * 1.7) * s2,
    )
}

/// A more curved surface for raster B, zero at the origin: slopes along X up to about
/// 0.85, curvature radii down to about 2.2 mm, where Z's acceleration limit holds the
/// speed a little under the feed.
pub fn curved_surface(x: f64, y: f64) -> (f64, f64, f64) {
    let (s1, c1) = (x / 2.5).sin_cos();
    let cy = (y / 4.0).cos();
    let (s2, c2) = ((x + y) / 1.2).sin_cos();
    (
        1.5 * s1 * cy + 0.3 * s2,
        1.5 / 2.5 * c1 * cy + 0.3 / 1.2 * c2,
        -1.5 / 6.25 * s1 * cy - 0.3 / 1.44 * s2,
    )
}

/// A wavy surface for raster C, zero at the origin: waves of 7.9 mm and 3.1 mm along X
/// (amplitudes 0.6 and 0.1 mm), where Z's jerk limit, not its acceleration, holds the
/// speed far under the feed: at a constant speed `v` Z's jerk is `z'''·v³` (`|z'''|` up
/// to about 1.1 /mm², on the flanks of the short wave), so under 30 mm/s there.
pub fn wavy_surface(x: f64, y: f64) -> (f64, f64, f64) {
    let (s1, c1) = (x / 1.25).sin_cos();
    let cy = (y / 4.0).cos();
    let (s2, c2) = ((x + y) / 0.5).sin_cos();
    (
        0.6 * s1 * cy + 0.1 * s2,
        0.6 / 1.25 * c1 * cy + 0.1 / 0.5 * c2,
        -0.6 / 1.5625 * s1 * cy - 0.1 / 0.25 * s2,
    )
}

/// Facet size of the faceted rasters, mm.
pub const FACET_MM: f64 = 1.0;

/// A raster over a triangulated surface as mesh-based CAM writes it, named `name`: `rows`
/// rows of `row_mm` along X, 0.5 mm apart, with a G1 point where the row crosses a facet
/// edge (every [`FACET_MM`] along X), Z taken from `surface` at those points and written
/// with 4 decimals, F3000; rows joined by one move along Y (and Z). Between its points
/// the path is flat: its exact geometry is the lines between the unrounded points, which
/// meet at small angles (a few degrees on the gentle surface).
pub fn faceted(
    name: &str,
    surface: fn(f64, f64) -> (f64, f64, f64),
    rows: usize,
    row_mm: f64,
) -> CamProgram {
    let feed_mm_min = 3000.0;
    let feed_mm_s = feed_mm_min / 60.0;
    let points = (row_mm / FACET_MM).round() as usize;
    let mut text = header(feed_mm_min);
    let mut pieces = Vec::new();
    let mut at = Vec3::zeros();
    let mut first = true;
    let mut go = |text: &mut String, pieces: &mut Vec<Piece>, x: f64, y: f64| {
        let p = Vec3::new(x, y, surface(x, y).0);
        g1_point(text, &mut first, p, 4);
        pieces.push(Piece {
            shape: Shape::Line { start: at, end: p },
            feed_mm_s,
        });
        at = p;
    };
    for r in 0..rows {
        let y = r as f64 * RASTER_ROW_GAP_MM;
        let forward = r % 2 == 0;
        let x_at = |i: usize| {
            let k = if forward { i } else { points - i };
            k as f64 * FACET_MM
        };
        for i in 1..=points {
            go(&mut text, &mut pieces, x_at(i), y);
        }
        if r + 1 < rows {
            go(&mut text, &mut pieces, x_at(points), y + RASTER_ROW_GAP_MM);
        }
    }
    text.push_str("M2\n");
    CamProgram {
        name: name.to_string(),
        text,
        pieces,
    }
}

/// A 3D raster finishing pass named `name`: `rows` rows of `row_mm` along X, 0.5 mm
/// apart, with a G1 point every 0.05 mm whose Z is `surface` (`(z, ∂z/∂x, ∂²z/∂x²)`, zero
/// at the origin) written with `decimals` decimals, F3000, each row joined to the next by
/// one move along Y (and Z).
pub fn raster(
    name: &str,
    surface: fn(f64, f64) -> (f64, f64, f64),
    decimals: usize,
    rows: usize,
    row_mm: f64,
) -> CamProgram {
    let feed_mm_min = 3000.0;
    let feed_mm_s = feed_mm_min / 60.0;
    let points = (row_mm / RASTER_STEP_MM).round() as usize;
    let mut text = header(feed_mm_min);
    let mut pieces = Vec::new();
    let mut first = true;
    let mut point = |text: &mut String, x: f64, y: f64| {
        g1_point(text, &mut first, Vec3::new(x, y, surface(x, y).0), decimals);
    };
    for r in 0..rows {
        let y = r as f64 * RASTER_ROW_GAP_MM;
        let forward = r % 2 == 0;
        let x_at = |i: usize| {
            let k = if forward { i } else { points - i };
            k as f64 * RASTER_STEP_MM
        };
        for i in 1..=points {
            point(&mut text, x_at(i), y);
        }
        pieces.push(Piece {
            shape: Shape::Row {
                surface,
                y,
                x_from: x_at(0),
                x_to: x_at(points),
            },
            feed_mm_s,
        });
        if r + 1 < rows {
            let x = x_at(points);
            let y_next = y + RASTER_ROW_GAP_MM;
            point(&mut text, x, y_next);
            pieces.push(Piece {
                shape: Shape::Line {
                    start: Vec3::new(x, y, surface(x, y).0),
                    end: Vec3::new(x, y_next, surface(x, y_next).0),
                },
                feed_mm_s,
            });
        }
    }
    text.push_str("M2\n");
    CamProgram {
        name: format!("{name} {decimals} dec"),
        text,
        pieces,
    }
}

/// The circle in XY of radius `r_mm` about (r, 0, 0), from the origin, counter-clockwise,
/// `turns` times round, at `feed_mm_s`: the exact path of [`dense_circle`].
pub fn circle_piece(r_mm: f64, turns: f64, feed_mm_s: f64) -> Piece {
    Piece {
        shape: Shape::Arc {
            center: Vec3::new(r_mm, 0.0, 0.0),
            e1: Vec3::new(-1.0, 0.0, 0.0),
            e2: Vec3::new(0.0, 1.0, 0.0),
            radius_mm: r_mm,
            from_rad: 0.0,
            to_rad: TAU * turns,
            axial_per_rad: Vec3::zeros(),
        },
        feed_mm_s,
    }
}

/// The dense circle of docs/PERFORMANCE.md: radius 10 mm through the origin, centre
/// (10, 0), clockwise, in `chords` G1 lines with `decimals` decimals, F6000.
pub fn dense_circle(decimals: usize, chords: usize) -> CamProgram {
    let feed_mm_min = 6000.0;
    let r = 10.0;
    let mut text = header(feed_mm_min);
    for k in 1..=chords {
        let phi = TAU * k as f64 / chords as f64;
        let _ = writeln!(
            text,
            "G1 X{} Y{}",
            num(r - r * phi.cos(), decimals),
            num(r * phi.sin(), decimals)
        );
    }
    text.push_str("M2\n");
    let pieces = vec![circle_piece(r, 1.0, feed_mm_min / 60.0)];
    CamProgram {
        name: format!("circle {chords} {decimals} dec"),
        text,
        pieces,
    }
}

/// A rectangular pocket: `loops` rectangles around the origin, half-sizes 2k × 1.5k mm,
/// each started at its (+X, −Y) corner and joined to the next by a diagonal step; every
/// corner sharp (90° inside a loop), F3000.
pub fn pocket(loops: usize) -> CamProgram {
    let feed_mm_min = 3000.0;
    let mut text = header(feed_mm_min);
    let mut pieces = Vec::new();
    let mut at = Vec3::zeros();
    for k in 1..=loops {
        let (hx, hy) = (2.0 * k as f64, 1.5 * k as f64);
        for (x, y) in [(hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)] {
            let p = Vec3::new(x, y, 0.0);
            let _ = writeln!(text, "G1 X{} Y{}", num(x, 3), num(y, 3));
            pieces.push(Piece {
                shape: Shape::Line { start: at, end: p },
                feed_mm_s: feed_mm_min / 60.0,
            });
            at = p;
        }
    }
    text.push_str("M2\n");
    CamProgram {
        name: format!("pocket {loops} loops"),
        text,
        pieces,
    }
}

/// An arc in a plane of constant Z (or a helix with `dz_per_rad`) from `start` about the
/// centre `center` (same Z), counter-clockwise seen from +Z when `ccw`, over `sweep_rad`.
fn arc_xy(start: Vec3, center: Vec3, ccw: bool, sweep_rad: f64, dz_per_rad: f64) -> Shape {
    let radius_mm = (start - center).norm();
    let e1 = (start - center) / radius_mm;
    let z_cross_e1 = Vec3::new(-e1.y, e1.x, 0.0);
    Shape::Arc {
        center,
        e1,
        e2: if ccw { z_cross_e1 } else { -z_cross_e1 },
        radius_mm,
        from_rad: 0.0,
        to_rad: sweep_rad,
        axial_per_rad: Vec3::new(0.0, 0.0, dz_per_rad),
    }
}

/// A helical ramp down from the origin: `turns` full turns of radius `radius_mm` about
/// (radius, 0), `pitch_mm` down per turn, one `G2`/`G3` block per turn.
pub fn helix(
    name: &str,
    radius_mm: f64,
    ccw: bool,
    turns: usize,
    pitch_mm: f64,
    feed_mm_min: f64,
) -> CamProgram {
    let mut text = header(feed_mm_min);
    let g = if ccw { "G3" } else { "G2" };
    for t in 1..=turns {
        let z = -pitch_mm * t as f64;
        let _ = writeln!(text, "{g} X0 Y0 Z{} I{radius_mm} J0", num(z, 3));
    }
    text.push_str("M2\n");
    let pieces = vec![Piece {
        shape: arc_xy(
            Vec3::zeros(),
            Vec3::new(radius_mm, 0.0, 0.0),
            ccw,
            TAU * turns as f64,
            -pitch_mm / TAU,
        ),
        feed_mm_s: feed_mm_min / 60.0,
    }];
    CamProgram {
        name: name.to_string(),
        text,
        pieces,
    }
}

/// A tangent line-arc chain: `loops` times round a 24 × 12 mm rectangle with corners
/// rounded by tangent quarter circles of 2 mm (G1, G3, G1, G3, ...), F6000, where the arcs
/// (centripetal limit about 63 mm/s) are slower than the lines.
pub fn obround(loops: usize) -> CamProgram {
    let feed_mm_min = 6000.0;
    let feed_mm_s = feed_mm_min / 60.0;
    let mut text = header(feed_mm_min);
    let mut pieces = Vec::new();
    let v = |x: f64, y: f64| Vec3::new(x, y, 0.0);
    // (line end, arc end, arc centre)
    let sides = [
        (v(20.0, 0.0), v(22.0, 2.0), v(20.0, 2.0)),
        (v(22.0, 10.0), v(20.0, 12.0), v(20.0, 10.0)),
        (v(0.0, 12.0), v(-2.0, 10.0), v(0.0, 10.0)),
        (v(-2.0, 2.0), v(0.0, 0.0), v(0.0, 2.0)),
    ];
    let mut at = Vec3::zeros();
    for _ in 0..loops {
        for (line_end, arc_end, c) in sides {
            let _ = writeln!(text, "G1 X{} Y{}", num(line_end.x, 3), num(line_end.y, 3));
            pieces.push(Piece {
                shape: Shape::Line {
                    start: at,
                    end: line_end,
                },
                feed_mm_s,
            });
            let (i, j) = (c.x - line_end.x, c.y - line_end.y);
            let _ = writeln!(
                text,
                "G3 X{} Y{} I{} J{}",
                num(arc_end.x, 3),
                num(arc_end.y, 3),
                num(i, 3),
                num(j, 3)
            );
            pieces.push(Piece {
                shape: arc_xy(line_end, c, true, PI / 2.0, 0.0),
                feed_mm_s,
            });
            at = arc_end;
        }
    }
    text.push_str("M2\n");
    CamProgram {
        name: format!("obround x{loops} F6000"),
        text,
        pieces,
    }
}

/// A tangent S-chain: `arcs` half circles of radius 2 mm turning alternately left (G3) and
/// right (G2), joined by 1 mm lines along Y, F3000: the curvature reverses at every join.
pub fn s_chain(arcs: usize) -> CamProgram {
    let feed_mm_min = 3000.0;
    let feed_mm_s = feed_mm_min / 60.0;
    let mut text = header(feed_mm_min);
    let mut pieces = Vec::new();
    let mut at = Vec3::zeros();
    for k in 0..arcs {
        let ccw = k % 2 == 0;
        let c = at + Vec3::new(2.0, 0.0, 0.0);
        let end = at + Vec3::new(4.0, 0.0, 0.0);
        let _ = writeln!(
            text,
            "{} X{} Y{} I2 J0",
            if ccw { "G3" } else { "G2" },
            num(end.x, 3),
            num(end.y, 3)
        );
        pieces.push(Piece {
            shape: arc_xy(at, c, ccw, PI, 0.0),
            feed_mm_s,
        });
        at = end;
        if k + 1 < arcs {
            // A left half circle ends heading +Y, a right one heading −Y.
            let next = at + Vec3::new(0.0, if ccw { 1.0 } else { -1.0 }, 0.0);
            let _ = writeln!(text, "G1 X{} Y{}", num(next.x, 3), num(next.y, 3));
            pieces.push(Piece {
                shape: Shape::Line {
                    start: at,
                    end: next,
                },
                feed_mm_s,
            });
            at = next;
        }
    }
    text.push_str("M2\n");
    CamProgram {
        name: format!("s-chain {arcs} arcs"),
        text,
        pieces,
    }
}

/// A non-repeating dense finishing raster of `segments` G1 moves, the same for the same
/// `seed`: rows of 30 mm along X, 0.5 mm apart, a point every 0.05 mm, F3000, G64 P0.01,
/// Z on a gentle surface (two waves whose amplitudes and wavelengths change from row to
/// row, drawn from the seed) plus a seeded noise of ±`noise_mm` at every point, written
/// with 4 decimals. No two moves have the same shape, so the planner's memos of repeated
/// shapes never help: this is planning's cost on code that never repeats.
pub fn noisy_surface(segments: usize, seed: u64, noise_mm: f64) -> String {
    let mut rng = SplitMix64(seed);
    let points = (30.0 / RASTER_STEP_MM).round() as usize;
    let mut text = String::with_capacity(segments * 28 + 64);
    text.push_str(&header(3000.0));
    let mut written = 0usize;
    let mut row = 0usize;
    let mut first = true;
    while written < segments {
        let y = row as f64 * RASTER_ROW_GAP_MM;
        let forward = row.is_multiple_of(2);
        let (a1, l1) = (0.2 + 1.3 * rng.unit(), 2.0 + 6.0 * rng.unit());
        let (a2, l2) = (0.3 * rng.unit(), 0.5 + 2.5 * rng.unit());
        // The row change is the first point of the row (a move along Y and Z).
        for i in 0..=points {
            if written == segments {
                break;
            }
            if row == 0 && i == 0 {
                continue;
            }
            let k = if forward { i } else { points - i };
            let x = k as f64 * RASTER_STEP_MM;
            let z = a1 * (x / l1).sin() * (y / 7.0).cos()
                + a2 * ((x + y) / l2).sin()
                + noise_mm * (2.0 * rng.unit() - 1.0);
            let g = if first { "G1 " } else { "" };
            first = false;
            let _ = writeln!(text, "{g}X{} Y{} Z{}", num(x, 4), num(y, 4), num(z, 4));
            written += 1;
        }
        row += 1;
    }
    text.push_str("M2\n");
    text
}

/// A small, fixed pseudo-random generator (SplitMix64): the generated programs are the
/// same on every machine without a dependency.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}
