//! LinuxCNC's data files that a machine configuration can name: the tool table
//! (`[gcode] tool_table`, LinuxCNC's `tool.tbl` format) and the numbered parameter file
//! (`[gcode] parameter_file`, LinuxCNC's `.var` format).
//!
//! Tool table: one tool a line, words `T` (tool number, required), `P` (pocket), `X` `Y`
//! `Z` `A` `B` `C` (offsets), `D` (diameter), `I` `J` (lathe front and back angles), `Q`
//! (lathe orientation 0–9), each a letter (either case) followed by a number, in any
//! order; `;` starts a comment to the end of the line; blank lines are skipped. Lengths
//! are millimetres (Kerf's machine unit), angles degrees. `U` `V` `W` offsets other than 0
//! are refused (Kerf has no U/V/W axes). Errors are `FILE:LINE:COL: error: MESSAGE`.
//!
//! Parameter file: one parameter a line, its number and its value separated by white
//! space (LinuxCNC writes a tab); lines that are not exactly two numbers are skipped, as
//! LinuxCNC does; the numbers must ascend ("Parameter file out of order"). Values in mm
//! and degrees.

use std::io::{self, Write};
use std::path::Path;

use kerf_gcode::Tool;

use crate::{ConfigError, MAX_COORDINATE_MM, TextPosition};

/// The most tools a table may hold: far beyond any tool changer, and it keeps a mistaken
/// file from filling memory.
pub const MAX_TOOLS: usize = 100_000;

fn invalid(origin: &str, line: usize, col: usize, message: String) -> ConfigError {
    ConfigError::Invalid {
        origin: origin.to_string(),
        position: Some(TextPosition {
            line: u32::try_from(line).unwrap_or(u32::MAX),
            col: u32::try_from(col).unwrap_or(u32::MAX),
        }),
        message,
    }
}

/// Reads a LinuxCNC tool table; `origin` names it in errors.
pub fn load_tool_table(path: &Path, origin: &str) -> Result<Vec<Tool>, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        origin: origin.to_string(),
        source,
    })?;
    parse_tool_table(&text, origin)
}

/// Parses the text of a LinuxCNC tool table; `origin` names it in errors.
pub fn parse_tool_table(text: &str, origin: &str) -> Result<Vec<Tool>, ConfigError> {
    let mut tools: Vec<Tool> = Vec::new();
    for (i, raw_line) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw_line.split(';').next().unwrap_or("");
        let Some((tool, col)) = parse_line(line, line_no, origin)? else {
            continue;
        };
        if tools.iter().any(|t| t.number == tool.number) {
            return Err(invalid(
                origin,
                line_no,
                col,
                format!("tool {} is listed twice", tool.number),
            ));
        }
        if tools.len() == MAX_TOOLS {
            return Err(invalid(
                origin,
                line_no,
                col,
                format!("more than {MAX_TOOLS} tools"),
            ));
        }
        tools.push(tool);
    }
    Ok(tools)
}

/// One line of a tool table without its comment: the tool and the column of its number,
/// or `None` for a line without words.
fn parse_line(
    line: &str,
    line_no: usize,
    origin: &str,
) -> Result<Option<(Tool, usize)>, ConfigError> {
    let mut tool = Tool::default();
    let mut seen = [false; 26];
    let mut number_col = None;
    let mut pos = 0;
    let bytes = line.as_bytes();
    while pos < bytes.len() {
        if bytes[pos].is_ascii_whitespace() {
            pos += 1;
            continue;
        }
        let col = line[..pos].chars().count() + 1;
        let letter = bytes[pos].to_ascii_uppercase();
        if !letter.is_ascii_uppercase() {
            let c = line[pos..].chars().next().unwrap_or('?');
            return Err(invalid(
                origin,
                line_no,
                col,
                format!("expected a word (a letter and a number), found `{c}`"),
            ));
        }
        let start = pos + 1;
        let mut end = start;
        while end < bytes.len() && !bytes[end].is_ascii_whitespace() {
            end += 1;
        }
        let word = &line[pos..end];
        pos = end;
        let value: f64 = match line[start..end].parse() {
            Ok(v) if f64::is_finite(v) => v,
            _ => {
                return Err(invalid(
                    origin,
                    line_no,
                    col,
                    format!("`{word}` is not a letter followed by a number"),
                ));
            }
        };
        let slot = usize::from(letter - b'A');
        if seen[slot] {
            return Err(invalid(
                origin,
                line_no,
                col,
                format!("word {} repeated", letter as char),
            ));
        }
        seen[slot] = true;
        let whole = |what: &str, max: f64| -> Result<u32, ConfigError> {
            if value.fract() == 0.0 && (0.0..=max).contains(&value) {
                Ok(value as u32)
            } else {
                Err(invalid(
                    origin,
                    line_no,
                    col,
                    format!("{what} must be a whole number from 0 to {max}, found {value}"),
                ))
            }
        };
        let coordinate = |what: &str| -> Result<f64, ConfigError> {
            if value.abs() <= MAX_COORDINATE_MM {
                Ok(value)
            } else {
                Err(invalid(
                    origin,
                    line_no,
                    col,
                    format!(
                        "{what} must be between -{MAX_COORDINATE_MM} and {MAX_COORDINATE_MM}, found {value}"
                    ),
                ))
            }
        };
        match letter {
            b'T' => {
                tool.number = whole("the tool number T", f64::from(u32::MAX))?;
                number_col = Some(col);
            }
            b'P' => tool.pocket = whole("the pocket P", f64::from(u32::MAX))?,
            b'X' => tool.offset_xy_mm[0] = coordinate("the X offset (mm)")?,
            b'Y' => tool.offset_xy_mm[1] = coordinate("the Y offset (mm)")?,
            b'Z' => tool.length_mm = coordinate("the Z offset (mm)")?,
            b'A' => tool.offset_abc_deg[0] = coordinate("the A offset (degrees)")?,
            b'B' => tool.offset_abc_deg[1] = coordinate("the B offset (degrees)")?,
            b'C' => tool.offset_abc_deg[2] = coordinate("the C offset (degrees)")?,
            b'U' | b'V' | b'W' => {
                if value != 0.0 {
                    return Err(invalid(
                        origin,
                        line_no,
                        col,
                        "U, V and W offsets are not supported (Kerf has no U, V, W axes)"
                            .to_string(),
                    ));
                }
            }
            b'D' => {
                if !(0.0..=2.0 * MAX_COORDINATE_MM).contains(&value) {
                    return Err(invalid(
                        origin,
                        line_no,
                        col,
                        format!(
                            "the diameter D must be from 0 to {} mm, found {value}",
                            2.0 * MAX_COORDINATE_MM
                        ),
                    ));
                }
                tool.radius_mm = value / 2.0;
            }
            b'I' => tool.front_angle_deg = coordinate("the front angle I (degrees)")?,
            b'J' => tool.back_angle_deg = coordinate("the back angle J (degrees)")?,
            b'Q' => tool.orientation = whole("the orientation Q", 9.0)? as u8,
            _ => {
                return Err(invalid(
                    origin,
                    line_no,
                    col,
                    format!("unknown word {} in a tool table", letter as char),
                ));
            }
        }
    }
    if seen.iter().all(|s| !s) {
        return Ok(None);
    }
    let Some(col) = number_col else {
        return Err(invalid(
            origin,
            line_no,
            1,
            "tool table line without a tool number T".to_string(),
        ));
    };
    Ok(Some((tool, col)))
}

/// Reads a parameter file. A missing file is an empty one (LinuxCNC starts with its
/// persistent parameters at zero then). `origin` names it in errors.
pub fn load_parameter_file(path: &Path, origin: &str) -> Result<Vec<(u32, f64)>, ConfigError> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(source) => {
            return Err(ConfigError::Io {
                origin: origin.to_string(),
                source,
            });
        }
    };
    parse_parameter_file(&text, origin)
}

/// Parses the text of a parameter file; `origin` names it in errors.
pub fn parse_parameter_file(text: &str, origin: &str) -> Result<Vec<(u32, f64)>, ConfigError> {
    let mut out: Vec<(u32, f64)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let [n, v] = fields.as_slice() else {
            continue;
        };
        let (Ok(n), Ok(v)) = (n.parse::<f64>(), v.parse::<f64>()) else {
            continue;
        };
        if n.fract() != 0.0 || !(1.0..=5602.0).contains(&n) || !v.is_finite() {
            return Err(invalid(
                origin,
                i + 1,
                1,
                format!("parameter number {n} out of range (1 to 5602) or value not finite"),
            ));
        }
        let n = n as u32;
        if out.last().is_some_and(|&(last, _)| last >= n) {
            return Err(invalid(
                origin,
                i + 1,
                1,
                "Parameter file out of order".to_string(),
            ));
        }
        out.push((n, v));
    }
    Ok(out)
}

/// Writes a parameter file (number, tab, value with six decimals, as LinuxCNC writes
/// it) atomically ([`write_atomically`]): a crash leaves either the old or the new file.
pub fn write_parameter_file(path: &Path, params: &[(u32, f64)]) -> io::Result<()> {
    let mut text = String::with_capacity(params.len() * 16);
    for &(n, v) in params {
        text.push_str(&format!("{n}\t{v:.6}\n"));
    }
    write_atomically(path, text.as_bytes())
}

/// One tool table line for `tool`, as LinuxCNC writes them: `T` and `P`, the offsets
/// that are not zero (`Z` always), `D` (the diameter), and the lathe words that are not
/// zero; numbers in their shortest exact form.
pub fn tool_table_line(tool: &Tool) -> String {
    let mut line = format!("T{} P{}", tool.number, tool.pocket);
    let words = [
        ('X', tool.offset_xy_mm[0]),
        ('Y', tool.offset_xy_mm[1]),
        ('Z', tool.length_mm),
        ('A', tool.offset_abc_deg[0]),
        ('B', tool.offset_abc_deg[1]),
        ('C', tool.offset_abc_deg[2]),
        ('D', 2.0 * tool.radius_mm),
        ('I', tool.front_angle_deg),
        ('J', tool.back_angle_deg),
        ('Q', f64::from(tool.orientation)),
    ];
    for (letter, value) in words {
        if value != 0.0 || matches!(letter, 'Z' | 'D') {
            // `-0` reads back as 0 and says nothing more.
            let value = if value == 0.0 { 0.0 } else { value };
            line.push_str(&format!(" {letter}{value}"));
        }
    }
    line
}

/// The text of a tool table with `tools` written in: the line of each tool already in
/// `text` gets its new words (its comment kept), the other tools are appended in the
/// order given; every other line (comments, other tools, blank lines) stays as it was.
pub fn update_tool_table_text(text: &str, tools: &[Tool]) -> String {
    let mut out = String::with_capacity(text.len() + 64 * tools.len());
    let mut written = vec![false; tools.len()];
    for raw_line in text.lines() {
        let (words, comment) = match raw_line.find(';') {
            Some(i) => (&raw_line[..i], Some(&raw_line[i..])),
            None => (raw_line, None),
        };
        let number = parse_line(words, 0, "")
            .ok()
            .flatten()
            .map(|(t, _)| t.number);
        let changed = number.and_then(|n| tools.iter().position(|t| t.number == n));
        match changed {
            Some(i) if !written[i] => {
                written[i] = true;
                out.push_str(&tool_table_line(&tools[i]));
                if let Some(c) = comment {
                    out.push(' ');
                    out.push_str(c);
                }
            }
            _ => out.push_str(raw_line),
        }
        out.push('\n');
    }
    for (tool, done) in tools.iter().zip(written) {
        if !done {
            out.push_str(&tool_table_line(tool));
            out.push('\n');
        }
    }
    out
}

/// Writes `tools` into the tool table at `path` ([`update_tool_table_text`]; a missing
/// file is an empty one), atomically ([`write_atomically`]).
pub fn write_tool_table(path: &Path, tools: &[Tool]) -> io::Result<()> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == io::ErrorKind::NotFound => String::new(),
        Err(e) => return Err(e),
    };
    write_atomically(path, update_tool_table_text(&text, tools).as_bytes())
}

/// Replaces the file at `path` with `bytes` so that a crash or a power cut leaves either
/// the old or the new file, never a mix: the bytes go to a temporary file in the same
/// directory (created when missing), which is synced to the disk, then renamed over
/// `path`, and the directory is synced so that the rename is kept.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir)?;
    let name = path
        .file_name()
        .map_or_else(|| "file".into(), |n| n.to_string_lossy());
    // Unique per process: two commands writing at once each rename a whole file.
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let written = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    // The rename is in the directory: sync it too (not every file system lets a
    // directory be opened for that; the file itself is safe either way).
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linuxcnc_tool_table_lines() {
        // The sample lines of LinuxCNC's manual ("Tool Table Format"), in mm.
        let text = "T1 P1 Z0.511 D0.125 ;1/8 end mill\n\
                    \n\
                    ; a comment line\n\
                    t2 p17 x1 y-2 z3 a4 b5 c6 d10 i95 j155 q9\n";
        let tools = parse_tool_table(text, "tool.tbl").expect("valid table");
        assert_eq!(tools.len(), 2);
        assert_eq!(tools[0].number, 1);
        assert_eq!(tools[0].pocket, 1);
        assert_eq!(tools[0].length_mm, 0.511);
        assert_eq!(tools[0].radius_mm, 0.0625);
        let t = &tools[1];
        assert_eq!((t.number, t.pocket), (2, 17));
        assert_eq!(t.offsets_mm_deg(), [1.0, -2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(t.radius_mm, 5.0);
        assert_eq!(
            (t.front_angle_deg, t.back_angle_deg, t.orientation),
            (95.0, 155.0, 9)
        );
    }

    #[test]
    fn tool_table_errors_name_the_place() {
        let cases = [
            (
                "T1 Z1\nT1 Z2\n",
                "tool.tbl:2:1: error: tool 1 is listed twice",
            ),
            (
                "T1 Zx\n",
                "tool.tbl:1:4: error: `Zx` is not a letter followed by a number",
            ),
            (
                "P3 Z1\n",
                "tool.tbl:1:1: error: tool table line without a tool number T",
            ),
            (
                "T1 K2\n",
                "tool.tbl:1:4: error: unknown word K in a tool table",
            ),
            (
                "T1 U2\n",
                "tool.tbl:1:4: error: U, V and W offsets are not supported",
            ),
            (
                "T-1\n",
                "tool.tbl:1:1: error: the tool number T must be a whole number",
            ),
            (
                "T1 Q10\n",
                "tool.tbl:1:4: error: the orientation Q must be a whole number from 0 to 9",
            ),
            (
                "T1 D-1\n",
                "tool.tbl:1:4: error: the diameter D must be from 0",
            ),
            ("T1 #\n", "tool.tbl:1:4: error: expected a word"),
        ];
        for (text, want) in cases {
            let e = parse_tool_table(text, "tool.tbl")
                .expect_err(text)
                .to_string();
            assert!(e.starts_with(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn parameter_file_reads_pairs_skips_other_lines_and_needs_ascending_numbers() {
        let p = parse_parameter_file("5161\t1.5\nnot a pair\n5162 -2\n5220 1.000000 x\n", "v")
            .expect("valid");
        assert_eq!(p, [(5161, 1.5), (5162, -2.0)]);
        let e = parse_parameter_file("5162 0\n5161 0\n", "p.var").expect_err("order");
        assert_eq!(
            e.to_string(),
            "p.var:2:1: error: Parameter file out of order"
        );
        let e = parse_parameter_file("6000 0\n", "p.var").expect_err("range");
        assert!(
            e.to_string()
                .starts_with("p.var:1:1: error: parameter number 6000")
        );
    }

    #[test]
    fn tool_table_writer_keeps_comments_and_other_tools_and_reads_back() {
        let text = "; shop tools\nT1 P1 Z0.511 D0.125 ;1/8 end mill\n\nT2 P2 Z3 D6\n";
        let mut t1 = parse_tool_table(text, "t").expect("valid")[0];
        t1.length_mm = -42.25;
        let t7 = Tool {
            number: 7,
            pocket: 7,
            length_mm: 12.0,
            radius_mm: 1.5,
            offset_xy_mm: [0.5, 0.0],
            orientation: 2,
            ..Tool::default()
        };
        let out = update_tool_table_text(text, &[t7, t1]);
        assert_eq!(
            out,
            "; shop tools\nT1 P1 Z-42.25 D0.125 ;1/8 end mill\n\nT2 P2 Z3 D6\nT7 P7 X0.5 Z12 D3 Q2\n"
        );
        let back = parse_tool_table(&out, "t").expect("reads back");
        assert_eq!(back.len(), 3);
        assert_eq!(back[0], t1);
        assert_eq!(back[2], t7);
    }

    #[test]
    fn parameter_file_round_trip() {
        let dir = std::env::temp_dir().join(format!("kerf-var-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("kerf.var");
        assert_eq!(
            load_parameter_file(&path, "kerf.var").expect("missing = empty"),
            []
        );
        let params = [(5161, 12.5), (5220, 2.0), (5221, -0.25)];
        write_parameter_file(&path, &params).expect("write");
        let text = std::fs::read_to_string(&path).expect("read");
        assert_eq!(text, "5161\t12.500000\n5220\t2.000000\n5221\t-0.250000\n");
        assert_eq!(
            load_parameter_file(&path, "kerf.var").expect("read back"),
            params
        );
        std::fs::remove_dir_all(&dir).expect("clean up");
    }
}
