//! The plot's tests: the recorder's envelopes and thinning, and the files it writes.

use super::draw::*;
use super::*;
use crate::sim::{self, SimOptions};
use kerf_config::Config;
use kerf_geom::Move;

/// The moves of a LinuxCNC program.
fn moves(text: &str) -> Vec<Move> {
    kerf_gcode::Interpreter::new(
        text.as_bytes(),
        kerf_gcode::Dialect::LinuxCnc,
        Config::builtin().settings(),
    )
    .filter_map(|item| match item.expect("a valid program") {
        kerf_gcode::Item::Move(m) => Some(m),
        kerf_gcode::Item::Event(_) => None,
    })
    .collect()
}

/// A raster in exact-stop mode (G61): `rows` passes of 20 mm along X, 2 mm apart, so
/// the motion stops between every two moves; a rapid to the start and one back.
fn raster(rows: usize) -> String {
    let mut text = String::from("G21 G90 G17 G61\nG0 X5 Y5\n");
    for r in 0..rows {
        let x = if r % 2 == 0 { 25 } else { 5 };
        text += &format!("G1 X{x} F3000\n");
        if r + 1 < rows {
            text += &format!("G1 Y{}\n", 5 + 2 * (r + 1));
        }
    }
    text += "G0 X0 Y0\nM2\n";
    text
}

/// One CSV row: t, x, y, z, line, feed.
struct Row {
    pos: [f64; 3],
    line: u32,
    feed: f64,
}

fn csv(moves: &[Move], config: &Config) -> Vec<Row> {
    let mut out = Vec::new();
    sim::simulate(moves, config, &SimOptions::default(), &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,x,y,z,line,feed_mm_s"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Row {
                pos: [f[1], f[2], f[3]].map(|v| v.parse().unwrap()),
                line: f[4].parse().unwrap(),
                feed: f[5].parse().unwrap(),
            }
        })
        .collect()
}

/// The plot of `moves` as SVG, run through `simulate_and_plot` (the streamed feed).
fn svg(moves: &[Move], config: &Config) -> String {
    let mut out = Vec::new();
    let mut image = Vec::new();
    sim::simulate_and_plot(
        moves,
        config,
        &SimOptions::default(),
        &mut out,
        Some(PlotOutput {
            format: PlotFormat::Svg,
            out: &mut image,
            title: "test.ngc".to_string(),
        }),
    )
    .unwrap();
    String::from_utf8(image).unwrap()
}

/// The polylines of an SVG: stroke colour and points in pixels.
fn polylines(svg: &str) -> Vec<(String, Vec<(i32, i32)>)> {
    svg.lines()
        .filter(|l| l.starts_with("<polyline"))
        .map(|l| {
            let attr = |name: &str| {
                let from = l.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
                let to = from + l[from..].find('"').unwrap();
                l[from..to].to_string()
            };
            let points = attr("points")
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect();
            (attr("stroke"), points)
        })
        .collect()
}

fn hex(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

#[test]
fn the_format_is_chosen_by_the_extension() {
    assert_eq!(PlotFormat::of_path(Path::new("a.svg")), Ok(PlotFormat::Svg));
    assert_eq!(
        PlotFormat::of_path(Path::new("d/a.PNG")),
        Ok(PlotFormat::Png)
    );
    assert_eq!(PlotFormat::of_path(Path::new("-")), Ok(PlotFormat::Svg));
    for bad in ["a.jpg", "a", "svg", "a.svg.txt"] {
        assert_eq!(PlotFormat::of_path(Path::new(bad)), Err(PlotFormatError));
    }
}

#[test]
fn each_column_holds_the_smallest_and_largest_sample_of_the_csv() {
    let config = Config::builtin();
    let program = moves(&raster(12));
    let rows = csv(&program, &config);
    let limits = kerf_config::machine_limits(&config);
    let mut rapids = RapidIndex::default();
    for m in &program {
        rapids.push(m.rapid);
    }
    let mut recorder = PlotRecorder::new(&limits, rapids);
    sim::simulate_with(&program, &limits, &SimOptions::default(), |_, sp| {
        recorder.push(sp)
    })
    .unwrap();
    // Long enough that the columns were merged: several periods each.
    let per = recorder.periods_per_bucket() as usize;
    assert!(per >= 2 && rows.len() > BUCKETS, "{per} {}", rows.len());
    let buckets = recorder.buckets();
    assert_eq!(buckets.len(), rows.len().div_ceil(per));
    let rapid_lines: Vec<u32> = program.iter().filter(|m| m.rapid).map(|m| m.line).collect();
    let dt = limits.period_s;
    // Velocity and acceleration of X and Y by finite differences of the CSV positions
    // (at rest at the origin before the first row).
    let at = |r: isize, i: usize| if r < 0 { 0.0 } else { rows[r as usize].pos[i] };
    for (k, b) in buckets.iter().enumerate() {
        let range = k * per..((k + 1) * per).min(rows.len());
        let feed = rows[range.clone()]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, r| {
                (a.0.min(r.feed), a.1.max(r.feed))
            });
        assert_eq!(b.feed_mm_s(), feed, "column {k}");
        for axis in 0..2 {
            let (mut v, mut a) = (
                (f64::INFINITY, f64::NEG_INFINITY),
                (f64::INFINITY, f64::NEG_INFINITY),
            );
            for r in range.clone() {
                let r = r as isize;
                let vel = (at(r, axis) - at(r - 1, axis)) / dt;
                let acc = (at(r, axis) - 2.0 * at(r - 1, axis) + at(r - 2, axis)) / (dt * dt);
                v = (v.0.min(vel), v.1.max(vel));
                a = (a.0.min(acc), a.1.max(acc));
            }
            let close = |x: (f64, f64), y: (f64, f64), scale: f64| {
                (x.0 - y.0).abs() <= 1e-9 * scale && (x.1 - y.1).abs() <= 1e-9 * scale
            };
            assert!(
                close(b.axis(axis, 0), v, 200.0),
                "column {k}: {:?} {v:?}",
                b.axis(axis, 0)
            );
            assert!(
                close(b.axis(axis, 1), a, 2000.0),
                "column {k}: {:?} {a:?}",
                b.axis(axis, 1)
            );
        }
        let rapid = rows[range].iter().any(|r| rapid_lines.contains(&r.line));
        assert_eq!(b.rapid, rapid, "column {k}");
    }
}

#[test]
fn a_raster_with_54_stops_shows_54_dips_to_zero_feed() {
    let config = Config::builtin();
    let program = moves(&raster(28));
    // 28 passes and 27 steps: 55 feed moves in exact-stop mode, 54 stops between them.
    let rows = csv(&program, &config);
    let feeds: Vec<f64> = rows.iter().map(|r| r.feed).collect();
    let runs_at_zero = |at_zero: &[bool]| {
        at_zero
            .iter()
            .enumerate()
            .filter(|&(i, &z)| z && (i == 0 || !at_zero[i - 1]))
            .count()
    };
    // A stop falls between two periods: the feed of the rows around it is below
    // 1 % of the programmed 50 mm/s, not exactly zero. Counted from the CSV without
    // the start and the end at rest.
    let zero: Vec<bool> = feeds.iter().map(|&f| f < 0.5).collect();
    let csv_stops = runs_at_zero(&zero) - 2;
    assert_eq!(
        csv_stops, 56,
        "54 stops between feed moves, 2 around the rapids"
    );

    let image = svg(&program, &config);
    // The feed panel's edges (blue and orange) lie between its top and bottom.
    let (top, bottom) = (HEAD_PX + PATH_PX, HEAD_PX + PATH_PX + FEED_PX);
    let mut lowest = std::collections::BTreeMap::<i32, i32>::new();
    for (stroke, points) in polylines(&image) {
        if stroke != hex(CUT) && stroke != hex(RAPID) {
            continue;
        }
        if points
            .iter()
            .all(|p| (top as i32..bottom as i32).contains(&p.1))
        {
            for (x, y) in points {
                let e = lowest.entry(x).or_insert(y);
                *e = (*e).max(y);
            }
        }
    }
    let zero_y = *lowest.values().max().unwrap();
    let at_zero: Vec<bool> = lowest.values().map(|&y| y == zero_y).collect();
    // Columns are wider than a period: every stop is a dip to the zero line.
    assert!(lowest.len() > 1000, "{}", lowest.len());
    assert_eq!(runs_at_zero(&at_zero) - 2, csv_stops);
}

/// A facing pass, a rapid and two drilled holes.
const PART: &str = "G21 G90 G17 G64 P0.01\nG0 Z5\nG0 X-5 Y0\nG1 Z-1 F300\nG1 X40 F1200\n\
    G1 Y10\nG1 X-5\nG0 Z5\nG0 X10 Y30\nG1 Z-6 F150\nG0 Z5\nG0 X30\nG1 Z-6\nG0 Z5\nG0 X0 Y0 Z0\nM2\n";

#[test]
fn the_svg_has_every_panel_with_units_ticks_and_limit_lines() {
    let config = Config::builtin();
    let image = svg(&moves(PART), &config);
    assert!(image.starts_with("<svg") && image.trim_end().ends_with("</svg>"));
    let count = |s: &str| image.matches(s).count();
    // A shaded envelope in each of the 10 time panels: the feed, and velocity,
    // acceleration and jerk of X, Y and Z.
    assert_eq!(count("<polygon"), 10);
    for axis in ["X", "Y", "Z"] {
        for what in ["velocity, mm/s:", "acceleration, mm/s²:", "jerk, mm/s³:"] {
            assert_eq!(
                count(&format!(">\n{axis} {what} peak ")),
                1,
                "{axis} {what}"
            );
        }
    }
    assert_eq!(count(">\nt (s)\n<"), 10);
    assert_eq!(count(">\nfeed (mm/s)\n<"), 1);
    for unit in ["mm/s", "mm/s²", "mm/s³"] {
        assert_eq!(count(&format!(">\n{unit}\n<")), 3, "{unit}");
    }
    // The three views of the path, each with both axes in mm.
    assert_eq!(count(">\nX (mm)\n<"), 2);
    assert_eq!(count(">\nY (mm)\n<"), 2);
    assert_eq!(count(">\nZ (mm)\n<"), 2);
    // Ticks: a number under every time axis at least (labels are text elements).
    let ticks = image
        .split("<text")
        .filter(|t| {
            t.split('>')
                .nth(1)
                .is_some_and(|v| v.trim().trim_end_matches("\n</text").parse::<f64>().is_ok())
        })
        .count();
    assert!(ticks > 100, "{ticks}");
    let lines = polylines(&image);
    // Two limit lines (+ and −) in each of the 9 per-axis panels, horizontal.
    let limits: Vec<_> = lines.iter().filter(|(s, _)| *s == hex(LIMIT)).collect();
    assert_eq!(limits.len(), 18);
    assert!(limits.iter().all(|(_, p)| p.len() == 2 && p[0].1 == p[1].1));
    // Rapids and feed moves both drawn; the two holes are circled in the view from above.
    assert!(lines.iter().any(|(s, _)| *s == hex(RAPID)));
    assert!(lines.iter().any(|(s, _)| *s == hex(CUT)));
    let circles: Vec<&str> = image.lines().filter(|l| l.starts_with("<circle")).collect();
    assert_eq!(circles.len(), 2, "{circles:?}");
    // Small: the path is thinned to the pixel and the series to the columns.
    assert!(image.len() < 400_000, "{}", image.len());
}

#[test]
fn rapids_and_feed_moves_are_drawn_where_they_ran() {
    // A rapid along X, then a feed move along Y (the streamed run learns the kinds
    // from the planner's thread).
    let config = Config::builtin();
    let image = svg(&moves("G21 G90\nG0 X10\nG1 Y10 F600\nM2\n"), &config);
    // The view from above: the left half of the path row.
    let in_view = |p: &(i32, i32)| {
        p.0 < (WIDTH_PX / 2) as i32 && (HEAD_PX as i32..(HEAD_PX + PATH_PX) as i32).contains(&p.1)
    };
    let of = |c: RGBColor| -> Vec<Vec<(i32, i32)>> {
        polylines(&image)
            .into_iter()
            .filter(|(s, p)| *s == hex(c) && p.iter().all(in_view))
            .map(|(_, p)| p)
            .collect()
    };
    let (rapid, cut) = (of(RAPID), of(CUT));
    assert_eq!((rapid.len(), cut.len()), (1, 1), "{rapid:?} {cut:?}");
    // The rapid is horizontal (X), the feed move vertical (Y), and they meet.
    let (r, c) = (&rapid[0], &cut[0]);
    assert!(r.iter().all(|p| p.1 == r[0].1) && r.last().unwrap().0 > r[0].0 + 100);
    assert!(c.iter().all(|p| p.0 == c[0].0) && c.last().unwrap().1 < c[0].1 - 100);
    assert_eq!(r.last(), c.first());
}

#[test]
fn the_png_has_the_size_and_the_colours_of_the_plot() {
    let config = Config::builtin();
    let mut out = Vec::new();
    let mut image = Vec::new();
    sim::simulate_and_plot(
        &moves(PART),
        &config,
        &SimOptions::default(),
        &mut out,
        Some(PlotOutput {
            format: PlotFormat::Png,
            out: &mut image,
            title: "part.ngc".to_string(),
        }),
    )
    .unwrap();
    let decoder = png::Decoder::new(io::Cursor::new(image));
    let mut reader = decoder.read_info().unwrap();
    let mut rgb = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut rgb).unwrap();
    assert_eq!(
        (info.width, info.height),
        (WIDTH_PX, HEAD_PX + PATH_PX + FEED_PX + AXES_PX)
    );
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let pixels = |c: RGBColor| {
        rgb.chunks(3)
            .filter(|p| p[0] == c.0 && p[1] == c.1 && p[2] == c.2)
            .count()
    };
    // Limit lines: 18 of about 400 pixels; rapids, feed moves and the text are drawn.
    assert!(pixels(LIMIT) > 18 * 300, "{}", pixels(LIMIT));
    assert!(pixels(RAPID) > 1000, "{}", pixels(RAPID));
    assert!(pixels(CUT) > 1000, "{}", pixels(CUT));
    assert!(
        pixels(RGBColor(0, 0, 0)) > 5000,
        "{}",
        pixels(RGBColor(0, 0, 0))
    );
}

#[test]
fn a_long_run_keeps_bounded_memory_and_every_spike() {
    // Twenty minutes at 1 ms of wiggling circles at 10 mm/s, with one period's drop of the
    // feed to zero.
    let config = Config::builtin();
    let limits = kerf_config::machine_limits(&config);
    let mut recorder = PlotRecorder::new(&limits, RapidIndex::default());
    let samples = 20 * 60 * 1000u64;
    let spike_at = 777_777;
    for k in 0..samples {
        let a = k as f64 * 1e-3;
        let mut sp = Setpoint {
            position: [
                10.0 * a.cos() + 0.05 * (k as f64 * 1.3).sin(),
                10.0 * a.sin(),
                (k % 1000) as f64 * 1e-3,
                0.0,
                0.0,
                0.0,
            ],
            line: 1,
            move_index: 0,
            move_count: 1,
            feed_mm_s: 10.0,
            rapid: false,
        };
        if k == spike_at {
            sp.feed_mm_s = 0.0;
        }
        recorder.push(&sp);
    }
    assert!(recorder.buckets().len() <= BUCKETS);
    assert!(recorder.buckets().len() > BUCKETS / 2);
    // The wiggle of 0.05 mm makes the path too detailed at 1 µm: it was thinned further.
    assert!(recorder.trace.len() <= MAX_PATH_POINTS);
    assert!(recorder.trace.thinner.tol > 1e-3);
    let per = recorder.periods_per_bucket();
    assert_eq!(per, 1024);
    let dips: Vec<usize> = recorder
        .buckets()
        .iter()
        .enumerate()
        .filter(|(_, b)| b.feed_mm_s().0 == 0.0)
        .map(|(k, _)| k)
        .collect();
    assert_eq!(dips, [(spike_at / per) as usize]);
    // The thinned path still goes round the circle: points in every quadrant.
    for q in 0..4 {
        let (sx, sy) = ([1.0, -1.0, -1.0, 1.0][q], [1.0, 1.0, -1.0, -1.0][q]);
        assert!(
            recorder
                .trace
                .all()
                .iter()
                .any(|(p, _)| p[0] * sx > 5.0 && p[1] * sy > 5.0)
        );
    }
}
