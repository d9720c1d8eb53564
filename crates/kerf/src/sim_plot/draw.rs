//! The plot drawn: the layout, the toolpath views, the feed, and each axis's velocity,
//! acceleration and jerk envelopes with their limits.

use super::*;

impl PlotRecorder {
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
pub(super) struct Column {
    t_s: f64,
    lo: f64,
    hi: f64,
    rapid: bool,
}

/// What drawing returns.
pub(super) type Drawn<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

pub(super) fn drawing_error<E: std::error::Error + Send + Sync>(
    e: DrawingAreaErrorKind<E>,
) -> io::Error {
    io::Error::other(e.to_string())
}

/// The bundled font (a subset of DejaVu Sans, see `fonts/LICENSE-DejaVu.txt`): the text
/// is measured and, in a PNG, drawn without any font of the system.
pub(super) const FONT: &[u8] = include_bytes!("../../fonts/DejaVuSans-subset.ttf");

pub(super) fn register_font() -> io::Result<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| io::Error::other("the bundled font cannot be read"))
}

pub(super) const WIDTH_PX: u32 = 1500;
pub(super) const HEAD_PX: u32 = 50;
pub(super) const PATH_PX: u32 = 620;
pub(super) const FEED_PX: u32 = 280;
/// Three rows of panels (velocity, acceleration, jerk) for up to three axes.
pub(super) const AXES_PX: u32 = 3 * 210;
pub(super) const MARGIN_PX: f64 = 8.0;
pub(super) const X_LABEL_PX: u32 = 36;
pub(super) const Y_LABEL_PX: u32 = 64;
pub(super) const PATH_Y_LABEL_PX: u32 = 56;
pub(super) const CAPTION_PX: f64 = 24.0;

pub(super) const CUT: RGBColor = RGBColor(31, 90, 180);
pub(super) const RAPID: RGBColor = RGBColor(235, 120, 0);
pub(super) const LIMIT: RGBColor = RGBColor(210, 30, 30);
pub(super) const BAND: RGBColor = RGBColor(190, 205, 230);
pub(super) const GRID: RGBColor = RGBColor(225, 225, 225);
pub(super) const GREY_TEXT: RGBColor = RGBColor(90, 90, 90);

/// Ranges of a view of the path with `plot_w` × `plot_h` pixels: equal scales, except
/// that the vertical one is stretched when its extent would take less than a quarter of
/// the height; returns the ranges and that stretch (1 for equal scales).
pub(super) fn fit_view(
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
pub(super) fn tick_format(span: f64) -> impl Fn(&f64) -> String {
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
pub(super) fn compact(v: f64) -> String {
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
