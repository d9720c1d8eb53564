//! Reading and drawing the drive side's black box (`kerf dump`, the files written at a
//! fault): `kerf plot` draws, per axis, the commanded against the actual position and the
//! following error over time, with the state of the safety layer.
//!
//! The CSV is `kerf_drive::recorder::Recorder::dump`'s: `sequence,time_s,state`, then per
//! axis `{a}_cmd_{u},{a}_act_{u},{a}_ferror_{u},{a}_controlword,{a}_statusword`.

use std::io::{self, BufRead, Write};

/// One axis's columns in a black-box file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AxisTrace {
    /// Axis letter, lower case.
    pub name: char,
    /// `mm` or `deg`.
    pub unit: String,
    /// Commanded position per row.
    pub commanded: Vec<f64>,
    /// Actual position per row.
    pub actual: Vec<f64>,
    /// Following error per row.
    pub following_error: Vec<f64>,
}

/// A black-box file, read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BlackBox {
    /// Time of each row, s.
    pub time_s: Vec<f64>,
    /// State of the safety layer per row (`running`, `holding`, `quick_stop`, `stopped`).
    pub state: Vec<String>,
    /// The axes, in the file's order.
    pub axes: Vec<AxisTrace>,
}

/// Why a black-box file could not be read: the line (from 1) and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct ReadError {
    /// The line, from 1.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

fn at(line: usize, message: String) -> ReadError {
    ReadError { line, message }
}

/// Whether `header` is a black-box file's first line.
pub fn is_blackbox_header(header: &str) -> bool {
    header.starts_with("sequence,time_s,state")
}

/// Reads a black-box CSV; the error names the line and what is wrong.
pub fn read(input: impl BufRead) -> Result<BlackBox, ReadError> {
    let mut lines = input.lines();
    let header = match lines.next() {
        Some(Ok(h)) => h,
        Some(Err(e)) => return Err(at(1, e.to_string())),
        None => return Err(at(1, "the file is empty".to_string())),
    };
    if !is_blackbox_header(&header) {
        return Err(at(
            1,
            format!(
                "not a black-box file (it begins `{}`; expected `sequence,time_s,state,…`)",
                header.chars().take(40).collect::<String>()
            ),
        ));
    }
    let cols: Vec<&str> = header.split(',').collect();
    let mut bb = BlackBox::default();
    let mut k = 3;
    while k + 5 <= cols.len() {
        let cmd = cols[k];
        let (name, unit) = match cmd.split_once("_cmd_") {
            Some((n, u)) if n.len() == 1 => (n.chars().next().unwrap_or('?'), u),
            _ => {
                return Err(at(
                    1,
                    format!("column {} is `{cmd}`, not `<axis>_cmd_<unit>`", k + 1),
                ));
            }
        };
        bb.axes.push(AxisTrace {
            name,
            unit: unit.to_string(),
            ..AxisTrace::default()
        });
        k += 5;
    }
    if k != cols.len() || bb.axes.is_empty() {
        return Err(at(
            1,
            format!("{} columns: expected 3, then 5 per axis", cols.len()),
        ));
    }
    for (n, line) in lines.enumerate() {
        let number = n + 2;
        let line = line.map_err(|e| at(number, e.to_string()))?;
        if line.is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != cols.len() {
            return Err(at(
                number,
                format!("{} fields, the header has {}", f.len(), cols.len()),
            ));
        }
        let num = |i: usize| -> Result<f64, ReadError> {
            f[i].parse::<f64>().map_err(|_| {
                at(
                    number,
                    format!("`{}` in column {} is not a number", f[i], i + 1),
                )
            })
        };
        bb.time_s.push(num(1)?);
        bb.state.push(f[2].to_string());
        for (a, axis) in bb.axes.iter_mut().enumerate() {
            let base = 3 + 5 * a;
            axis.commanded.push(num(base)?);
            axis.actual.push(num(base + 1)?);
            axis.following_error.push(num(base + 2)?);
        }
    }
    Ok(bb)
}

/// Plot width, px.
const WIDTH: f64 = 900.0;
/// Left and right margins, px.
const PAD: f64 = 60.0;
/// Height of one panel, px.
const PANEL: f64 = 160.0;
/// Gap above each panel (its title), px.
const GAP: f64 = 36.0;

/// Per pixel column, the lowest and highest value drawn there (none: no row).
type Envelope = Vec<Option<(f64, f64)>>;

/// The lowest and highest value of each pixel column (an envelope, so that a spike or a
/// dip of one cycle is never hidden).
fn envelope(
    time_s: &[f64],
    values: &[f64],
    t0: f64,
    t1: f64,
    cols: usize,
) -> Vec<Option<(f64, f64)>> {
    let mut out = vec![None; cols];
    let span = (t1 - t0).max(1e-12);
    for (t, v) in time_s.iter().zip(values) {
        let c = (((t - t0) / span) * (cols as f64 - 1.0))
            .round()
            .clamp(0.0, cols as f64 - 1.0) as usize;
        out[c] = Some(match out[c] {
            None => (*v, *v),
            Some((lo, hi)) => (f64::min(lo, *v), f64::max(hi, *v)),
        });
    }
    out
}

/// Draws `bb` as SVG: per axis a panel of the commanded (blue) and actual (orange)
/// position and one of the following error (red), over time in s, with the span of
/// each row's safety state shaded (quick stop and stopped in red, holding in yellow).
pub fn write_svg(bb: &BlackBox, out: &mut dyn Write) -> io::Result<()> {
    let panels = 2 * bb.axes.len();
    let height = GAP + panels as f64 * (PANEL + GAP) + 20.0;
    writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" font-family="sans-serif" font-size="12">"#
    )?;
    writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#)?;
    let (t0, t1) = match (bb.time_s.first(), bb.time_s.last()) {
        (Some(a), Some(b)) => (*a, *b),
        _ => return writeln!(out, "</svg>"),
    };
    let cols = (WIDTH - 2.0 * PAD) as usize;
    let x_of = |c: usize| PAD + c as f64;
    let mut top = GAP;
    for axis in &bb.axes {
        let name = axis.name.to_ascii_uppercase();
        let u = &axis.unit;
        let cmd = envelope(&bb.time_s, &axis.commanded, t0, t1, cols);
        let act = envelope(&bb.time_s, &axis.actual, t0, t1, cols);
        let err = envelope(&bb.time_s, &axis.following_error, t0, t1, cols);
        let title = format!("{name}: commanded (blue) and actual (orange) position, {u}");
        panel(
            out,
            bb,
            top,
            &title,
            t0,
            t1,
            &[(&cmd, "steelblue"), (&act, "darkorange")],
            u,
            x_of,
        )?;
        top += PANEL + GAP;
        let title = format!("{name}: following error (commanded − actual), {u}");
        panel(out, bb, top, &title, t0, t1, &[(&err, "crimson")], u, x_of)?;
        top += PANEL + GAP;
    }
    writeln!(out, "</svg>")
}

#[allow(clippy::too_many_arguments)]
fn panel(
    out: &mut dyn Write,
    bb: &BlackBox,
    top: f64,
    title: &str,
    t0: f64,
    t1: f64,
    series: &[(&Envelope, &str)],
    unit: &str,
    x_of: impl Fn(usize) -> f64,
) -> io::Result<()> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (s, _) in series {
        for (a, b) in s.iter().flatten() {
            lo = lo.min(*a);
            hi = hi.max(*b);
        }
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return Ok(());
    }
    if hi - lo < 1e-9 {
        lo -= 0.5e-3;
        hi += 0.5e-3;
    }
    let y_of = |v: f64| top + PANEL - (v - lo) / (hi - lo) * PANEL;
    writeln!(out, r#"<text x="{PAD}" y="{}">{title}</text>"#, top - 8.0)?;
    // The safety state, shaded.
    let cols = (WIDTH - 2.0 * PAD) as usize;
    let span = (t1 - t0).max(1e-12);
    let mut shade = vec![""; cols];
    for (t, s) in bb.time_s.iter().zip(&bb.state) {
        let c = (((t - t0) / span) * (cols as f64 - 1.0))
            .round()
            .clamp(0.0, cols as f64 - 1.0) as usize;
        let colour = match s.as_str() {
            "quick_stop" | "stopped" => "#f6d0d0",
            "holding" => "#f6efc0",
            _ => "",
        };
        if !colour.is_empty() {
            shade[c] = colour;
        }
    }
    for (c, colour) in shade.iter().enumerate() {
        if !colour.is_empty() {
            writeln!(
                out,
                r#"<rect x="{:.1}" y="{top}" width="1" height="{PANEL}" fill="{colour}"/>"#,
                x_of(c)
            )?;
        }
    }
    writeln!(
        out,
        r#"<rect x="{PAD}" y="{top}" width="{}" height="{PANEL}" fill="none" stroke="black" stroke-width="0.5"/>"#,
        WIDTH - 2.0 * PAD
    )?;
    // Value ticks at the bottom and top, time ticks at both ends.
    writeln!(
        out,
        r#"<text x="{}" y="{:.1}" text-anchor="end">{}</text>"#,
        PAD - 4.0,
        top + PANEL,
        tick(lo, unit)
    )?;
    writeln!(
        out,
        r#"<text x="{}" y="{:.1}" text-anchor="end">{}</text>"#,
        PAD - 4.0,
        top + 10.0,
        tick(hi, unit)
    )?;
    writeln!(
        out,
        r#"<text x="{PAD}" y="{:.1}">{t0:.3} s</text>"#,
        top + PANEL + 14.0
    )?;
    writeln!(
        out,
        r#"<text x="{}" y="{:.1}" text-anchor="end">{t1:.3} s</text>"#,
        WIDTH - PAD,
        top + PANEL + 14.0
    )?;
    for (s, colour) in series {
        // The envelope: a vertical stroke from the column's lowest to its highest value,
        // joined column to column.
        write!(
            out,
            r#"<polyline class="envelope" fill="none" stroke="{colour}" stroke-width="1" points=""#
        )?;
        for (c, v) in s.iter().enumerate() {
            if let Some((a, b)) = v {
                write!(
                    out,
                    "{:.1},{:.1} {:.1},{:.1} ",
                    x_of(c),
                    y_of(*a),
                    x_of(c),
                    y_of(*b)
                )?;
            }
        }
        writeln!(out, r#""/>"#)?;
    }
    Ok(())
}

fn tick(v: f64, unit: &str) -> String {
    let digits = if v.abs() >= 100.0 { 1 } else { 4 };
    format!("{v:.digits$} {unit}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> String {
        let mut s = String::from(
            "sequence,time_s,state,x_cmd_mm,x_act_mm,x_ferror_mm,x_controlword,x_statusword,a_cmd_deg,a_act_deg,a_ferror_deg,a_controlword,a_statusword\n",
        );
        for k in 0..2000 {
            let t = k as f64 * 0.001;
            let state = if k < 1500 { "running" } else { "quick_stop" };
            // One cycle of a 0.7 mm following error spike at k = 777.
            let err = if k == 777 { 0.7 } else { 0.01 };
            s += &format!(
                "{k},{t},{state},{},{},{err},0x000f,0x1637,{},{},0,0x000f,0x1637\n",
                t * 10.0,
                t * 10.0 - err,
                -t,
                -t
            );
        }
        s
    }

    #[test]
    fn reads_every_row_and_axis() {
        let bb = read(sample().as_bytes()).unwrap();
        assert_eq!(bb.time_s.len(), 2000);
        assert_eq!(bb.axes.len(), 2);
        assert_eq!((bb.axes[0].name, bb.axes[1].name), ('x', 'a'));
        assert_eq!(
            (bb.axes[0].unit.as_str(), bb.axes[1].unit.as_str()),
            ("mm", "deg")
        );
        assert_eq!(bb.axes[0].following_error[777], 0.7);
        assert_eq!(bb.state[1999], "quick_stop");
    }

    #[test]
    fn refuses_other_files_with_the_line() {
        let e = read("t,x,y,z,line,feed_mm_s\n".as_bytes()).unwrap_err();
        assert_eq!(e.line, 1);
        assert!(e.message.starts_with("not a black-box file"), "{e}");
        let bad = sample().replace("777,0.777,running,7.77", "777,0.777,running,seven");
        let e = read(bad.as_bytes()).unwrap_err();
        assert_eq!(e.line, 779);
        assert!(
            e.message.starts_with("`seven") && e.message.ends_with("in column 4 is not a number"),
            "{e}"
        );
    }

    #[test]
    fn the_plot_keeps_a_one_cycle_spike_and_shades_the_stop() {
        let bb = read(sample().as_bytes()).unwrap();
        let mut svg = Vec::new();
        write_svg(&bb, &mut svg).unwrap();
        let svg = String::from_utf8(svg).unwrap();
        // Two axes, two panels each, three series in all per axis.
        assert_eq!(svg.matches(r#"class="envelope""#).count(), 6);
        // The 0.7 mm spike is the top of the X following-error panel: its tick says so,
        // and a point of the envelope reaches the panel's top edge.
        assert!(svg.contains(">0.7000 mm<"), "{svg}");
        // The X following-error panel is the second: its top edge at y = 36 + 160 + 36.
        let err_line = svg
            .lines()
            .find(|l| l.contains(r#"class="envelope""#) && l.contains("crimson"))
            .unwrap();
        assert!(err_line.contains(",232.0 "), "{err_line}");
        // The quick stop (the last quarter of the time) is shaded.
        assert!(svg.matches("#f6d0d0").count() > 100);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    }
}
