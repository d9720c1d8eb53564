//! A job's toolpath for the page: the program resolved by the interpreter from the state
//! a program starts in on the machine (its parameters, offsets and tool; the position it
//! stands at), as `kerf run` resolves it, drawn as polylines in machine millimetres:
//! lines as they are, arcs and helices as chords of at most [`CHORD_RAD`] of turn.
//! Consecutive moves of the same kind (rapid or feed) make one polyline. At most
//! [`MAX_POINTS`] points: a longer program keeps every n-th point of its moves (the view
//! is a picture, not the path the machine follows).

use std::path::Path as FilePath;

use kerf_config::Config;
use kerf_gcode::{Interpreter, Item};
use kerf_geom::{Path, Vec3};

/// The largest turn of one chord of an arc, rad (5°).
pub const CHORD_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// The most points a toolpath keeps.
pub const MAX_POINTS: usize = 50_000;

/// One polyline: a rapid or a feed, its points in machine mm.
#[derive(Debug, Clone, PartialEq)]
pub struct Polyline {
    /// Rapid (G0) moves.
    pub rapid: bool,
    /// The points.
    pub points: Vec<[f64; 3]>,
}

/// The point of `arc` at fraction `t` of its sweep, on the helix it is (the rise along the
/// axis proportional to the turn).
fn arc_point(arc: &kerf_geom::Arc, t: f64) -> Vec3 {
    let k = arc.axis;
    let r0 = arc.start - arc.center;
    let h0 = r0.dot(&k);
    let h1 = (arc.end - arc.center).dot(&k);
    let radial = r0 - k * h0;
    let (sin, cos) = (t * arc.sweep_rad).sin_cos();
    arc.center + radial * cos + k.cross(&radial) * sin + k * (h0 + t * (h1 - h0))
}

/// The toolpath of program `text` (named `name`, whose extension may choose the dialect)
/// on the machine of `config`, starting at `start` (machine mm): the polylines, and the
/// interpreter's error if it stopped at one (what came before it is kept).
pub fn toolpath(
    config: &Config,
    name: &str,
    text: &[u8],
    start: [f64; 3],
) -> (Vec<Polyline>, Option<String>) {
    let (dialect, _) = crate::choose_dialect_from(
        None,
        Some((FilePath::new(name), &text[..text.len().min(4096)])),
        config.dialect,
    );
    let mut settings = match config.machine_settings() {
        Ok(s) => s,
        Err(e) => return (Vec::new(), Some(e.to_string())),
    };
    settings.start_mm_deg[..3].copy_from_slice(&start);
    let mut lines: Vec<Polyline> = Vec::new();
    let mut error = None;
    for item in Interpreter::new(text, dialect, settings) {
        let m = match item {
            Ok(Item::Move(m)) => m,
            Ok(Item::Event(_)) => continue,
            Err(e) => {
                error = Some(format!("{name}:{e}"));
                break;
            }
        };
        let (from, points): (Vec3, Vec<Vec3>) = match &m.path {
            Path::Line(l) => (l.start, vec![l.end]),
            Path::Arc(a) => {
                let chords = ((a.sweep_rad.abs() / CHORD_RAD).ceil() as usize).clamp(1, 720);
                let points = (1..=chords)
                    .map(|i| {
                        if i == chords {
                            a.end
                        } else {
                            arc_point(a, i as f64 / chords as f64)
                        }
                    })
                    .collect();
                (a.start, points)
            }
        };
        let same = lines.last().is_some_and(|l| l.rapid == m.rapid);
        if !same {
            lines.push(Polyline {
                rapid: m.rapid,
                points: vec![[from.x, from.y, from.z]],
            });
        }
        if let Some(l) = lines.last_mut() {
            l.points.extend(points.iter().map(|p| [p.x, p.y, p.z]));
        }
    }
    let total: usize = lines.iter().map(|l| l.points.len()).sum();
    if total > MAX_POINTS {
        let every = total.div_ceil(MAX_POINTS);
        for l in &mut lines {
            let last = *l.points.last().expect("a polyline has points");
            let mut kept: Vec<[f64; 3]> = l.points.iter().step_by(every).copied().collect();
            if kept.last() != Some(&last) {
                kept.push(last);
            }
            l.points = kept;
        }
    }
    (lines, error)
}

/// The toolpath as JSON: `{"paths":[{"rapid":false,"points":[[x,y,z],…]},…],"error":…}`
/// (coordinates rounded to a micrometre).
pub fn toolpath_json(lines: &[Polyline], error: Option<&str>) -> String {
    let mut out = String::from("{\"paths\":[");
    for (i, l) in lines.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(if l.rapid {
            "{\"rapid\":true,\"points\":["
        } else {
            "{\"rapid\":false,\"points\":["
        });
        for (j, p) in l.points.iter().enumerate() {
            if j > 0 {
                out.push(',');
            }
            let r = |v: f64| (v * 1000.0).round() / 1000.0;
            out.push_str(&format!("[{},{},{}]", r(p[0]), r(p[1]), r(p[2])));
        }
        out.push_str("]}");
    }
    out.push_str("],\"error\":");
    out.push_str(&error.map_or("null".into(), super::link::json_string));
    out.push('}');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arcs_become_chords_on_their_circle_and_lines_stay_lines() {
        let config = Config::builtin();
        // From 10, 0: a line to 20, 0, then a full counter-clockwise circle of radius 5
        // about 15, 0 back to 20, 0 rising 2 mm, then a rapid up.
        let text = b"G21 G90 G17 G54\nG1 X20 Y0 F600\nG3 X20 Y0 Z2 I-5 J0\nG0 Z10\nM2\n";
        let (lines, error) = toolpath(&config, "t.ngc", text, [10.0, 0.0, 0.0]);
        assert_eq!(error, None);
        assert_eq!(lines.len(), 2, "{lines:?}");
        let feed = &lines[0];
        assert!(!feed.rapid);
        assert_eq!(feed.points[0], [10.0, 0.0, 0.0]);
        assert_eq!(feed.points[1], [20.0, 0.0, 0.0]);
        // 360° in 5° chords: 72 points after the line's end, each on the circle, rising
        // linearly with the turn; the last exactly the arc's end.
        assert_eq!(feed.points.len(), 2 + 72);
        for (i, p) in feed.points[2..].iter().enumerate() {
            let radius = ((p[0] - 15.0).powi(2) + p[1].powi(2)).sqrt();
            assert!((radius - 5.0).abs() < 1e-9, "{p:?}");
            let turn = (i + 1) as f64 / 72.0;
            assert!((p[2] - 2.0 * turn).abs() < 1e-9, "{p:?}");
        }
        assert_eq!(*feed.points.last().unwrap(), [20.0, 0.0, 2.0]);
        // Counter-clockwise: the first chord point is above the X axis.
        assert!(feed.points[2][1] > 0.0);
        assert_eq!(lines[1].points, vec![[20.0, 0.0, 2.0], [20.0, 0.0, 10.0]]);
        let json = toolpath_json(&lines, None);
        assert!(
            json.starts_with("{\"paths\":[{\"rapid\":false,\"points\":[[10,0,0],[20,0,0],"),
            "{json}"
        );
        assert!(
            json.ends_with("[[20,0,2],[20,0,10]]}],\"error\":null}"),
            "{json}"
        );
    }

    #[test]
    fn an_error_keeps_what_came_before_it_and_says_where() {
        let config = Config::builtin();
        let (lines, error) = toolpath(
            &config,
            "e.ngc",
            b"G21 G90\nG1 X5 F100\nG1 X6 Q\n",
            [0.0; 3],
        );
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0].points, vec![[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]);
        let error = error.expect("an error");
        assert!(error.starts_with("e.ngc:3:"), "{error}");
    }
}
