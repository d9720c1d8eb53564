//! Shared helpers for the workspace tests.
//!
//! The helpers run a program through the G-code front end and compare what comes out with
//! geometry computed independently in the tests (by hand from the control manuals). They
//! deliberately know nothing of how `kerf-gcode` works inside: they only use its public
//! iterator of items and the canonical types of `kerf-geom`.
//!
//! Comparisons use an absolute tolerance of [`TOL`] (1e-9 mm or rad) unless a test asks for
//! another one, because every expected value is an exact decimal or a closed-form
//! expression evaluated in `f64`.
#![deny(missing_docs)]

pub mod canon;
pub mod rs274;

use std::fmt::Write as _;
use std::path::{Path as FsPath, PathBuf};

pub use kerf_gcode::{
    Arc, CornerMode, Diagnostic, Dialect, Event, EventCode, Interpreter, Item, Line, Move, Path,
    Settings, Tool, Vec3,
};

/// Default comparison tolerance: 1e-9 mm for lengths, 1e-9 rad for angles.
pub const TOL: f64 = 1e-9;

/// One inch in millimetres, exact by definition.
pub const INCH_MM: f64 = 25.4;

/// Unit normal of the G17 (XY) plane.
pub fn axis_g17() -> Vec3 {
    Vec3::new(0.0, 0.0, 1.0)
}

/// Unit normal of the G18 (ZX) plane.
pub fn axis_g18() -> Vec3 {
    Vec3::new(0.0, 1.0, 0.0)
}

/// Unit normal of the G19 (YZ) plane.
pub fn axis_g19() -> Vec3 {
    Vec3::new(1.0, 0.0, 0.0)
}

/// Shorthand for a point.
pub fn v(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Degrees to radians.
pub fn deg(angle_deg: f64) -> f64 {
    angle_deg.to_radians()
}

/// Everything the interpreter yields for one program: the items before the first error, the
/// error if there was one.
#[derive(Debug)]
pub struct Outcome {
    /// Items yielded before the first error (or all of them).
    pub items: Vec<Item>,
    /// The first error, if any.
    pub error: Option<Diagnostic>,
}

/// Upper bound on the number of items a program of `len` bytes may yield. Every item needs at
/// least one word of two bytes, except the moves and events of a LinuxCNC canned cycle: one
/// block of three bytes or more (`X1` and a line end, in cycle mode) may give up to
/// [`MAX_CYCLE_ITEMS`] of them. A larger count means the interpreter is looping.
pub fn item_bound(len: usize) -> usize {
    2 * len + 16 + MAX_CYCLE_ITEMS * len.div_ceil(3)
}

/// The most items one LinuxCNC canned-cycle block may give (L repeats and pecks together);
/// more is the interpreter's error.
pub const MAX_CYCLE_ITEMS: usize = 100_000;

/// Runs `src` in `dialect` with `settings` and collects every item up to and including the
/// first error.
///
/// It also checks the iterator contract that does not depend on the program: after the first
/// error the iterator is finished (it returns `None`, also when asked again), and it never
/// yields more items than [`item_bound`] allows (so a looping interpreter fails instead of
/// hanging the test).
pub fn run_bytes(dialect: Dialect, settings: Settings, src: &[u8]) -> Outcome {
    run_reader(dialect, settings, src, src.len())
}

/// Like [`run_bytes`] but reads through any `BufRead` (for example a reader with a tiny
/// buffer); `len` is the program size in bytes, for the item bound.
pub fn run_reader<R: std::io::BufRead>(
    dialect: Dialect,
    settings: Settings,
    reader: R,
    len: usize,
) -> Outcome {
    let mut interp = Interpreter::new(reader, dialect, settings);
    let mut items = Vec::new();
    let mut error = None;
    let bound = item_bound(len);
    for next in interp.by_ref() {
        match next {
            Ok(item) => {
                items.push(item);
                assert!(
                    items.len() <= bound,
                    "interpreter yielded more than {bound} items for {len} bytes: it does not terminate"
                );
            }
            Err(diag) => {
                error = Some(diag);
                break;
            }
        }
    }
    if error.is_some() {
        for _ in 0..3 {
            assert!(
                interp.next().is_none(),
                "the iterator must be finished after the first error"
            );
        }
    }
    Outcome { items, error }
}

/// Runs a program with default settings; `Err` carries the first diagnostic.
pub fn run(dialect: Dialect, src: &str) -> Result<Vec<Item>, Diagnostic> {
    run_with(dialect, Settings::default(), src)
}

/// A LinuxCNC program must end with M2/M30 (or its closing `%`): rs274 refuses a file that
/// ends without ("File ended with no percent sign or program end"), and so does Kerf. The
/// programs of the tests are mostly fragments, so [`run_with`] and the helpers built on it
/// end a LinuxCNC program with an `M2` line of its own (after the program's own end it is
/// never read) and leave the `M2` event of that line out of the items. [`run_bytes`] runs
/// the program exactly as given.
pub fn with_program_end(dialect: Dialect, src: &str) -> std::borrow::Cow<'_, str> {
    if dialect != Dialect::LinuxCnc {
        return std::borrow::Cow::Borrowed(src);
    }
    let sep = if src.is_empty() || src.ends_with('\n') {
        ""
    } else {
        "\n"
    };
    std::borrow::Cow::Owned(format!("{src}{sep}M2\n"))
}

/// Runs a program with the given settings; `Err` carries the first diagnostic. A LinuxCNC
/// program is ended with M2 ([`with_program_end`]).
pub fn run_with(dialect: Dialect, settings: Settings, src: &str) -> Result<Vec<Item>, Diagnostic> {
    let ended = with_program_end(dialect, src);
    let mut out = run_bytes(dialect, settings, ended.as_bytes());
    if ended.len() != src.len() {
        // The M2 event of the added line is not the program's.
        let added_line = u32::try_from(ended.lines().count()).unwrap_or(u32::MAX);
        if let Some(Item::Event(e)) = out.items.last()
            && e.code == EventCode::M2
            && e.line == added_line
        {
            out.items.pop();
        }
    }
    match out.error {
        Some(e) => Err(e),
        None => Ok(out.items),
    }
}

/// Runs a program that must be accepted and returns its moves (events dropped).
pub fn moves(dialect: Dialect, src: &str) -> Vec<Move> {
    moves_with(dialect, Settings::default(), src)
}

/// Runs a program that must be accepted with the given settings and returns its moves.
pub fn moves_with(dialect: Dialect, settings: Settings, src: &str) -> Vec<Move> {
    match run_with(dialect, settings, src) {
        Ok(items) => only_moves(&items),
        Err(e) => panic!(
            "{} program rejected: {e}\n--- program ---\n{src}",
            dialect.name()
        ),
    }
}

/// Runs a program that must be accepted and returns all its items.
pub fn items(dialect: Dialect, src: &str) -> Vec<Item> {
    match run(dialect, src) {
        Ok(items) => items,
        Err(e) => panic!(
            "{} program rejected: {e}\n--- program ---\n{src}",
            dialect.name()
        ),
    }
}

/// Runs a program that must be rejected and returns the diagnostic.
pub fn error(dialect: Dialect, src: &str) -> Diagnostic {
    error_with(dialect, Settings::default(), src)
}

/// Runs a program that must be rejected with the given settings and returns the diagnostic.
pub fn error_with(dialect: Dialect, settings: Settings, src: &str) -> Diagnostic {
    match run_with(dialect, settings, src) {
        Ok(items) => panic!(
            "{} program accepted but must be rejected; it gave {} items:\n{}\n--- program ---\n{src}",
            dialect.name(),
            items.len(),
            describe_items(&items)
        ),
        Err(e) => e,
    }
}

/// Asserts that a diagnostic is at `line:col` and that its message contains every one of
/// `fragments` (case-insensitive).
pub fn assert_diag(d: &Diagnostic, line: u32, col: u32, fragments: &[&str]) {
    let msg = d.message.to_lowercase();
    let missing: Vec<&&str> = fragments
        .iter()
        .filter(|f| !msg.contains(&f.to_lowercase()))
        .collect();
    assert!(
        d.line == line && d.col == col && missing.is_empty(),
        "expected {line}:{col} with {fragments:?}, got {}:{}: {:?} (missing {missing:?})",
        d.line,
        d.col,
        d.message
    );
}

/// Asserts that a diagnostic's message contains every fragment (case-insensitive) and is on
/// `line`, whatever the column.
pub fn assert_diag_line(d: &Diagnostic, line: u32, fragments: &[&str]) {
    let msg = d.message.to_lowercase();
    let missing: Vec<&&str> = fragments
        .iter()
        .filter(|f| !msg.contains(&f.to_lowercase()))
        .collect();
    assert!(
        d.line == line && missing.is_empty(),
        "expected line {line} with {fragments:?}, got {}:{}: {:?} (missing {missing:?})",
        d.line,
        d.col,
        d.message
    );
}

/// The moves among `items`, in order.
pub fn only_moves(items: &[Item]) -> Vec<Move> {
    items
        .iter()
        .filter_map(|i| match i {
            Item::Move(m) => Some(*m),
            Item::Event(_) => None,
        })
        .collect()
}

/// The events among `items`, in order.
pub fn only_events(items: &[Item]) -> Vec<Event> {
    items
        .iter()
        .filter_map(|i| match i {
            Item::Event(e) => Some(e.clone()),
            Item::Move(_) => None,
        })
        .collect()
}

/// Source line of an item.
pub fn item_line(item: &Item) -> u32 {
    match item {
        Item::Move(m) => m.line,
        Item::Event(e) => e.line,
    }
}

/// A readable listing of items for failure messages.
pub fn describe_items(items: &[Item]) -> String {
    let mut s = String::new();
    for item in items {
        match item {
            Item::Move(m) => {
                let _ = writeln!(s, "  {}", describe_move(m));
            }
            Item::Event(e) => {
                let _ = writeln!(
                    s,
                    "  line {} event {} {:?}",
                    e.line,
                    e.code.as_str(),
                    e.value
                );
            }
        }
    }
    s
}

/// A readable one-line description of a move.
pub fn describe_move(m: &Move) -> String {
    match m.path {
        Path::Line(l) => format!(
            "line {} {} {:?} -> {:?} feed {:?} abc {:?}",
            m.line,
            if m.rapid { "rapid" } else { "line" },
            l.start.as_slice(),
            l.end.as_slice(),
            m.feed_mm_min,
            m.abc_deg
        ),
        Path::Arc(a) => format!(
            "line {} arc {:?} -> {:?} centre {:?} axis {:?} sweep {} rad ({} deg) feed {:?} abc {:?}",
            m.line,
            a.start.as_slice(),
            a.end.as_slice(),
            a.center.as_slice(),
            a.axis.as_slice(),
            a.sweep_rad,
            a.sweep_rad.to_degrees(),
            m.feed_mm_min,
            m.abc_deg
        ),
    }
}

/// Asserts two points are equal within `tol` in every coordinate.
pub fn assert_point(what: &str, got: Vec3, want: Vec3, tol: f64) {
    let ok = (got - want).iter().all(|d| d.abs() <= tol);
    assert!(
        ok,
        "{what}: got {:?}, want {:?} (tolerance {tol})",
        got.as_slice(),
        want.as_slice()
    );
}

/// Asserts two scalars are equal within `tol`.
pub fn assert_close(what: &str, got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol,
        "{what}: got {got}, want {want} (tolerance {tol}, off by {})",
        got - want
    );
}

/// The line of a move, or a panic naming the move.
pub fn as_line(m: &Move) -> Line {
    match m.path {
        Path::Line(l) => l,
        Path::Arc(_) => panic!("expected a line, got {}", describe_move(m)),
    }
}

/// The arc of a move, or a panic naming the move.
pub fn as_arc(m: &Move) -> Arc {
    match m.path {
        Path::Arc(a) => a,
        Path::Line(_) => panic!("expected an arc, got {}", describe_move(m)),
    }
}

/// Asserts a feed move along a straight line.
pub fn assert_feed_line(m: &Move, start: Vec3, end: Vec3, feed_mm_min: f64) {
    let l = as_line(m);
    let ctx = describe_move(m);
    assert!(!m.rapid, "expected a feed move, got a rapid: {ctx}");
    assert_point(&format!("start of {ctx}"), l.start, start, TOL);
    assert_point(&format!("end of {ctx}"), l.end, end, TOL);
    match m.feed_mm_min {
        Some(f) => assert_close(
            &format!("feed of {ctx}"),
            f,
            feed_mm_min,
            1e-9 * feed_mm_min.max(1.0),
        ),
        None => panic!("feed move without a feed: {ctx}"),
    }
}

/// Asserts a rapid along a straight line.
pub fn assert_rapid(m: &Move, start: Vec3, end: Vec3) {
    let l = as_line(m);
    let ctx = describe_move(m);
    assert!(m.rapid, "expected a rapid: {ctx}");
    assert!(m.feed_mm_min.is_none(), "a rapid has no feed: {ctx}");
    assert_point(&format!("start of {ctx}"), l.start, start, TOL);
    assert_point(&format!("end of {ctx}"), l.end, end, TOL);
}

/// Asserts an arc move exactly: start, end, centre, axis and signed sweep, and checks its
/// geometry is self-consistent (see [`check_arc_geometry`]).
pub fn assert_arc(m: &Move, start: Vec3, end: Vec3, center: Vec3, axis: Vec3, sweep_rad: f64) {
    let a = as_arc(m);
    let ctx = describe_move(m);
    assert!(!m.rapid, "an arc is never a rapid: {ctx}");
    assert_point(&format!("start of {ctx}"), a.start, start, TOL);
    assert_point(&format!("end of {ctx}"), a.end, end, TOL);
    assert_point(&format!("centre of {ctx}"), a.center, center, TOL);
    assert_point(&format!("axis of {ctx}"), a.axis, axis, TOL);
    assert_close(&format!("sweep of {ctx}"), a.sweep_rad, sweep_rad, TOL);
    check_arc_geometry(&a, TOL);
}

/// Splits `p - center` into its component along `axis` and its in-plane part.
fn plane_parts(p: Vec3, center: Vec3, axis: Vec3) -> (f64, Vec3) {
    let d = p - center;
    let along = d.dot(&axis);
    (along, d - axis * along)
}

/// Checks that an arc is a well-formed circle or helix, independently of how it was
/// computed:
/// - `axis` is a unit vector along X, Y or Z (arcs are only programmed in G17/G18/G19);
/// - the centre lies in the plane of the start point;
/// - the in-plane distances from the centre to start and end are equal (a circle, not a
///   spiral) and not zero;
/// - the signed in-plane angle from start to end, by the right-hand rule about `axis`,
///   agrees with `sweep_rad` modulo a whole turn.
pub fn check_arc_geometry(a: &Arc, tol: f64) {
    let ctx = format!("{a:?}");
    let n = a.axis.norm();
    assert_close(&format!("|axis| of {ctx}"), n, 1.0, 1e-12);
    let axis_count = a
        .axis
        .iter()
        .filter(|c| (c.abs() - 1.0).abs() < 1e-12)
        .count();
    assert_eq!(axis_count, 1, "axis must be ±X, ±Y or ±Z: {ctx}");
    let (s_along, s_in) = plane_parts(a.start, a.center, a.axis);
    let (_, e_in) = plane_parts(a.end, a.center, a.axis);
    assert_close(
        &format!("centre in the plane of the start for {ctx}"),
        s_along,
        0.0,
        tol,
    );
    let r1 = s_in.norm();
    let r2 = e_in.norm();
    assert!(r1 > tol, "zero-radius arc: {ctx}");
    assert_close(
        &format!("radius to end vs radius to start for {ctx}"),
        r2,
        r1,
        tol.max(r1 * 1e-12),
    );
    assert!(
        a.sweep_rad.is_finite() && a.sweep_rad != 0.0,
        "sweep must be finite and non-zero: {ctx}"
    );
    let chord_angle = signed_angle(s_in, e_in, a.axis);
    let diff = (a.sweep_rad - chord_angle).rem_euclid(std::f64::consts::TAU);
    let diff = diff.min(std::f64::consts::TAU - diff);
    // The angular tolerance scales with 1/r: a 1e-9 mm displacement of the end point on a
    // small circle changes its angle by more than 1e-9 rad.
    assert!(
        diff <= tol / r1 * 10.0 + 1e-12,
        "sweep {} does not reach the end point (chord angle {chord_angle}): {ctx}",
        a.sweep_rad
    );
}

/// Signed angle from `from` to `to` about `axis` by the right-hand rule, in (-π, π].
pub fn signed_angle(from: Vec3, to: Vec3, axis: Vec3) -> f64 {
    let cross = from.cross(&to).dot(&axis);
    let dot = from.dot(&to);
    cross.atan2(dot)
}

/// Point at fraction `t` in [0, 1] of an arc or helix: rotated by `t · sweep` about the axis
/// through the centre, displaced along the axis by `t` of the start-to-end axial distance.
pub fn arc_point(a: &Arc, t: f64) -> Vec3 {
    let (_, s_in) = plane_parts(a.start, a.center, a.axis);
    let (e_along, _) = plane_parts(a.end, a.center, a.axis);
    let angle = a.sweep_rad * t;
    // Rodrigues rotation of the in-plane radius vector about the unit axis.
    let rotated = s_in * angle.cos() + a.axis.cross(&s_in) * angle.sin();
    a.center + rotated + a.axis * (e_along * t)
}

/// Length of a path, for cross-checks.
pub fn path_length(p: &Path) -> f64 {
    match p {
        Path::Line(l) => (l.end - l.start).norm(),
        Path::Arc(a) => {
            let (_, s_in) = plane_parts(a.start, a.center, a.axis);
            let (e_along, _) = plane_parts(a.end, a.center, a.axis);
            let planar = s_in.norm() * a.sweep_rad.abs();
            (planar * planar + e_along * e_along).sqrt()
        }
    }
}

/// Asserts that each move starts where the previous one ended, and the first starts at
/// `origin`.
pub fn assert_continuous(ms: &[Move], origin: Vec3) {
    let mut at = origin;
    for m in ms {
        assert_point(
            &format!("start of {} (continuity)", describe_move(m)),
            m.path.start(),
            at,
            TOL,
        );
        at = m.path.end();
    }
}

/// Compares two move lists geometrically within `tol`: same kind (line or arc), same rapid
/// flag, same start, end, centre, axis, sweep and feed. Source lines are not compared (the
/// same part has a different layout in each dialect). Every difference is reported.
pub fn assert_same_moves(what: &str, got: &[Move], want: &[Move], tol: f64) {
    let mut errors = Vec::new();
    if got.len() != want.len() {
        errors.push(format!("{} moves, want {}", got.len(), want.len()));
    }
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        if let Some(e) = move_difference(g, w, tol) {
            errors.push(format!(
                "move {i}: {e}\n    got  {}\n    want {}",
                describe_move(g),
                describe_move(w)
            ));
        }
    }
    assert!(errors.is_empty(), "{what}:\n{}", errors.join("\n"));
}

fn close_pt(a: Vec3, b: Vec3, tol: f64) -> bool {
    (a - b).iter().all(|d| d.abs() <= tol)
}

fn move_difference(g: &Move, w: &Move, tol: f64) -> Option<String> {
    if g.rapid != w.rapid {
        return Some("rapid flag differs".into());
    }
    match (g.feed_mm_min, w.feed_mm_min) {
        (None, None) => {}
        (Some(a), Some(b)) if (a - b).abs() <= tol * b.abs().max(1.0) => {}
        _ => return Some("feed differs".into()),
    }
    match (g.abc_deg, w.abc_deg) {
        (None, None) => {}
        (Some((gs, ge)), Some((ws, we))) => {
            let all = gs.iter().chain(&ge).zip(ws.iter().chain(&we));
            if all.into_iter().any(|(a, b)| (a - b).abs() > tol) {
                return Some("rotary axes differ".into());
            }
        }
        _ => return Some("rotary axes present in one only".into()),
    }
    match (g.path, w.path) {
        (Path::Line(a), Path::Line(b)) => {
            if !close_pt(a.start, b.start, tol) || !close_pt(a.end, b.end, tol) {
                return Some("line end points differ".into());
            }
        }
        (Path::Arc(a), Path::Arc(b)) => {
            if !close_pt(a.start, b.start, tol)
                || !close_pt(a.end, b.end, tol)
                || !close_pt(a.center, b.center, tol)
                || !close_pt(a.axis, b.axis, tol)
                || (a.sweep_rad - b.sweep_rad).abs() > tol
            {
                return Some("arc geometry differs".into());
            }
        }
        _ => return Some("one is a line, the other an arc".into()),
    }
    None
}

/// The workspace's `tests/data` directory.
pub fn data_dir() -> PathBuf {
    FsPath::new(env!("CARGO_MANIFEST_DIR")).join("data")
}

/// File extension used for the fixture programs of a dialect.
pub fn extension(dialect: Dialect) -> &'static str {
    match dialect {
        Dialect::LinuxCnc => "ngc",
        Dialect::Rockwell => "nc",
        Dialect::Sinumerik => "mpf",
        Dialect::Heidenhain => "h",
        Dialect::Fagor => "pim",
    }
}

/// Every file with the given extension under `dir`, sorted by name.
pub fn files_with_ext(dir: &FsPath, ext: &str) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == ext))
            .collect(),
        Err(_) => Vec::new(),
    };
    out.sort();
    out
}

/// Settings with one tool in the table.
pub fn settings_with_tool(number: u32, length_mm: f64, radius_mm: f64) -> Settings {
    Settings {
        tools: vec![Tool {
            number,
            length_mm,
            radius_mm,
            ..Tool::default()
        }],
        ..Settings::default()
    }
}
