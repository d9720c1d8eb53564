//! The plot of `kerf sim --plot FILE.svg|FILE.png`: what a person looks at to understand a
//! slow or rough program.
//!
//! Drawn with `plotters`, as SVG or PNG ([`PlotFormat`], chosen by the file's extension):
//!
//! - the toolpath seen from above (XY, equal scales) and from the front (XZ) and the side
//!   (YZ), rapids and feed moves in different colours, so that drilling and 3D surfaces show;
//! - the path feed over time (s), rapids and feed moves in the same colours;
//! - for every axis its velocity, acceleration and jerk over time (finite differences of the
//!   setpoints at the period, as the limit monitor measures them) with the limit lines.
//!
//! Every time series is an envelope: for each column of time it draws the minimum and the
//! maximum of the samples in it (and shades between them), so a dip of the feed to zero or a
//! one-period spike of jerk is never hidden however long the program.
//!
//! The recorder ([`PlotRecorder`]) aggregates while the simulation runs, in memory that
//! does not grow with the program's time: at most [`BUCKETS`] columns of time (each a
//! power-of-two number of periods; when the time outgrows them, neighbours are merged and
//! the width doubles), and a toolpath thinned to a distance that doubles whenever it holds
//! more than [`MAX_PATH_POINTS`] points.

use std::io::{self, Write};
use std::path::Path;

use kerf_motion::{MachineLimits, Setpoint};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// The image format of a plot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlotFormat {
    /// Scalable vector graphics (text stays text).
    Svg,
    /// A PNG image, 8-bit RGB.
    Png,
}

/// A plot file name that ends in neither `.svg` nor `.png`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the plot format is chosen by the file name, which must end in .svg or .png")]
pub struct PlotFormatError;

impl PlotFormat {
    /// The format of `path` by its extension (`.svg` or `.png`, any case); `-` (standard
    /// output) is SVG.
    pub fn of_path(path: &Path) -> Result<PlotFormat, PlotFormatError> {
        if path.as_os_str() == "-" {
            return Ok(PlotFormat::Svg);
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("svg") => Ok(PlotFormat::Svg),
            Some("png") => Ok(PlotFormat::Png),
            _ => Err(PlotFormatError),
        }
    }
}

/// Where a plot goes and in which format.
pub struct PlotOutput<'a> {
    /// The image format.
    pub format: PlotFormat,
    /// The output.
    pub out: &'a mut dyn Write,
    /// What the title names (the program).
    pub title: String,
}

/// Columns of time at most: more than the widest panel has pixels.
pub const BUCKETS: usize = 2048;

/// Points of the thinned toolpath at most before it is thinned further.
pub const MAX_PATH_POINTS: usize = 100_000;

/// Series of a bucket: the path feed, then per axis (X … C) velocity, acceleration, jerk.
const CHANNELS: usize = 1 + 6 * 3;

/// The channel of the path feed.
const FEED: usize = 0;

/// The channel of `quantity` (0 velocity, 1 acceleration, 2 jerk) of `axis`.
const fn channel(axis: usize, quantity: usize) -> usize {
    1 + axis * 3 + quantity
}

/// Minimum and maximum of every series over some consecutive periods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bucket {
    lo: [f64; CHANNELS],
    hi: [f64; CHANNELS],
    /// A sample of a rapid move is in it.
    pub rapid: bool,
    /// A sample of a feed move is in it.
    pub cut: bool,
}

impl Bucket {
    fn empty() -> Self {
        Bucket {
            lo: [f64::INFINITY; CHANNELS],
            hi: [f64::NEG_INFINITY; CHANNELS],
            rapid: false,
            cut: false,
        }
    }

    fn merge(&mut self, other: &Bucket) {
        for c in 0..CHANNELS {
            self.lo[c] = self.lo[c].min(other.lo[c]);
            self.hi[c] = self.hi[c].max(other.hi[c]);
        }
        self.rapid |= other.rapid;
        self.cut |= other.cut;
    }

    /// The smallest and the largest path feed in it, mm/s.
    pub fn feed_mm_s(&self) -> (f64, f64) {
        (self.lo[FEED], self.hi[FEED])
    }

    /// The smallest and the largest of `quantity` (0 velocity, 1 acceleration, 2 jerk) of
    /// `axis` (0 = X … 5 = C) in it, in mm (degrees) per s, s², s³.
    pub fn axis(&self, axis: usize, quantity: usize) -> (f64, f64) {
        let c = channel(axis, quantity);
        (self.lo[c], self.hi[c])
    }
}

/// Whether each move is a rapid, by program index: the indices where that changes.
#[derive(Debug, Default)]
pub struct RapidIndex {
    /// Move indices at which the kind flips (starting from "feed" before move 0).
    flips: Vec<u64>,
    /// Moves seen so far, and whether the last was a rapid.
    moves: u64,
    last: bool,
}

impl RapidIndex {
    /// Notes the next move of the program, in program order.
    pub fn push(&mut self, rapid: bool) {
        if let Some(at) = self.next_flip(rapid) {
            self.flips.push(at);
        }
    }

    /// Counts the next move of the program, in program order, without keeping it, and
    /// returns its index when its kind differs from the move before (the flip to hand to
    /// the recorder of a run fed on another thread).
    pub fn next_flip(&mut self, rapid: bool) -> Option<u64> {
        let at = (rapid != self.last).then_some(self.moves);
        self.last = rapid;
        self.moves += 1;
        at
    }

    /// Notes a flip at `index` (from [`RapidIndex::push`] on another thread).
    fn flip_at(&mut self, index: u64) {
        self.flips.push(index);
    }

    /// Whether move `index` is a rapid.
    pub fn is_rapid(&self, index: u64) -> bool {
        self.flips.partition_point(|&f| f <= index) % 2 == 1
    }
}

/// A point of the toolpath, and whether the move that reaches it is a rapid.
type PathPoint = ([f64; 3], bool);

/// The directions from a vertex within which the polyline may go on straight: each point
/// since the vertex narrows them to those whose line passes within the tolerance of it
/// (a sleeve), and a point that comes back towards the vertex ends it.
#[derive(Clone, Copy, Debug)]
struct Sleeve {
    anchor: (f64, f64),
    /// Direction of the first point beyond the tolerance, and the allowed directions
    /// around it, radians.
    cone: Option<(f64, f64, f64)>,
    /// The farthest a point has been from the anchor.
    reach: f64,
}

impl Sleeve {
    fn at(anchor: (f64, f64)) -> Self {
        Sleeve {
            anchor,
            cone: None,
            reach: 0.0,
        }
    }

    /// The sleeve narrowed by `q`, or `None` when the line from the anchor to `q` misses a
    /// point since the anchor by more than `tol`.
    fn through(&self, q: (f64, f64), tol: f64) -> Option<Sleeve> {
        let (dx, dy) = (q.0 - self.anchor.0, q.1 - self.anchor.1);
        let d = dx.hypot(dy);
        if d < self.reach - tol {
            return None;
        }
        if d <= tol {
            return Some(*self);
        }
        let half = (tol / d).asin();
        let angle = dy.atan2(dx);
        let cone = match self.cone {
            None => (angle, -half, half),
            Some((axis, lo, hi)) => {
                let mut rel = angle - axis;
                if rel > std::f64::consts::PI {
                    rel -= std::f64::consts::TAU;
                } else if rel < -std::f64::consts::PI {
                    rel += std::f64::consts::TAU;
                }
                if rel < lo || rel > hi {
                    return None;
                }
                (axis, lo.max(rel - half), hi.min(rel + half))
            }
        };
        Some(Sleeve {
            anchor: self.anchor,
            cone: Some(cone),
            reach: self.reach.max(d),
        })
    }
}

/// Thins a polyline as its points come: a point is kept (a vertex) where the line from the
/// last vertex would pass farther than `tol` from a point in between, in any of the
/// `planes` (pairs of coordinates, each scaled), and where the kind of move changes.
#[derive(Debug)]
struct Thinner<const N: usize> {
    tol: f64,
    planes: [(usize, usize, f64, f64); N],
    sleeves: Option<[Sleeve; N]>,
    prev: Option<PathPoint>,
    out: Vec<PathPoint>,
}

impl<const N: usize> Thinner<N> {
    fn new(tol: f64, planes: [(usize, usize, f64, f64); N]) -> Self {
        Thinner {
            tol,
            planes,
            sleeves: None,
            prev: None,
            out: Vec::new(),
        }
    }

    fn project(&self, p: &[f64; 3], k: usize) -> (f64, f64) {
        let (h, v, sh, sv) = self.planes[k];
        (p[h] * sh, p[v] * sv)
    }

    fn vertex(&mut self, p: PathPoint) {
        self.out.push(p);
        self.sleeves = Some(std::array::from_fn(|k| Sleeve::at(self.project(&p.0, k))));
    }

    fn push(&mut self, p: PathPoint) {
        let Some(prev) = self.prev else {
            self.vertex(p);
            self.prev = Some(p);
            return;
        };
        if p.1 != prev.1 {
            if self.out.last() != Some(&prev) {
                self.vertex(prev);
            }
            self.vertex(p);
            self.prev = Some(p);
            return;
        }
        for attempt in 0..2 {
            let Some(sleeves) = self.sleeves else {
                break;
            };
            let mut next = sleeves;
            let mut fits = true;
            for (k, s) in sleeves.iter().enumerate() {
                match s.through(self.project(&p.0, k), self.tol) {
                    Some(n) => next[k] = n,
                    None => fits = false,
                }
            }
            if fits {
                self.sleeves = Some(next);
                break;
            }
            if attempt == 0 && self.out.last() != Some(&prev) {
                // The previous point is a corner: the sleeves start again there.
                self.vertex(prev);
            } else {
                self.vertex(p);
                break;
            }
        }
        self.prev = Some(p);
    }

    /// The vertices and the last point.
    fn finish(mut self) -> Vec<PathPoint> {
        if let Some(p) = self.prev
            && self.out.last() != Some(&p)
        {
            self.out.push(p);
        }
        self.out
    }
}

/// The three views of the path, in mm.
const VIEWS_MM: [(usize, usize, f64, f64); 3] =
    [(0, 1, 1.0, 1.0), (0, 2, 1.0, 1.0), (1, 2, 1.0, 1.0)];

/// The toolpath, thinned as it comes to `tol_mm` in the three views (the tolerance
/// doubles, and the points kept are thinned again, whenever more than
/// [`MAX_PATH_POINTS`] are kept).
#[derive(Debug)]
struct Trace {
    thinner: Thinner<3>,
}

impl Trace {
    fn new() -> Self {
        Trace {
            thinner: Thinner::new(1e-3, VIEWS_MM),
        }
    }

    fn push(&mut self, position: [f64; 3], rapid: bool) {
        self.thinner.push((position, rapid));
        while self.thinner.out.len() > MAX_PATH_POINTS {
            let tol = self.thinner.tol * 2.0;
            let mut again = Thinner::new(tol, VIEWS_MM);
            for p in &self.thinner.out {
                again.push(*p);
            }
            let mut kept = again.finish();
            // Thinning goes on from the last point seen.
            let prev = self.thinner.prev;
            if let Some(p) = prev
                && kept.last() == Some(&p)
            {
                kept.pop();
            }
            let mut next = Thinner::new(tol, VIEWS_MM);
            for p in kept {
                next.push(p);
            }
            if let Some(p) = prev {
                next.push(p);
            }
            self.thinner = next;
        }
    }

    /// The points kept and the last one.
    fn all(&self) -> Vec<PathPoint> {
        let mut v = self.thinner.out.clone();
        if let Some(p) = self.thinner.prev
            && v.last() != Some(&p)
        {
            v.push(p);
        }
        v
    }

    /// Points kept.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.thinner.out.len()
    }
}

/// Collects what the plot shows while the simulation runs.
#[derive(Debug)]
pub struct PlotRecorder {
    limits: MachineLimits,
    /// The last four positions, newest first (at rest at the origin before the first).
    hist: [[f64; 6]; 4],
    /// Samples seen.
    samples: u64,
    /// Periods per bucket (a power of two).
    per_bucket: u64,
    buckets: Vec<Bucket>,
    trace: Trace,
    rapids: RapidIndex,
    /// Flips of the rapid index sent by the thread that reads the moves.
    flips: Option<std::sync::mpsc::Receiver<u64>>,
    rotary_used: bool,
}

impl PlotRecorder {
    /// A recorder for a run on `limits` whose moves are rapids as `rapids` says (filled
    /// now, or later through [`PlotRecorder::flips_from`]).
    pub fn new(limits: &MachineLimits, rapids: RapidIndex) -> Self {
        PlotRecorder {
            limits: *limits,
            hist: [[0.0; 6]; 4],
            samples: 0,
            per_bucket: 1,
            buckets: Vec::with_capacity(BUCKETS),
            trace: Trace::new(),
            rapids,
            flips: None,
            rotary_used: false,
        }
    }

    /// Takes the flips of the rapid index from `rx` as they come (the moves are read on
    /// another thread, always before their setpoints).
    pub fn flips_from(&mut self, rx: std::sync::mpsc::Receiver<u64>) {
        self.flips = Some(rx);
    }

    /// Records the setpoint of the next period (the first at t = 0).
    pub fn push(&mut self, sp: &Setpoint) {
        if let Some(rx) = &self.flips {
            for f in rx.try_iter() {
                self.rapids.flip_at(f);
            }
        }
        let rapid = self.rapids.is_rapid(sp.move_index);
        self.hist.rotate_right(1);
        self.hist[0] = sp.position;
        let dt = self.limits.period_s;
        let mut b = Bucket::empty();
        b.rapid = rapid;
        b.cut = !rapid;
        b.lo[FEED] = sp.feed_mm_s;
        b.hi[FEED] = sp.feed_mm_s;
        for i in 0..6 {
            if self.limits.axes[i].is_none() {
                continue;
            }
            let h = |k: usize| self.hist[k][i];
            let q = [
                (h(0) - h(1)) / dt,
                (h(0) - 2.0 * h(1) + h(2)) / (dt * dt),
                (h(0) - 3.0 * h(1) + 3.0 * h(2) - h(3)) / (dt * dt * dt),
            ];
            for (k, v) in q.into_iter().enumerate() {
                b.lo[channel(i, k)] = v;
                b.hi[channel(i, k)] = v;
            }
            if i >= 3 && sp.position[i] != 0.0 {
                self.rotary_used = true;
            }
        }
        let mut index = self.samples / self.per_bucket;
        while index as usize >= BUCKETS {
            self.halve();
            index = self.samples / self.per_bucket;
        }
        let index = index as usize;
        if index == self.buckets.len() {
            self.buckets.push(b);
        } else {
            self.buckets[index].merge(&b);
        }
        self.samples += 1;
        let p = sp.position;
        self.trace.push([p[0], p[1], p[2]], rapid);
    }

    /// Merges neighbouring buckets: twice the periods each.
    fn halve(&mut self) {
        let merged: Vec<Bucket> = self
            .buckets
            .chunks(2)
            .map(|pair| {
                let mut b = pair[0];
                if let Some(second) = pair.get(1) {
                    b.merge(second);
                }
                b
            })
            .collect();
        self.buckets = merged;
        self.per_bucket *= 2;
    }

    /// The columns of time, each [`PlotRecorder::periods_per_bucket`] periods from t = 0
    /// (the last may hold fewer).
    pub fn buckets(&self) -> &[Bucket] {
        &self.buckets
    }

    /// Periods in each bucket.
    pub fn periods_per_bucket(&self) -> u64 {
        self.per_bucket
    }

    /// Draws the plot in `format` into `out`.
    pub fn write(&self, format: PlotFormat, title: &str, out: &mut dyn Write) -> io::Result<()> {
        register_font()?;
        let size = self.size_px();
        match format {
            PlotFormat::Svg => {
                let mut text = String::new();
                {
                    let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                    self.draw(&root, title).map_err(drawing_error)?;
                    root.present().map_err(drawing_error)?;
                }
                out.write_all(text.as_bytes())
            }
            PlotFormat::Png => {
                let (w, h) = size;
                let mut rgb = vec![0u8; w as usize * h as usize * 3];
                {
                    let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
                    self.draw(&root, title).map_err(drawing_error)?;
                    root.present().map_err(drawing_error)?;
                }
                let mut encoder = png::Encoder::new(out, w, h);
                encoder.set_color(png::ColorType::Rgb);
                encoder.set_depth(png::BitDepth::Eight);
                let mut writer = encoder.write_header().map_err(io::Error::other)?;
                writer.write_image_data(&rgb).map_err(io::Error::other)?;
                writer.finish().map_err(io::Error::other)
            }
        }
    }

    /// The axes drawn in the per-axis panels: the configured linear ones, and the rotary
    /// ones when the program drove one.
    fn plotted_axes(&self) -> Vec<usize> {
        (0..6)
            .filter(|&i| self.limits.axes[i].is_some() && (i < 3 || self.rotary_used))
            .collect()
    }

    fn size_px(&self) -> (u32, u32) {
        let rows = self.plotted_axes().len().div_ceil(3) as u32;
        (WIDTH_PX, HEAD_PX + PATH_PX + FEED_PX + rows * AXES_PX)
    }

    /// Time of the last sample, s.
    fn end_s(&self) -> f64 {
        self.samples.saturating_sub(1) as f64 * self.limits.period_s
    }

    /// The time of bucket `k`'s middle, s.
    fn bucket_t(&self, k: usize) -> f64 {
        let first = k as u64 * self.per_bucket;
        let last = (first + self.per_bucket - 1).min(self.samples.saturating_sub(1));
        (first + last) as f64 / 2.0 * self.limits.period_s
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, title: &str) -> Drawn<DB> {
        root.fill(&WHITE)?;
        let (head, rest) = root.split_vertically(HEAD_PX);
        let (path, rest) = rest.split_vertically(PATH_PX);
        let (feed, axes) = rest.split_vertically(FEED_PX);
        let end_s = self.end_s();
        head.draw(&Text::new(
            format!(
                "{title}: {end_s:.3} s of motion. Toolpath, path feed, and each axis's \
                 velocity, acceleration and jerk against its limits (red). Blue: feed moves, \
                 orange: rapids."
            ),
            (12, 10),
            ("sans-serif", 17).into_font(),
        ))?;
        head.draw(&Text::new(
            "Circles: feed moves across the view (plunges, drilled holes). Time series show, \
             per column of time, the range from the smallest to the largest value in it: every \
             stop and every spike is drawn.",
            (12, 32),
            ("sans-serif", 14).into_font().color(&GREY_TEXT),
        ))?;
        self.draw_path(&path)?;
        self.draw_feed(&feed)?;
        let axes_list = self.plotted_axes();
        let rows = axes_list.len().div_ceil(3);
        let cells = axes.split_evenly((rows * 3, 3));
        for (n, &axis) in axes_list.iter().enumerate() {
            let (row, col) = (n / 3, n % 3);
            for q in 0..3 {
                self.draw_axis(&cells[(row * 3 + q) * 3 + col], axis, q)?;
            }
        }
        Ok(())
    }

    fn draw_path<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Drawn<DB> {
        let all = self.trace.all();
        let (top, sides) = area.split_horizontally(WIDTH_PX / 2);
        let (front, side) = sides.split_vertically(PATH_PX / 2);
        let views: [(&DrawingArea<DB, Shift>, usize, usize, &str); 3] = [
            (&top, 0, 1, "from above"),
            (&front, 0, 2, "from the front"),
            (&side, 1, 2, "from the side"),
        ];
        for (area, h, v, what) in views {
            let name = |i: usize| ["X", "Y", "Z"][i];
            let range = |i: usize| {
                let (lo, hi) = all
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p.0[i]), hi.max(p.0[i]))
                    });
                if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) }
            };
            let (w_px, h_px) = area.dim_in_pixel();
            let plot_w = f64::from(w_px) - f64::from(PATH_Y_LABEL_PX) - 2.0 * MARGIN_PX;
            let plot_h = f64::from(h_px) - f64::from(X_LABEL_PX) - CAPTION_PX - 2.0 * MARGIN_PX;
            let (xr, yr, stretch) = fit_view(range(h), range(v), plot_w, plot_h);
            let caption = if stretch > 1.5 {
                format!(
                    "{}{} {what} ({} drawn {stretch:.0}× taller than {})",
                    name(h),
                    name(v),
                    name(v),
                    name(h)
                )
            } else {
                format!("{}{} {what} (equal scales)", name(h), name(v))
            };
            let mut chart = ChartBuilder::on(area)
                .caption(caption, ("sans-serif", 15))
                .margin(MARGIN_PX as u32)
                .x_label_area_size(X_LABEL_PX)
                .y_label_area_size(PATH_Y_LABEL_PX)
                .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
            let (fx, fy) = (tick_format(xr.1 - xr.0), tick_format(yr.1 - yr.0));
            chart
                .configure_mesh()
                .x_desc(format!("{} (mm)", name(h)))
                .y_desc(format!("{} (mm)", name(v)))
                .x_label_formatter(&fx)
                .y_label_formatter(&fy)
                .max_light_lines(0)
                .bold_line_style(GRID)
                .draw()?;
            // Thinned to a quarter of a pixel of this view (straight runs become one segment).
            let (pw, ph) = chart.plotting_area().dim_in_pixel();
            let px = (
                f64::from(pw.max(1)) / (xr.1 - xr.0),
                f64::from(ph.max(1)) / (yr.1 - yr.0),
            );
            let mut thinner = Thinner::new(0.25, [(h, v, px.0, px.1)]);
            for p in &all {
                thinner.push(*p);
            }
            let points = thinner.finish();
            // Runs of one kind, each starting where the previous ended.
            let mut marked = std::collections::HashSet::new();
            let mut start = 0;
            while start + 1 < points.len() {
                let rapid = points[start + 1].1;
                let mut end = start + 1;
                while end + 1 < points.len() && points[end + 1].1 == rapid {
                    end += 1;
                }
                let colour = if rapid { RAPID } else { CUT };
                let run = &points[start..=end];
                chart.draw_series(LineSeries::new(
                    run.iter().map(|p| (p.0[h], p.0[v])),
                    colour.stroke_width(1),
                ))?;
                // A feed move along the axis this view does not show (a plunge, a drilled
                // hole) would be a dot: it gets a circle.
                let extent = |i: usize, scale: f64| {
                    let (lo, hi) = run.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
                        (a.0.min(p.0[i]), a.1.max(p.0[i]))
                    });
                    (hi - lo) * scale
                };
                if !rapid && extent(h, px.0) < 2.0 && extent(v, px.1) < 2.0 {
                    let p = run[run.len() - 1].0;
                    if marked.insert(((p[h] * px.0) as i64, (p[v] * px.1) as i64)) {
                        chart.draw_series(std::iter::once(Circle::new(
                            (p[h], p[v]),
                            5,
                            CUT.stroke_width(2),
                        )))?;
                    }
                }
                start = end;
            }
        }
        Ok(())
    }

    fn draw_feed<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Drawn<DB> {
        let hi = self
            .buckets
            .iter()
            .map(|b| b.hi[FEED])
            .fold(0.0f64, f64::max);
        let top = if hi > 0.0 { hi * 1.08 } else { 1.0 };
        let end_s = self.end_s().max(self.limits.period_s);
        let mut chart = ChartBuilder::on(area)
            .caption(
                "Path feed, mm/s (shaded: smallest to largest in each column of time)",
                ("sans-serif", 15),
            )
            .margin(MARGIN_PX as u32)
            .x_label_area_size(X_LABEL_PX)
            .y_label_area_size(Y_LABEL_PX)
            .build_cartesian_2d(0.0..end_s, 0.0..top)?;
        let (fx, fy) = (tick_format(end_s), tick_format(top));
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc("feed (mm/s)")
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .max_light_lines(0)
            .bold_line_style(GRID)
            .draw()?;
        self.draw_envelope(&mut chart, FEED)
    }

    /// The envelope of channel `c` in at most `max_columns` columns: consecutive buckets
    /// merged, each column its middle time (s), its smallest and largest value, and whether
    /// a rapid ran in it.
    fn columns(&self, c: usize, max_columns: usize) -> Vec<Column> {
        let per = self.buckets.len().div_ceil(max_columns.max(1)).max(1);
        self.buckets
            .chunks(per)
            .enumerate()
            .map(|(k, group)| {
                let mut b = group[0];
                for other in &group[1..] {
                    b.merge(other);
                }
                let first = k * per;
                let last = first + group.len() - 1;
                Column {
                    t_s: (self.bucket_t(first) + self.bucket_t(last)) / 2.0,
                    lo: b.lo[c],
                    hi: b.hi[c],
                    rapid: b.rapid,
                }
            })
            .collect()
    }

    /// The band from the smallest to the largest value of `c` in each column of the
    /// plotting area, and its edges, blue, or orange where a rapid ran.
    fn draw_envelope<DB: DrawingBackend>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
        c: usize,
    ) -> Drawn<DB> {
        let width_px = chart.plotting_area().dim_in_pixel().0 as usize;
        let cols = self.columns(c, width_px);
        let n = cols.len();
        if n == 0 {
            return Ok(());
        }
        let band: Vec<(f64, f64)> = cols
            .iter()
            .map(|k| (k.t_s, k.hi))
            .chain(cols.iter().rev().map(|k| (k.t_s, k.lo)))
            .collect();
        chart.draw_series(std::iter::once(Polygon::new(band, BAND.filled())))?;
        for edge in [0, 1] {
            let value = |k: &Column| (k.t_s, if edge == 0 { k.lo } else { k.hi });
            let mut start = 0;
            while start < n {
                let kind = cols[start].rapid;
                let mut end = start;
                while end + 1 < n && cols[end + 1].rapid == kind {
                    end += 1;
                }
                // Joined to the next run so that the edge has no gap.
                let last = (end + 1).min(n - 1);
                let colour = if kind { RAPID } else { CUT };
                chart.draw_series(LineSeries::new(
                    cols[start..=last].iter().map(value),
                    colour.stroke_width(1),
                ))?;
                start = end + 1;
            }
        }
        Ok(())
    }

    fn draw_axis<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        axis: usize,
        quantity: usize,
    ) -> Drawn<DB> {
        let Some(l) = self.limits.axes[axis] else {
            return Ok(());
        };
        let limit = [l.velocity_units_s, l.acceleration_units_s2, l.jerk_units_s3][quantity];
        let c = channel(axis, quantity);
        let peak = self
            .buckets
            .iter()
            .map(|b| b.hi[c].abs().max(b.lo[c].abs()))
            .fold(0.0f64, f64::max);
        let span = limit.max(peak) * 1.15;
        let unit = if axis < 3 { "mm" } else { "°" };
        let (what, power) =
            [("velocity", "/s"), ("acceleration", "/s²"), ("jerk", "/s³")][quantity];
        let name = kerf_geom::AXIS_NAMES[axis];
        let end_s = self.end_s().max(self.limits.period_s);
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "{name} {what}, {unit}{power}: peak {:.0} % of the limit {}",
                    peak / limit * 100.0,
                    compact(limit)
                ),
                ("sans-serif", 14),
            )
            .margin(MARGIN_PX as u32)
            .x_label_area_size(X_LABEL_PX)
            .y_label_area_size(Y_LABEL_PX)
            .build_cartesian_2d(0.0..end_s, -span..span)?;
        let fx = tick_format(end_s);
        let fy = |v: &f64| compact(*v);
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc(format!("{unit}{power}"))
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .y_labels(5)
            .x_labels(6)
            .max_light_lines(0)
            .bold_line_style(GRID)
            .draw()?;
        for sign in [1.0, -1.0] {
            chart.draw_series(LineSeries::new(
                [(0.0, sign * limit), (end_s, sign * limit)],
                LIMIT.stroke_width(1),
            ))?;
        }
        self.draw_envelope(&mut chart, c)
    }
}

/// One column of time of a plotted envelope.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Column {
    t_s: f64,
    lo: f64,
    hi: f64,
    rapid: bool,
}

/// What drawing returns.
type Drawn<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn drawing_error<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> io::Error {
    io::Error::other(e.to_string())
}

/// The bundled font (a subset of DejaVu Sans, see `fonts/LICENSE-DejaVu.txt`): the text
/// is measured and, in a PNG, drawn without any font of the system.
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans-subset.ttf");

fn register_font() -> io::Result<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| io::Error::other("the bundled font cannot be read"))
}

const WIDTH_PX: u32 = 1500;
const HEAD_PX: u32 = 50;
const PATH_PX: u32 = 620;
const FEED_PX: u32 = 280;
/// Three rows of panels (velocity, acceleration, jerk) for up to three axes.
const AXES_PX: u32 = 3 * 210;
const MARGIN_PX: f64 = 8.0;
const X_LABEL_PX: u32 = 36;
const Y_LABEL_PX: u32 = 64;
const PATH_Y_LABEL_PX: u32 = 56;
const CAPTION_PX: f64 = 24.0;

const CUT: RGBColor = RGBColor(31, 90, 180);
const RAPID: RGBColor = RGBColor(235, 120, 0);
const LIMIT: RGBColor = RGBColor(210, 30, 30);
const BAND: RGBColor = RGBColor(190, 205, 230);
const GRID: RGBColor = RGBColor(225, 225, 225);
const GREY_TEXT: RGBColor = RGBColor(90, 90, 90);

/// Ranges of a view of the path with `plot_w` × `plot_h` pixels: equal scales, except
/// that the vertical one is stretched when its extent would take less than a quarter of
/// the height; returns the ranges and that stretch (1 for equal scales).
fn fit_view(
    h: (f64, f64),
    v: (f64, f64),
    plot_w: f64,
    plot_h: f64,
) -> ((f64, f64), (f64, f64), f64) {
    let pad = |(lo, hi): (f64, f64)| {
        let span = (hi - lo).max(1.0);
        let mid = (lo + hi) / 2.0;
        (mid - span * 0.54, mid + span * 0.54)
    };
    let raw_v = v.1 - v.0;
    let (mut h, mut v) = (pad(h), pad(v));
    let mm_per_px = ((h.1 - h.0) / plot_w).max((v.1 - v.0) / plot_h);
    let widen = |(lo, hi): (f64, f64), px: f64, mm_per_px: f64| {
        let mid = (lo + hi) / 2.0;
        (mid - px * mm_per_px / 2.0, mid + px * mm_per_px / 2.0)
    };
    h = widen(h, plot_w, mm_per_px);
    let v_px = (v.1 - v.0) / mm_per_px;
    // A path flat in this view (extent under 0.1 mm) is not stretched: there is nothing
    // to see.
    if v_px >= plot_h / 4.0 || raw_v < 0.1 {
        v = widen(v, plot_h, mm_per_px);
        return (h, v, 1.0);
    }
    // Stretched so that the extent fills the height (a whole-number factor).
    let stretch = (plot_h / v_px).floor().max(1.0);
    v = widen(v, plot_h, mm_per_px / stretch);
    (h, v, stretch)
}

/// Tick labels for a range of `span`: the tick's value without float noise or trailing
/// zeros (`0`, `2.5`, `0.25`).
fn tick_format(span: f64) -> impl Fn(&f64) -> String {
    let decimals = if span > 0.0 {
        (4.0 - span.log10().floor()).clamp(0.0, 9.0) as usize
    } else {
        0
    };
    move |v: &f64| {
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.')
        } else {
            &s
        };
        if s == "-0" {
            "0".to_string()
        } else {
            s.to_string()
        }
    }
}

/// A value in a few characters: `250`, `2.5k`, `1.2M`.
fn compact(v: f64) -> String {
    let a = v.abs();
    let (scaled, suffix) = if a >= 1e6 {
        (v / 1e6, "M")
    } else if a >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    let s = format!("{scaled:.1}");
    let s = s.strip_suffix(".0").unwrap_or(&s).to_string();
    let s = if s == "-0" { "0".to_string() } else { s };
    format!("{s}{suffix}")
}

#[cfg(test)]
mod tests {
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
            p.0 < (WIDTH_PX / 2) as i32
                && (HEAD_PX as i32..(HEAD_PX + PATH_PX) as i32).contains(&p.1)
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
        let decoder = png::Decoder::new(std::io::Cursor::new(image));
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
}
