//! The differential harness: a LinuxCNC program run through Kerf and through LinuxCNC's own
//! interpreter `rs274` (its canonical calls, read by [`crate::canon`]), compared move by
//! move and event by event.
//!
//! What is compared, in program order: the number of moves, their kind (rapid, feed line,
//! arc), end points, arc centres, planes, sweeps (so turns), A/B/C, feeds, corner modes
//! (G61/G61.1 exact stop, G64 with its P tolerance), and the events
//! (S, T, M6, M3/M4/M5, M7/M8/M9, G4 with its time, M0/M1/M60, M2/M30, the outputs
//! M62–M65 with their number and M67/M68 with number and value, messages and prints; not
//! M66, for which rs274 prints nothing). Lengths agree within the tolerance each canon item carries (1e-6 plus half a
//! unit of the last printed digit of every number it comes from, in the units it was
//! printed in); an arc LinuxCNC would spiral (its printed start and end radii differ) may
//! have its centre that much further away, since Kerf moves the centre to make the circle
//! exact. A program rs274 refuses must be refused by Kerf on the line rs274 prints, after
//! the same items (rs274 may have run the first words of the failing block; Kerf runs
//! nothing of it, so only events may follow in the canon).
//!
//! Goldens live in `tests/data/ngc/<area>/NAME.ngc` with `NAME.canon` (rs274's standard
//! output from `tests/rs274/canon.sh`), `NAME.err` when rs274 refused the program
//! (`exit N` and its standard error, written by `tests/rs274/golden.sh`) and `NAME.tbl`, a
//! tool table in mm, when the program needs tools, and `NAME.var`, the persistent parameters
//! at program start (coordinate systems, G28/G30 positions) in mm and degrees.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use kerf_gcode::{
    CornerMode, Diagnostic, Dialect, EventCode, Interpreter, Item, Path as KPath, Settings, Tool,
};

use crate::canon::{self, CanonCorner, CanonItem, CanonMove, MoveKind};

/// The most items one program may yield before the harness calls it endless.
pub const MAX_ITEMS: usize = 2_000_000;

/// rs274 refused a program: its exit status and what it printed on standard error.
#[derive(Clone, Debug, PartialEq)]
pub struct Refusal {
    /// rs274's exit status.
    pub exit: i32,
    /// The error message (the line before the last of standard error).
    pub message: String,
    /// The text of the block rs274 failed on, as it printed it (the last line).
    pub block: String,
}

impl Refusal {
    /// Reads rs274's exit status and standard error.
    pub fn from_stderr(exit: i32, stderr: &str) -> Refusal {
        let lines: Vec<&str> = stderr
            .lines()
            .filter(|l| !l.trim().is_empty() && l.trim() != "executing")
            .collect();
        let block = lines.last().map_or(String::new(), |s| s.to_string());
        let message = if lines.len() >= 2 {
            lines[lines.len() - 2].to_string()
        } else {
            block.clone()
        };
        Refusal {
            exit,
            message,
            block,
        }
    }

    /// Reads a `NAME.err` file: a first line `exit N`, then rs274's standard error.
    pub fn from_err_file(text: &str) -> Option<Refusal> {
        let (first, rest) = text.split_once('\n').unwrap_or((text, ""));
        let exit = first.trim().strip_prefix("exit ")?.trim().parse().ok()?;
        Some(Refusal::from_stderr(exit, rest))
    }

    /// The content of a `NAME.err` file for this exit status and standard error.
    pub fn err_file(exit: i32, stderr: &str) -> String {
        format!("exit {exit}\n{stderr}")
    }
}

/// Reads a LinuxCNC tool table (`T1 P1 X.. Y.. Z25.4 A.. B.. C.. D6 I.. J.. Q.. ;comment`),
/// lengths in mm and angles in degrees: Z is the tool length, D the diameter.
pub fn parse_tool_table(text: &str) -> Result<Vec<Tool>, String> {
    let mut tools = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split(';').next().unwrap_or("");
        let mut number = None;
        let mut tool = Tool::default();
        for word in line.split_whitespace() {
            let (letter, value) = word.split_at(1);
            let value: f64 = value
                .parse()
                .map_err(|e| format!("tool table line {}: bad word {word}: {e}", i + 1))?;
            match letter.to_ascii_uppercase().as_str() {
                "T" => number = Some(value as u32),
                "P" => tool.pocket = value as u32,
                "X" => tool.offset_xy_mm[0] = value,
                "Y" => tool.offset_xy_mm[1] = value,
                "Z" => tool.length_mm = value,
                "A" => tool.offset_abc_deg[0] = value,
                "B" => tool.offset_abc_deg[1] = value,
                "C" => tool.offset_abc_deg[2] = value,
                "D" => tool.radius_mm = value / 2.0,
                "I" => tool.front_angle_deg = value,
                "J" => tool.back_angle_deg = value,
                "Q" => tool.orientation = value as u8,
                _ => {}
            }
        }
        if let Some(number) = number {
            tool.number = number;
            tools.push(tool);
        }
    }
    Ok(tools)
}

/// Applies a LinuxCNC parameter file (`NUMBER VALUE` lines, mm and degrees; the `NAME.var`
/// of a golden) to Kerf's settings: every parameter is restored at program start
/// ([`Settings::parameters`]), as LinuxCNC restores its `.var` file.
pub fn apply_var_file(text: &str, settings: &mut Settings) -> Result<(), String> {
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let (Some(n), Some(v)) = (words.next(), words.next()) else {
            continue;
        };
        let bad = |e: &dyn std::fmt::Display| format!("parameter file line {}: {e}", i + 1);
        let n: u32 = n.parse().map_err(|e| bad(&e))?;
        let v: f64 = v.parse().map_err(|e| bad(&e))?;
        settings.parameters.push((n, v));
    }
    Ok(())
}

/// What Kerf made of a program.
#[derive(Debug)]
pub struct KerfRun {
    /// Items up to the first error.
    pub items: Vec<Item>,
    /// The first error.
    pub error: Option<Diagnostic>,
}

/// Runs the program `src`, read from the file `program`, through Kerf's LinuxCNC dialect
/// with `tools`, subroutine files searched in the program's directory (where rs274 finds
/// them too), as `kerf sim` runs it.
pub fn run_kerf(src: &[u8], tools: Vec<Tool>, program: &Path) -> KerfRun {
    let mut settings = program_settings(tools, program);
    settings.block_delete = asks_block_delete(src);
    run_kerf_with(src, settings)
}

/// The settings `kerf sim` gives the program file `program`: `tools`, its directory on
/// the subroutine path, and the file itself for subroutines defined after their call.
pub fn program_settings(tools: Vec<Tool>, program: &Path) -> Settings {
    Settings {
        tools,
        subroutine_path: program
            .parent()
            .map(|d| vec![d.to_path_buf()])
            .unwrap_or_default(),
        program_file: Some(program.to_path_buf()),
        ..Settings::default()
    }
}

/// The marker of a golden program that runs with the block delete switch on: its first
/// line is this comment (`tests/rs274/canon.sh` then runs rs274 with `-b`).
pub const BLOCK_DELETE_MARK: &str = "(kerf: block_delete on)";

/// Whether the program's first line asks for the block delete switch on.
pub fn asks_block_delete(src: &[u8]) -> bool {
    let first = src.split(|&b| b == b'\n').next().unwrap_or(&[]);
    String::from_utf8_lossy(first)
        .to_ascii_lowercase()
        .contains(BLOCK_DELETE_MARK)
}

/// Runs `src` through Kerf's LinuxCNC dialect with `settings`.
pub fn run_kerf_with(src: &[u8], settings: Settings) -> KerfRun {
    let mut items = Vec::new();
    let mut error = None;
    for next in Interpreter::new(src, Dialect::LinuxCnc, settings) {
        match next {
            Ok(item) => {
                items.push(item);
                if items.len() > MAX_ITEMS {
                    error = Some(Diagnostic {
                        line: 0,
                        col: 0,
                        message: format!("harness: more than {MAX_ITEMS} items, stopped"),
                        file: None,
                        called_from: Vec::new(),
                    });
                    break;
                }
            }
            Err(e) => {
                error = Some(e);
                break;
            }
        }
    }
    KerfRun { items, error }
}

/// The constructs out of Kerf's scope for LinuxCNC (issue 9): an error naming one of them
/// and saying "not supported" (not "not supported yet") is an accepted refusal. Each entry:
/// fragments of which one must appear in the message, and the name in the report.
pub const OUT_OF_SCOPE: &[(&[&str], &str)] = &[
    (
        &["spindle synchron", "spindle-synchron"],
        "spindle-synchronised motion",
    ),
    (&["G38", "probing"], "probing"),
    (&["spline", "G5 ", "G5.1", "G5.2", "(G5)"], "splines"),
    (
        &["lathe", "G7 ", "G8 ", "G70", "G71", "G72", "G96"],
        "lathe codes",
    ),
    (&["remap"], "remapped codes"),
    (&["Python", "python"], "Python"),
    (&["U, V", "U/V/W", "U V W"], "U/V/W axes"),
];

/// The out-of-scope construct an error message names, if it is an out-of-scope refusal.
pub fn out_of_scope(message: &str) -> Option<&'static str> {
    if !message.contains("not supported") || message.contains("not supported yet") {
        return None;
    }
    OUT_OF_SCOPE
        .iter()
        .find(|(frags, _)| frags.iter().any(|f| message.contains(f)))
        .map(|(_, name)| *name)
}

/// The result of one comparison.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Same motion and events.
    Same {
        /// Moves compared.
        moves: usize,
        /// Events compared.
        events: usize,
    },
    /// Both refuse the program on the same line, after the same items.
    BothRefuse {
        /// 1-based line.
        line: u32,
        /// rs274's message.
        message: String,
    },
    /// Kerf refuses an out-of-scope construct, after the same items as rs274.
    OutOfScope {
        /// Which construct.
        construct: &'static str,
        /// Kerf's diagnostic.
        diag: String,
    },
    /// rs274 refuses the program and Kerf does not (or on another line).
    Rs274Refuses {
        /// rs274's message and failing block.
        rs274: String,
        /// What Kerf did.
        kerf: String,
    },
    /// Kerf refuses a program rs274 accepts, with an error that is not out of scope.
    KerfRefuses {
        /// Kerf's diagnostic, and the source line.
        diag: String,
    },
    /// The motion or the events differ.
    Mismatch(String),
}

impl Verdict {
    /// Whether a golden program passes: same, both refuse, or out of scope.
    pub fn golden_ok(&self) -> bool {
        matches!(
            self,
            Verdict::Same { .. } | Verdict::BothRefuse { .. } | Verdict::OutOfScope { .. }
        )
    }
}

fn source_line(src: &[u8], line: u32) -> String {
    let text = String::from_utf8_lossy(src);
    text.lines()
        .nth((line as usize).saturating_sub(1))
        .unwrap_or("")
        .trim_end_matches('\r')
        .to_string()
}

/// The source line a diagnostic names: in its subroutine file when it has one (read from
/// disk; the program's own source otherwise).
fn diag_source_line(src: &[u8], d: &Diagnostic) -> String {
    match &d.file {
        Some(f) => match std::fs::read(&**f) {
            Ok(sub) => source_line(&sub, d.line),
            Err(_) => String::new(),
        },
        None => source_line(src, d.line),
    }
}

fn fmt_v(p: &kerf_gcode::Vec3) -> String {
    format!("({:.6}, {:.6}, {:.6})", p.x, p.y, p.z)
}

fn describe_kerf(item: &Item, src: &[u8]) -> String {
    match item {
        Item::Move(m) => {
            let kind = match (&m.path, m.rapid) {
                (KPath::Arc(_), _) => "arc",
                (_, true) => "rapid",
                _ => "feed",
            };
            let mut s = format!("{kind} to {}", fmt_v(&m.path.end()));
            if let KPath::Arc(a) = &m.path {
                let _ = write!(
                    s,
                    " centre {} axis {} sweep {:.9} rad",
                    fmt_v(&a.center),
                    fmt_v(&a.axis),
                    a.sweep_rad
                );
            }
            if let Some((_, e)) = m.abc_deg {
                let _ = write!(s, " abc ({:.6}, {:.6}, {:.6})", e[0], e[1], e[2]);
            }
            if let Some(f) = m.feed_mm_min {
                let _ = write!(s, " F{f:.6} mm/min");
            }
            let _ = write!(s, " [line {}: {}]", m.line, source_line(src, m.line).trim());
            s
        }
        Item::Event(e) => {
            let mut s = format!("event {}", e.code.as_str());
            if let Some(v) = e.value {
                let _ = write!(s, " {v}");
            }
            if let Some(q) = e.q {
                let _ = write!(s, " Q{q}");
            }
            if let Some(t) = &e.text {
                let _ = write!(s, " {t:?}");
            }
            let _ = write!(s, " [line {}: {}]", e.line, source_line(src, e.line).trim());
            s
        }
    }
}

fn describe_canon(item: &CanonItem, canon_text: &str) -> String {
    let mut s = match item {
        CanonItem::Move(m) => {
            let kind = match m.kind {
                MoveKind::Rapid => "rapid",
                MoveKind::Feed => "feed",
                MoveKind::Arc => "arc",
            };
            let mut s = format!("{kind} to {}", fmt_v(&m.end_mm));
            if let Some(a) = &m.arc {
                let _ = write!(
                    s,
                    " centre {} axis {} sweep {:.9} rad",
                    fmt_v(&a.center_mm),
                    fmt_v(&a.axis),
                    a.sweep_rad
                );
            }
            let e = m.end_abc_deg;
            let _ = write!(s, " abc ({:.6}, {:.6}, {:.6})", e[0], e[1], e[2]);
            if let Some(f) = m.feed_mm_min {
                let _ = write!(s, " F{f:.6} mm/min");
            }
            let _ = write!(s, " (tolerance {:.2e} mm)", m.tol_mm);
            s
        }
        CanonItem::Event(e) => {
            let code = if e.code == EventCode::Msg {
                "MSG/DEBUG"
            } else {
                e.code.as_str()
            };
            let mut s = format!("event {code}");
            if let Some(v) = e.value {
                let _ = write!(s, " {v}");
            }
            if let Some(q) = e.q {
                let _ = write!(s, " Q{q}");
            }
            if let Some(t) = &e.text {
                let _ = write!(s, " {t:?}");
            }
            s
        }
        CanonItem::Other { call, .. } => format!("unmodelled call {call}"),
    };
    let n = item.canon_line();
    let _ = write!(s, " [canon line {n}: {}]", canon::call_at(canon_text, n));
    s
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn close_v(a: &kerf_gcode::Vec3, b: &kerf_gcode::Vec3, tol: f64) -> bool {
    (a - b).amax() <= tol
}

/// Why a Kerf move differs from a canon move, or `None` when they agree.
pub fn move_difference(k: &kerf_gcode::Move, c: &CanonMove) -> Option<String> {
    let kind_ok = match (&k.path, c.kind) {
        (KPath::Line(_), MoveKind::Rapid) => k.rapid,
        (KPath::Line(_), MoveKind::Feed) => !k.rapid,
        (KPath::Arc(_), MoveKind::Arc) => !k.rapid,
        _ => false,
    };
    if !kind_ok {
        return Some("kind".into());
    }
    let tol = c.tol_mm;
    if !close_v(&k.path.end(), &c.end_mm, tol) {
        return Some("end point".into());
    }
    let k_abc = k.abc_deg.map_or([0.0; 3], |(_, e)| e);
    if k_abc
        .iter()
        .zip(c.end_abc_deg.iter())
        .any(|(a, b)| !close(*a, *b, canon::BASE_TOL + 4.0 * canon::HALF_DIGIT))
    {
        return Some("A/B/C".into());
    }
    if let (KPath::Arc(ka), Some(ca)) = (&k.path, &c.arc) {
        if ka.axis.dot(&ca.axis) < 1.0 - 1e-9 {
            return Some("plane".into());
        }
        // LinuxCNC spirals when its start and end radii differ; Kerf moves the centre onto
        // the chord's perpendicular bisector, the point nearest LinuxCNC's centre: that
        // distance is |r_start² − r_end²| / (2 · chord).
        let (rs, re) = (ca.start_radius_mm, ca.end_radius_mm);
        let d = c.end_mm - c.start_mm;
        let chord = (d - ca.axis * d.dot(&ca.axis)).norm();
        let spiral = if chord <= tol {
            (rs - re).abs()
        } else {
            (rs - re)
                .abs()
                .max((rs * rs - re * re).abs() / (2.0 * chord))
        };
        if !close_v(&ka.center, &ca.center_mm, tol + spiral) {
            return Some("arc centre".into());
        }
        let r = ca.start_radius_mm.max(ca.end_radius_mm).max(1e-9);
        let sweep_tol = 1e-9 + 2.0 * (tol + spiral) / r;
        if !close(ka.sweep_rad, ca.sweep_rad, sweep_tol) {
            return Some("sweep (direction or turns)".into());
        }
    }
    let corner_ok = match (k.corner, c.corner) {
        // Kerf has one exact-stop mode for G61 and G61.1.
        (CornerMode::ExactStop, CanonCorner::ExactStop | CanonCorner::ExactPath) => true,
        (
            CornerMode::Blend {
                tolerance_mm,
                naive_cam_mm,
            },
            CanonCorner::Continuous {
                tolerance_mm: t,
                tol_mm,
                naive_cam_mm: q,
                naive_tol_mm,
            },
        ) => {
            close(tolerance_mm.unwrap_or(0.0), t, tol_mm + canon::BASE_TOL)
                && close(
                    naive_cam_mm.unwrap_or(0.0),
                    q,
                    naive_tol_mm + canon::BASE_TOL,
                )
        }
        _ => false,
    };
    if !corner_ok {
        return Some("corner mode (G61/G61.1/G64)".into());
    }
    match (k.feed_mm_min, c.feed_mm_min) {
        (None, None) => {}
        (Some(a), Some(b)) if close(a, b, c.feed_tol_mm_min + 1e-9 * b.abs()) => {}
        _ => return Some("feed".into()),
    }
    None
}

fn event_difference(k: &kerf_gcode::Event, c: &canon::CanonEvent) -> Option<String> {
    let code_ok = match c.code {
        EventCode::Msg => matches!(k.code, EventCode::Msg | EventCode::Debug),
        code => k.code == code,
    };
    if !code_ok {
        return Some("event".into());
    }
    match (k.value, c.value) {
        (_, None) => {}
        (Some(a), Some(b)) if close(a, b, c.value_tol) => {}
        _ => return Some("event value".into()),
    }
    match (k.q, c.q) {
        (_, None) => {}
        (Some(a), Some(b)) if close(a, b, c.value_tol) => {}
        _ => return Some("analog output value (Q)".into()),
    }
    if let Some(ct) = &c.text {
        let kt = k.text.as_deref().unwrap_or("");
        if kt.trim_end() != ct.trim_end() {
            return Some("message text".into());
        }
    }
    None
}

/// What may follow in the canon after Kerf's last item.
#[derive(Clone, Copy, PartialEq)]
enum Rest {
    /// Nothing: both ran the whole program.
    Nothing,
    /// Events only: rs274's reset calls after its own refusal.
    Events,
    /// Anything: Kerf refused an out-of-scope block, which rs274 executes (probing,
    /// splines, lathe cycles, threading) before going on with the rest of the program.
    /// Kerf executes no block partly, so its items are those of the blocks before.
    Anything,
}

/// Compares Kerf's items with the canon's, item by item. `Ok((moves, events))` when every
/// item of `kerf` matches the first items of `canon` and the canon items after them are
/// what `rest` allows; `Err` names the first difference, both sides.
fn compare_items(
    kerf: &[Item],
    canon_items: &[CanonItem],
    src: &[u8],
    canon_text: &str,
    rest: Rest,
) -> Result<(usize, usize), String> {
    let (mut moves, mut events) = (0, 0);
    for (i, k) in kerf.iter().enumerate() {
        let Some(c) = canon_items.get(i) else {
            return Err(format!(
                "item {}: Kerf has more items than rs274\n  kerf:  {}\n  rs274: (nothing more)",
                i + 1,
                describe_kerf(k, src)
            ));
        };
        let diff = match (k, c) {
            (Item::Move(km), CanonItem::Move(cm)) => move_difference(km, cm),
            (Item::Event(ke), CanonItem::Event(ce)) => event_difference(ke, ce),
            (Item::Move(_), _) => Some("a move against an event".into()),
            (Item::Event(_), _) => Some("an event against a move".into()),
        };
        if let Some(what) = diff {
            return Err(format!(
                "item {} differs ({what})\n  kerf:  {}\n  rs274: {}",
                i + 1,
                describe_kerf(k, src),
                describe_canon(c, canon_text)
            ));
        }
        match k {
            Item::Move(_) => moves += 1,
            Item::Event(_) => events += 1,
        }
    }
    if let Some(c) = canon_items.get(kerf.len()) {
        let only_events = canon_items[kerf.len()..]
            .iter()
            .all(|c| matches!(c, CanonItem::Event(_)));
        let allowed = match rest {
            Rest::Nothing => false,
            Rest::Events => only_events,
            Rest::Anything => true,
        };
        if !allowed {
            return Err(format!(
                "item {}: rs274 has more items than Kerf\n  kerf:  (nothing more)\n  rs274: {}",
                kerf.len() + 1,
                describe_canon(c, canon_text)
            ));
        }
    }
    Ok((moves, events))
}

/// Compares one program: its source, Kerf's run of it, rs274's canon output and, when
/// rs274 refused it, the refusal.
pub fn compare(src: &[u8], kerf: &KerfRun, canon_text: &str, refusal: Option<&Refusal>) -> Verdict {
    let kept = whole_turns_as_spirals(&overrides_as_rs274_prints_them(&without_g88_retracts(
        &without_input_waits(&kerf.items),
    )));
    let kerf = &KerfRun {
        items: kept,
        error: kerf.error.clone(),
    };
    let canon_items = match canon::parse(canon_text) {
        Ok(c) => c,
        Err(e) => return Verdict::Mismatch(format!("the canon output cannot be read: {e}")),
    };
    // A diagnostic in a subroutine file names the file.
    let diag_text = |d: &Diagnostic| {
        let file = d.file.as_deref().map_or(String::new(), |f| {
            let name = Path::new(f)
                .file_name()
                .map_or_else(|| f.to_string(), |n| n.to_string_lossy().into_owned());
            format!("{name}:")
        });
        format!(
            "{file}{d} [line {}: {}]",
            d.line,
            diag_source_line(src, d).trim()
        )
    };
    match (refusal, &kerf.error) {
        (Some(r), Some(d)) => {
            let rs274 = format!("{} [block: {}]", r.message, r.block.trim());
            let text = String::from_utf8_lossy(src);
            let found = text.lines().any(|l| l.trim() == r.block.trim());
            if found && diag_source_line(src, d).trim() != r.block.trim() {
                return Verdict::Rs274Refuses {
                    rs274,
                    kerf: format!("refuses another line: {}", diag_text(d)),
                };
            }
            match compare_items(&kerf.items, &canon_items, src, canon_text, Rest::Events) {
                Ok(_) => Verdict::BothRefuse {
                    line: d.line,
                    message: r.message.clone(),
                },
                Err(e) => Verdict::Mismatch(format!("before the refusal: {e}")),
            }
        }
        (Some(r), None) => Verdict::Rs274Refuses {
            rs274: format!("{} [block: {}]", r.message, r.block.trim()),
            kerf: "accepts it".into(),
        },
        (None, Some(d)) => {
            let Some(construct) = out_of_scope(&d.message) else {
                return Verdict::KerfRefuses { diag: diag_text(d) };
            };
            match compare_items(&kerf.items, &canon_items, src, canon_text, Rest::Anything) {
                Ok(_) => Verdict::OutOfScope {
                    construct,
                    diag: diag_text(d),
                },
                Err(e) => Verdict::Mismatch(format!("before the out-of-scope refusal: {e}")),
            }
        }
        (None, None) => {
            match compare_items(&kerf.items, &canon_items, src, canon_text, Rest::Nothing) {
                Ok((moves, events)) => Verdict::Same { moves, events },
                Err(e) => Verdict::Mismatch(e),
            }
        }
    }
}

/// Kerf's items with each whole turn that LinuxCNC spirals as one arc: where the end of a
/// centre-format arc lies on the ray from its centre through its start, LinuxCNC turns a
/// whole circle spiralling to the end radius (one ARC_FEED); Kerf turns the whole circle at
/// the start radius, then moves along the radius to the end (an arc, then a line of the
/// same block no longer than 1 mm, starting where the arc ends). The pair is compared as
/// the arc with the line's end, which the spiral tolerance of [`move_difference`] covers.
fn whole_turns_as_spirals(items: &[Item]) -> Vec<Item> {
    let mut out: Vec<Item> = Vec::with_capacity(items.len());
    for item in items {
        if let (Item::Move(l), Some(Item::Move(a))) = (item, out.last_mut())
            && let (KPath::Line(line), KPath::Arc(arc)) = (&l.path, &mut a.path)
            && l.line == a.line
            && !l.rapid
            && arc.sweep_rad.abs() >= std::f64::consts::TAU - 1e-9
            && (line.start - arc.end).norm() < 1e-9
            && (line.end - line.start).norm() <= 1.0
        {
            arc.end = line.end;
            continue;
        }
        out.push(item.clone());
    }
    out
}

/// Kerf's items without its M66 events: rs274 prints no canonical call for a wait on an
/// input (its WAIT is silent), so they are not compared. What the wait gives `#5399` is
/// compared where the program prints it or branches on it; rs274's answer is the
/// parameter's previous value, Kerf's offline one the simulated inputs (all off), so the
/// golden programs read `#5399` only where the two agree (`docs/linuxcnc/harness.md`).
fn without_input_waits(items: &[Item]) -> Vec<Item> {
    items
        .iter()
        .filter(|i| !matches!(i, Item::Event(e) if matches!(e.code, EventCode::M66 | EventCode::M66Analog)))
        .cloned()
        .collect()
}

/// Kerf's items with M48 (M49) as rs274 prints it: the feed override enabled (disabled),
/// then the spindle override, the events M50 and M51 would give.
fn overrides_as_rs274_prints_them(items: &[Item]) -> Vec<Item> {
    let mut out = Vec::with_capacity(items.len());
    for item in items {
        match item {
            Item::Event(e) if matches!(e.code, EventCode::M48 | EventCode::M49) => {
                let on = if e.code == EventCode::M48 { 1.0 } else { 0.0 };
                for code in [EventCode::M50, EventCode::M51] {
                    out.push(Item::Event(kerf_gcode::Event::new(e.line, code, Some(on))));
                }
            }
            _ => out.push(item.clone()),
        }
    }
    out
}

/// Kerf's items without the one documented difference of the canned cycles: after G88's
/// program stop, where LinuxCNC leaves the retract to the operator (rs274 prints nothing,
/// and its next move starts at the bottom of the hole), Kerf makes the retract a rapid to
/// the clearance level so that its moves stay continuous. That rapid is not compared: it
/// is the move right after an M0 event of the same block, which only a G88 cycle makes (a
/// block's own M0 comes after its motion).
fn without_g88_retracts(items: &[Item]) -> Vec<Item> {
    let mut kept: Vec<Item> = Vec::with_capacity(items.len());
    for item in items {
        if let (Item::Move(m), Some(Item::Event(e))) = (item, kept.last())
            && e.code == EventCode::M0
            && e.line == m.line
            && m.rapid
        {
            continue;
        }
        kept.push(item.clone());
    }
    kept
}

/// One golden program: `NAME.ngc` with `NAME.canon`, and `NAME.err`/`NAME.tbl` if present.
#[derive(Clone, Debug)]
pub struct Golden {
    /// The program.
    pub ngc: PathBuf,
    /// rs274's standard output.
    pub canon: PathBuf,
    /// rs274's exit status and standard error, when it refused the program.
    pub err: Option<PathBuf>,
    /// The tool table (mm).
    pub tbl: Option<PathBuf>,
    /// The persistent parameters at program start (mm, degrees).
    pub var: Option<PathBuf>,
}

/// Whether a program is a subroutine file (LinuxCNC's rule: a file `NAME.ngc` whose first
/// block is `o<NAME> sub`), which is called by other programs and is no golden itself.
pub fn is_subroutine_file(path: &Path, src: &str) -> bool {
    let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
        return false;
    };
    let first = src
        .lines()
        .map(|l| {
            // Comments and blank lines before the sub do not count.
            let l = l.trim();
            let l = l.split(';').next().unwrap_or("");
            let mut out = String::new();
            let mut depth = 0;
            for ch in l.chars() {
                match ch {
                    '(' => depth += 1,
                    ')' if depth > 0 => depth -= 1,
                    _ if depth == 0 => out.push(ch),
                    _ => {}
                }
            }
            out.trim().to_ascii_lowercase().replace(' ', "")
        })
        .find(|l| !l.is_empty() && l != "%");
    first.is_some_and(|l| l.starts_with(&format!("o<{}>sub", stem.to_ascii_lowercase())))
}

/// Every `*.ngc` under `dir`, recursively, sorted.
pub fn ngc_files(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d)? {
            let path = entry?.path();
            if path.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("ngc"))
            {
                out.push(path);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// The golden programs under `dir`; `Err` lists programs without a `.canon` (subroutine
/// files excepted).
pub fn goldens(dir: &Path) -> Result<Vec<Golden>, String> {
    let files = ngc_files(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out = Vec::new();
    let mut missing = Vec::new();
    for ngc in files {
        let canon = ngc.with_extension("canon");
        if !canon.exists() {
            let src = std::fs::read_to_string(&ngc).unwrap_or_default();
            if !is_subroutine_file(&ngc, &src) {
                missing.push(ngc.display().to_string());
            }
            continue;
        }
        let err = Some(ngc.with_extension("err")).filter(|p| p.exists());
        let tbl = Some(ngc.with_extension("tbl")).filter(|p| p.exists());
        let var = Some(ngc.with_extension("var")).filter(|p| p.exists());
        out.push(Golden {
            ngc,
            canon,
            err,
            tbl,
            var,
        });
    }
    if missing.is_empty() {
        Ok(out)
    } else {
        Err(format!(
            "programs without a .canon (run tests/rs274/golden.sh on them): {}",
            missing.join(", ")
        ))
    }
}

/// A golden read from disk, with the settings Kerf runs it with.
#[derive(Clone, Debug)]
pub struct LoadedGolden {
    /// The program.
    pub src: Vec<u8>,
    /// rs274's standard output.
    pub canon: String,
    /// rs274's refusal.
    pub refusal: Option<Refusal>,
    /// The tool table, the parameters and the program's directory as the subroutine path.
    pub settings: Settings,
}

/// Reads a golden's files.
pub fn load_golden(g: &Golden) -> Result<LoadedGolden, String> {
    let read = |p: &Path| std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()));
    let src = std::fs::read(&g.ngc).map_err(|e| format!("{}: {e}", g.ngc.display()))?;
    let canon = read(&g.canon)?;
    let refusal = match &g.err {
        Some(p) => Some(
            Refusal::from_err_file(&read(p)?)
                .ok_or_else(|| format!("{}: not an `exit N` file", p.display()))?,
        ),
        None => None,
    };
    let tools = match &g.tbl {
        Some(p) => parse_tool_table(&read(p)?)?,
        None => Vec::new(),
    };
    let mut settings = program_settings(tools, &g.ngc);
    settings.block_delete = asks_block_delete(&src);
    if let Some(p) = &g.var {
        apply_var_file(&read(p)?, &mut settings).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    Ok(LoadedGolden {
        src,
        canon,
        refusal,
        settings,
    })
}

/// Runs one golden through Kerf and compares it with its committed canon output.
pub fn check_golden(g: &Golden) -> Result<Verdict, String> {
    let l = load_golden(g)?;
    let kerf = run_kerf_with(&l.src, l.settings);
    Ok(compare(&l.src, &kerf, &l.canon, l.refusal.as_ref()))
}
