//! The LinuxCNC language layer: parameters, expressions, messages and O-word control flow.
//!
//! A LinuxCNC line that holds `#`, `[`, an O-word or a message comment comes here instead
//! of the plain lexer (lines without them keep the fast path). The line is normalized as
//! LinuxCNC reads it (spaces and tabs removed, letters lower case, comments kept), its
//! values are read (every value of the line before any of its assignments takes effect),
//! and its words go to the same block resolution as a plain line.
//!
//! Control flow keeps the source text of the structures it runs: a `sub` … `endsub`, or a
//! top-level `if`/`while`/`do`/`repeat` up to its end line, is collected into a [`Body`]
//! (bounded by the program's text of those bodies, never by iterations) and run from
//! memory by a stack of [`Frame`]s; lines outside them stream from the reader as before.

use std::collections::HashMap;
use std::sync::Arc;

use crate::interp::State;
use crate::interp::params;
use crate::lex::{Form, K_AT, K_CARET, Word};
use crate::{Event, EventCode, Item};

pub(crate) mod expr;

/// LinuxCNC's deepest subroutine nesting: a call from level 9 is "Too many subroutine
/// levels" (rs274 runs nine nested calls, `#<_call_level>` 1 to 9).
pub(crate) const MAX_CALL_LEVELS: usize = 9;

/// The most lines one collected body (a subroutine or a top-level loop) may hold: beyond
/// it the program is refused, which keeps memory bounded on any input.
pub(crate) const MAX_BODY_LINES: usize = 1_000_000;

/// The most named parameters a program may create (memory stays bounded).
const MAX_NAMED: usize = 100_000;

pub(crate) use crate::lex::BlockError;

pub(crate) fn fail<T>(col: u32, message: impl Into<String>) -> Result<T, BlockError> {
    Err(BlockError {
        col,
        message: message.into(),
    })
}

/// True when a LinuxCNC line needs the language layer: a parameter, an expression, an
/// O-word, or a comment that is a message (MSG, DEBUG, PRINT, LOG…).
pub(crate) fn needs_language(line: &[u8]) -> bool {
    let mut i = 0;
    while i < line.len() {
        match line[i] {
            b'#' | b'[' | b'o' | b'O' => return true,
            b';' => return false,
            b'(' => {
                let rest = &line[i + 1..];
                let start = rest
                    .iter()
                    .position(|&b| b != b' ' && b != b'\t')
                    .unwrap_or(rest.len());
                let rest = &rest[start..];
                for key in [&b"msg,"[..], b"debug,", b"print,", b"log"] {
                    if rest.len() >= key.len() && rest[..key.len()].eq_ignore_ascii_case(key) {
                        return true;
                    }
                }
                match rest.iter().position(|&b| b == b')') {
                    Some(off) => i += 1 + start + off,
                    None => return false,
                }
            }
            _ => {}
        }
        i += 1;
    }
    false
}

/// The O-word keywords.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kw {
    Sub,
    EndSub,
    Call,
    Return,
    If,
    ElseIf,
    Else,
    EndIf,
    While,
    EndWhile,
    Do,
    Repeat,
    EndRepeat,
    Break,
    Continue,
}

const KEYWORDS: [(&[u8], Kw); 15] = [
    (b"endsub", Kw::EndSub),
    (b"endif", Kw::EndIf),
    (b"endwhile", Kw::EndWhile),
    (b"endrepeat", Kw::EndRepeat),
    (b"elseif", Kw::ElseIf),
    (b"else", Kw::Else),
    (b"sub", Kw::Sub),
    (b"call", Kw::Call),
    (b"return", Kw::Return),
    (b"if", Kw::If),
    (b"while", Kw::While),
    (b"do", Kw::Do),
    (b"repeat", Kw::Repeat),
    (b"break", Kw::Break),
    (b"continue", Kw::Continue),
];

/// One source line kept in memory, with its O-word (label and keyword) if it has one.
pub(crate) struct SrcLine {
    text: Box<[u8]>,
    line: u32,
    head: Option<(Arc<str>, Kw)>,
}

/// Collected source lines: a subroutine (from its `sub` line to its `endsub`) or a
/// top-level control structure.
pub(crate) struct Body {
    lines: Vec<SrcLine>,
    /// The subroutine file the lines come from (`None`: the program itself).
    file: Option<Arc<str>>,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum LoopKind {
    While,
    Do,
    Repeat,
}

struct LoopState {
    label: Arc<str>,
    kind: LoopKind,
    /// Index of the loop's first line (`while`, `do` or `repeat`).
    start: usize,
    remaining: f64,
    iterations: u64,
}

struct Call {
    saved: [f64; 30],
    /// Where the call was made: file and line.
    from_file: Option<Arc<str>>,
    from_line: u32,
}

struct Frame {
    body: Arc<Body>,
    /// The next line to run.
    pc: usize,
    call: Option<Call>,
    loops: Vec<LoopState>,
}

struct Capture {
    label: Arc<str>,
    kind: Kw,
    lines: Vec<SrcLine>,
}

enum Target {
    Numbered(usize),
    Named(String),
}

enum MsgKind {
    Msg,
    Debug,
    Print,
    /// `LOGOPEN`, `LOGAPPEND`, `LOG` (substituted) or `LOGCLOSE`: the event text's prefix.
    Log(&'static str),
}

/// What the caller does with a line after [`Ngc::line`].
pub(crate) enum Action {
    /// Nothing to execute (control flow, a definition, a comment).
    Nothing,
    /// Execute the words put into the word buffer, after [`Ngc::commit`].
    Block,
    /// Let the plain path handle the line (a `%` line).
    Plain,
}

/// The state of the LinuxCNC language layer of one program.
pub(crate) struct Ngc {
    norm: Vec<u8>,
    cols: Vec<u32>,
    globals: HashMap<String, f64>,
    /// Named local parameters, one map per call level (level 0 is the main program).
    locals: Vec<HashMap<String, f64>>,
    subs: HashMap<Arc<str>, Arc<Body>>,
    frames: Vec<Frame>,
    capture: Option<Capture>,
    /// The current line came from a frame (not from the reader).
    from_frame: bool,
    /// The file and line numbers of the current line (set by `next_line`).
    cur_file: Option<Arc<str>>,
    value: f64,
    value_returned: bool,
    assignments: Vec<(Target, f64, u32)>,
    messages: Vec<(MsgKind, String)>,
    /// Directories searched for `NAME.ngc` (the program's own directory first).
    search_path: Vec<std::path::PathBuf>,
    max_loop_iterations: u64,
    /// The program's file, searched for subs called before their definition.
    program_file: Option<std::path::PathBuf>,
    /// Subs found later in the program's file by a call before their definition:
    /// reaching their definition afterwards is LinuxCNC's "found in illegal location".
    forward: std::collections::HashSet<Arc<str>>,
    /// The events of the modal state M73 restores at an `endsub`/`return` (taken by
    /// `take_restored` after the line).
    restored: Vec<Item>,
}

impl Ngc {
    pub(crate) fn new(
        search_path: Vec<std::path::PathBuf>,
        max_loop_iterations: u64,
        program_file: Option<std::path::PathBuf>,
    ) -> Self {
        Ngc {
            norm: Vec::new(),
            cols: Vec::new(),
            globals: HashMap::new(),
            locals: vec![HashMap::new()],
            subs: HashMap::new(),
            frames: Vec::new(),
            capture: None,
            from_frame: false,
            cur_file: None,
            value: 0.0,
            value_returned: false,
            assignments: Vec::new(),
            messages: Vec::new(),
            search_path,
            max_loop_iterations,
            program_file,
            forward: std::collections::HashSet::new(),
            restored: Vec::new(),
        }
    }

    /// Moves the events of an M73 restore made by the last line (at its `endsub` or
    /// `return`) to `items`.
    pub(crate) fn take_restored(&mut self, items: &mut Vec<Item>) {
        items.append(&mut self.restored);
    }

    /// True while lines must come here whatever they hold: a structure is being collected.
    pub(crate) fn busy(&self) -> bool {
        self.capture.is_some() || self.from_frame
    }

    /// The file of the current line (`None`: the program).
    pub(crate) fn current_file(&self) -> Option<Arc<str>> {
        self.cur_file.clone()
    }

    /// The calls that led to the current line, innermost first: (file, line) of each call.
    pub(crate) fn call_chain(&self) -> Vec<(Option<Arc<str>>, u32)> {
        self.frames
            .iter()
            .rev()
            .filter_map(|f| f.call.as_ref())
            .map(|c| (c.from_file.clone(), c.from_line))
            .collect()
    }

    /// An unfinished structure at the end of the input.
    pub(crate) fn unfinished(&self) -> Option<(u32, String)> {
        self.capture.as_ref().map(|c| {
            let line = c.lines.first().map_or(1, |l| l.line);
            (
                line,
                format!(
                    "{} {} without its end at the end of the program",
                    label_name(&c.label),
                    kw_name(c.kind)
                ),
            )
        })
    }

    /// The next line from memory into `out`, with its line number; `None` when the lines
    /// come from the reader.
    pub(crate) fn next_line(&mut self, out: &mut Vec<u8>) -> Option<u32> {
        loop {
            let Some(frame) = self.frames.last_mut() else {
                self.from_frame = false;
                self.cur_file = None;
                return None;
            };
            if let Some(src) = frame.body.lines.get(frame.pc) {
                frame.pc += 1;
                out.clear();
                out.extend_from_slice(&src.text);
                self.from_frame = true;
                self.cur_file = frame.body.file.clone();
                return Some(src.line);
            }
            // A top-level structure ran to its end (a sub body always ends in endsub,
            // which returns before this).
            self.frames.pop();
        }
    }
}

/// The display form of a label: `o100` or `o<name>`.
fn label_name(label: &str) -> String {
    if label.starts_with(|c: char| c.is_ascii_digit()) {
        format!("o{label}")
    } else {
        format!("o<{label}>")
    }
}

fn kw_name(kw: Kw) -> &'static str {
    KEYWORDS
        .iter()
        .find(|(_, k)| *k == kw)
        .and_then(|(t, _)| std::str::from_utf8(t).ok())
        .unwrap_or("?")
}

/// Normalizes a line as LinuxCNC reads it: spaces and tabs outside comments removed,
/// letters lower case outside comments, a `;` comment dropped; `cols` maps each kept byte
/// to its 1-based source column.
fn normalize(line: &[u8], norm: &mut Vec<u8>, cols: &mut Vec<u32>) -> Result<(), BlockError> {
    norm.clear();
    cols.clear();
    let mut i = 0;
    while i < line.len() {
        let c = line[i];
        match c {
            b' ' | b'\t' | b'\r' => {}
            b';' => break,
            b'(' => {
                let Some(off) = line[i..].iter().position(|&b| b == b')') else {
                    return fail(crate::lex::col_of(i), "Unclosed comment found");
                };
                for (k, &b) in line[i..=i + off].iter().enumerate() {
                    norm.push(b);
                    cols.push(crate::lex::col_of(i + k));
                }
                i += off;
            }
            _ => {
                norm.push(c.to_ascii_lowercase());
                cols.push(crate::lex::col_of(i));
            }
        }
        i += 1;
    }
    Ok(())
}

/// The O-word of a normalized line: label, keyword and the offset after the keyword.
/// `Ok(None)` when the line holds no O-word. Leading `N` words and a block delete are
/// skipped.
fn o_head(norm: &[u8], cols: &[u32]) -> Result<Option<(Arc<str>, Kw, usize)>, BlockError> {
    let mut i = 0;
    if norm.first() == Some(&b'/') {
        return Ok(None);
    }
    if norm.first() == Some(&b'n') {
        i = 1;
        while norm
            .get(i)
            .is_some_and(|c| c.is_ascii_digit() || *c == b'.')
        {
            i += 1;
        }
    }
    if norm.get(i) != Some(&b'o') {
        return Ok(None);
    }
    let col = cols.get(i).copied().unwrap_or(1);
    i += 1;
    let label: String = match norm.get(i) {
        Some(b'<') => {
            let start = i + 1;
            let Some(off) = norm[start..].iter().position(|&b| b == b'>') else {
                return fail(col, "Named parameter not terminated");
            };
            i = start + off + 1;
            if off == 0 {
                return fail(col, "Bad O-word label");
            }
            String::from_utf8_lossy(&norm[start..start + off]).into_owned()
        }
        Some(c) if c.is_ascii_digit() => {
            let start = i;
            while norm.get(i).is_some_and(|c| c.is_ascii_digit()) {
                i += 1;
            }
            let digits = &norm[start..i];
            let trimmed: &[u8] = match digits.iter().position(|&b| b != b'0') {
                Some(p) => &digits[p..],
                None => b"0",
            };
            if trimmed.len() > 18 {
                return fail(col, "O-word number too large");
            }
            String::from_utf8_lossy(trimmed).into_owned()
        }
        Some(b'[') => {
            // A computed label (`o[#1] call`): kept as written and evaluated when the line
            // runs (in `Ngc::line`).
            let start = i;
            let closed;
            (i, closed) = skip_brackets(norm, i);
            if !closed {
                return fail(col, "Unclosed expression");
            }
            String::from_utf8_lossy(&norm[start..i]).into_owned()
        }
        _ => return fail(col, "Bad O-word label"),
    };
    for (text, kw) in KEYWORDS {
        if norm.get(i..).is_some_and(|r| r.starts_with(text)) {
            return Ok(Some((Arc::from(label), kw, i + text.len())));
        }
    }
    fail(
        cols.get(i).copied().unwrap_or(col),
        "Unknown command in O-word",
    )
}

/// From the `[` at `i`, the index after its matching `]`, and whether it was found (the
/// end of the line otherwise).
fn skip_brackets(norm: &[u8], mut i: usize) -> (usize, bool) {
    let mut depth = 0usize;
    while let Some(&c) = norm.get(i) {
        i += 1;
        match c {
            b'[' => depth += 1,
            b']' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return (i, true);
                }
            }
            _ => {}
        }
    }
    (i, false)
}

/// Checks what follows an O-word's keyword: its bracketed values (none for most keywords,
/// one for `if`/`elseif`/`while`/`repeat`/`return`/`endsub`, any number for `call`), then
/// only comments. Anything else is LinuxCNC's "Unexpected character after O-word": an
/// O-word line runs nothing else, so nothing may be silently dropped.
fn check_o_tail(norm: &[u8], cols: &[u32], after: usize, kw: Kw) -> Result<(), BlockError> {
    let max_groups = match kw {
        Kw::Call => usize::MAX,
        Kw::If | Kw::ElseIf | Kw::While | Kw::Repeat | Kw::Return | Kw::EndSub => 1,
        _ => 0,
    };
    let mut i = after;
    let mut groups = 0;
    while groups < max_groups && norm.get(i) == Some(&b'[') {
        i = skip_brackets(norm, i).0;
        groups += 1;
    }
    while let Some(&c) = norm.get(i) {
        if c != b'(' {
            let col = cols.get(i).copied().unwrap_or(1);
            return fail(col, "Unexpected character after O-word");
        }
        match norm[i..].iter().position(|&b| b == b')') {
            Some(off) => i += off + 1,
            None => break,
        }
    }
    Ok(())
}

fn make_src(text: &[u8], line: u32) -> SrcLine {
    let mut norm = Vec::new();
    let mut cols = Vec::new();
    let head = match normalize(text, &mut norm, &mut cols) {
        Ok(()) => o_head(&norm, &cols).ok().flatten().map(|(l, k, _)| (l, k)),
        Err(_) => None,
    };
    SrcLine {
        text: text.into(),
        line,
        head,
    }
}

/// The keyword that ends a structure begun by `kind`.
fn end_of(kind: Kw) -> Kw {
    match kind {
        Kw::Sub => Kw::EndSub,
        Kw::If => Kw::EndIf,
        Kw::While => Kw::EndWhile,
        Kw::Do => Kw::While,
        _ => Kw::EndRepeat,
    }
}

/// Parameter access for the expression reader.
struct Ctx<'a> {
    ngc: &'a Ngc,
    state: &'a State,
    line: u32,
    /// Named parameters assigned earlier on the line: rs274 reads one of them that was
    /// never set as 0 instead of refusing it (`#<a>=1 #<a>=[#<a>+1]` sets 1).
    assigned: std::cell::RefCell<Vec<String>>,
}

impl Ctx<'_> {
    fn predefined(&self, name: &str) -> Option<f64> {
        let s = self.state;
        let b = |c: bool| if c { 1.0 } else { 0.0 };
        let axis = |n: &str| ["x", "y", "z", "a", "b", "c"].iter().position(|a| *a == n);
        let rest = name.strip_prefix('_')?;
        if let Some(i) = axis(rest) {
            return Some(s.q_program_pos()[i]);
        }
        if let Some(i) = rest.strip_prefix("abs_").and_then(axis) {
            return Some(s.q_machine_pos()[i]);
        }
        Some(match rest {
            "u" | "v" | "w" => 0.0,
            "vmajor" => 2.9,
            "vminor" => 0.0,
            "line" => f64::from(self.line),
            "motion_mode" => s.q_motion_mode(),
            "plane" => s.q_plane(),
            "ccomp" => s.q_ccomp(),
            "metric" => b(!s.q_inch()),
            "imperial" => b(s.q_inch()),
            "absolute" => b(s.q_absolute()),
            "incremental" => b(!s.q_absolute()),
            "inverse_time" => s.q_feed_mode_inverse_time(),
            "units_per_minute" => s.q_feed_mode_per_minute(),
            "units_per_rev" => s.q_feed_mode_per_rev(),
            "coord_system" => s.q_coord_system(),
            "tool_offset" => b(s.q_tool_offset()),
            "retract_r_plane" => b(!s.q_retract_old_z()),
            "retract_old_z" => b(s.q_retract_old_z()),
            "spindle_rpm_mode" => 1.0,
            "spindle_css_mode" => 0.0,
            "ijk_absolute_mode" => b(s.q_arc_absolute()),
            // rs274 (a mill configuration) reads radius mode on and diameter mode off.
            "lathe_diameter_mode" => 0.0,
            "lathe_radius_mode" => 1.0,
            "spindle_on" => b(s.q_spindle_on()),
            "spindle_cw" => b(s.q_spindle_cw()),
            "mist" => b(s.q_mist()),
            "flood" => b(s.q_flood()),
            "speed_override" | "feed_override" => 1.0,
            "adaptive_feed" => 0.0,
            // The feed hold switch is enabled at start, as rs274 reads it.
            "feed_hold" => 1.0,
            "feed" => s.q_feed(),
            "rpm" => s.q_rpm(),
            "current_tool" => s.q_current_tool(),
            "current_pocket" => -1.0,
            "selected_tool" => s.q_selected_tool(),
            "selected_pocket" => -1.0,
            "value" => self.ngc.value,
            "value_returned" => b(self.ngc.value_returned),
            "task" => 0.0,
            "call_level" => self.ngc.call_level() as f64,
            "remap_level" => 0.0,
            _ => return None,
        })
    }
}

impl expr::Params for Ctx<'_> {
    fn numbered(&self, n: f64, col: u32) -> Result<f64, BlockError> {
        let i = param_index(n, col)?;
        if (params::CURRENT_POSITION..params::CURRENT_POSITION + 9).contains(&i) {
            let k = i - params::CURRENT_POSITION;
            return Ok(self.state.q_program_pos().get(k).copied().unwrap_or(0.0));
        }
        if i == params::TOOL_NUMBER {
            return Ok(self.state.q_current_tool());
        }
        match self.state.params.get(i) {
            Some(v) => Ok(v),
            None => fail(col, "Parameter number out of range"),
        }
    }

    fn named(&self, name: &str, col: u32) -> Result<f64, BlockError> {
        let found = if name.starts_with('_') {
            self.predefined(name)
                .or_else(|| self.ngc.globals.get(name).copied())
        } else {
            self.ngc.locals.last().and_then(|m| m.get(name).copied())
        };
        match found {
            Some(v) => Ok(v),
            None if self.assigned.borrow().iter().any(|n| n == name) => Ok(0.0),
            None => fail(col, format!("Named parameter #<{name}> not defined")),
        }
    }

    fn exists(&self, name: &str) -> bool {
        if name.starts_with('_') {
            self.predefined(name).is_some() || self.ngc.globals.contains_key(name)
        } else {
            self.ngc.locals.last().is_some_and(|m| m.contains_key(name))
        }
    }
}

/// The index of a numbered parameter: an integer (within LinuxCNC's tolerance) from 1 to
/// 5601.
fn param_index(n: f64, col: u32) -> Result<usize, BlockError> {
    let r = n.round();
    if (n - r).abs() > 0.0001 {
        return fail(col, "Non integer value for integer");
    }
    if !(1.0..params::MAX_NUMBERED as f64).contains(&r) {
        return fail(col, "Parameter number out of range");
    }
    Ok(r as usize)
}

impl Ngc {
    fn call_level(&self) -> usize {
        self.frames.iter().filter(|f| f.call.is_some()).count()
    }

    fn ctx<'a>(&'a self, state: &'a State, line: u32) -> Ctx<'a> {
        Ctx {
            ngc: self,
            state,
            line,
            assigned: std::cell::RefCell::new(Vec::new()),
        }
    }

    /// Handles one LinuxCNC line: collects it into a structure, runs its O-word, or reads
    /// its words (into `words`) and assignments and messages (kept for [`Ngc::commit`]).
    pub(crate) fn line(
        &mut self,
        text: &[u8],
        line_no: u32,
        state: &mut State,
        words: &mut Vec<Word>,
    ) -> Result<Action, BlockError> {
        words.clear();
        self.assignments.clear();
        self.messages.clear();
        let mut norm = std::mem::take(&mut self.norm);
        let mut cols = std::mem::take(&mut self.cols);
        let r = self.line_inner(text, line_no, state, words, &mut norm, &mut cols);
        self.norm = norm;
        self.cols = cols;
        r
    }

    fn line_inner(
        &mut self,
        text: &[u8],
        line_no: u32,
        state: &mut State,
        words: &mut Vec<Word>,
        norm: &mut Vec<u8>,
        cols: &mut Vec<u32>,
    ) -> Result<Action, BlockError> {
        if !self.from_frame
            && let Some(cap) = self.capture.as_mut()
        {
            let src = make_src(text, line_no);
            if cap.kind == Kw::Sub && matches!(&src.head, Some((l, Kw::Sub)) if *l != cap.label) {
                return fail(1, "Nested subroutine definition");
            }
            let end =
                matches!(&src.head, Some((l, k)) if *l == cap.label && *k == end_of(cap.kind));
            if cap.lines.len() >= MAX_BODY_LINES {
                return fail(
                    1,
                    format!(
                        "{} is longer than {MAX_BODY_LINES} lines",
                        label_name(&cap.label)
                    ),
                );
            }
            cap.lines.push(src);
            if end && let Some(cap) = self.capture.take() {
                let body = Arc::new(Body {
                    lines: cap.lines,
                    file: None,
                });
                if cap.kind == Kw::Sub {
                    self.subs.insert(cap.label, body);
                } else {
                    self.frames.push(Frame {
                        body,
                        pc: 0,
                        call: None,
                        loops: Vec::new(),
                    });
                }
            }
            return Ok(Action::Nothing);
        }
        normalize(text, norm, cols)?;
        if norm.first() == Some(&b'/') && !state.block_delete() {
            // Block delete switch off: the block runs as if the `/` were not there.
            norm.remove(0);
            cols.remove(0);
        }
        match norm.first() {
            None => return Ok(Action::Nothing),
            Some(b'/') => return Ok(Action::Nothing),
            Some(b'%') => return Ok(Action::Plain),
            _ => {}
        }
        if let Some((label, kw, after)) = o_head(norm, cols)? {
            let col = cols.iter().copied().find(|_| true).unwrap_or(1);
            let o_at = norm.iter().position(|&b| b == b'o');
            let ocol = o_at.and_then(|i| cols.get(i).copied()).unwrap_or(col);
            let label = if label.starts_with('[') {
                // `o[expr] call`: the value of the expression is the sub's number.
                if kw != Kw::Call {
                    return fail(ocol, "Bad O-word label");
                }
                let ctx = self.ctx(state, line_no);
                let mut r = expr::Reader::new(norm, cols, o_at.map_or(0, |i| i + 1));
                let v = r.real_value(&ctx)?;
                if v < 0.0 || v.fract() != 0.0 || v > 1e18 {
                    return fail(ocol, "Bad O-word label");
                }
                Arc::from(format!("{}", v as u64))
            } else {
                label
            };
            self.o_word(text, line_no, state, &label, kw, after, ocol, norm, cols)?;
            return Ok(Action::Nothing);
        }
        self.read_words(line_no, state, words, norm, cols)?;
        Ok(Action::Block)
    }

    fn read_words(
        &mut self,
        line_no: u32,
        state: &State,
        words: &mut Vec<Word>,
        norm: &[u8],
        cols: &[u32],
    ) -> Result<(), BlockError> {
        let ctx = self.ctx(state, line_no);
        let mut r = expr::Reader::new(norm, cols, 0);
        let mut assignments = Vec::new();
        let mut messages = Vec::new();
        while let Some(c) = r.peek() {
            let col = r.col();
            match c {
                b'(' => {
                    let start = r.pos + 1;
                    let end = norm[start..]
                        .iter()
                        .position(|&b| b == b')')
                        .map_or(norm.len(), |o| start + o);
                    r.pos = (end + 1).min(norm.len());
                    let body = &norm[start..end];
                    let skip = body
                        .iter()
                        .position(|&b| b != b' ' && b != b'\t')
                        .unwrap_or(body.len());
                    let body = &body[skip..];
                    let starts =
                        |k: &[u8]| body.len() >= k.len() && body[..k.len()].eq_ignore_ascii_case(k);
                    let text = |n: usize| String::from_utf8_lossy(&body[n..]).into_owned();
                    if starts(b"msg,") {
                        messages.push((MsgKind::Msg, text(4)));
                    } else if starts(b"debug,") {
                        messages.push((MsgKind::Debug, text(6)));
                    } else if starts(b"print,") {
                        messages.push((MsgKind::Print, text(6)));
                    } else if starts(b"logopen,") {
                        messages.push((MsgKind::Log("LOGOPEN"), text(8)));
                    } else if starts(b"logappend,") {
                        messages.push((MsgKind::Log("LOGAPPEND"), text(10)));
                    } else if starts(b"log,") {
                        messages.push((MsgKind::Log("LOG"), text(4)));
                    } else if body.eq_ignore_ascii_case(b"logclose") {
                        messages.push((MsgKind::Log("LOGCLOSE"), String::new()));
                    }
                }
                b'#' => {
                    r.pos += 1;
                    let target = if r.peek() == Some(b'<') {
                        let name = r.name()?;
                        if name.starts_with('_') && ctx.predefined(&name).is_some() {
                            return fail(
                                col,
                                format!("Cannot assign to read-only parameter #<{name}>"),
                            );
                        }
                        ctx.assigned.borrow_mut().push(name.clone());
                        Target::Named(name)
                    } else {
                        let n = r.real_value(&ctx)?;
                        let i = param_index(n, col)?;
                        if (params::TOOL_NUMBER..params::CURRENT_POSITION + 9).contains(&i) {
                            // #5400-#5428 (tool data, current position) are set by the
                            // interpreter only.
                            return fail(col, "Parameter is readonly");
                        }
                        Target::Numbered(i)
                    };
                    if r.peek() != Some(b'=') {
                        return fail(r.col(), "Equal sign missing in parameter setting");
                    }
                    r.pos += 1;
                    let v = r.real_value(&ctx)?;
                    assignments.push((target, v, col));
                }
                b'@' | b'^' => {
                    r.pos += 1;
                    let value = r.real_value(&ctx)?;
                    words.push(Word {
                        key: if c == b'@' { K_AT } else { K_CARET },
                        value,
                        col,
                        form: Form::Plain,
                    });
                }
                b'a'..=b'z' => {
                    r.pos += 1;
                    if c == b'o' {
                        return fail(col, "Bad character 'o' used");
                    }
                    let value = r.real_value(&ctx)?;
                    if words.len() >= 64 {
                        return fail(col, "too many words in one block");
                    }
                    if c != b'n' {
                        words.push(Word {
                            key: c.to_ascii_uppercase() - b'A',
                            value,
                            col,
                            form: Form::Plain,
                        });
                    }
                }
                _ => {
                    let shown = if c.is_ascii_graphic() {
                        (c as char).to_string()
                    } else {
                        format!("\\x{c:02x}")
                    };
                    return fail(col, format!("Bad character '{shown}' used"));
                }
            }
        }
        self.assignments = assignments;
        self.messages = messages;
        Ok(())
    }

    /// Applies the line's assignments (after all its values were read, as LinuxCNC does)
    /// and emits its messages, before the block runs.
    pub(crate) fn commit(
        &mut self,
        state: &mut State,
        items: &mut Vec<Item>,
        line_no: u32,
    ) -> Result<(), BlockError> {
        for (target, v, col) in std::mem::take(&mut self.assignments) {
            match target {
                Target::Numbered(i) => {
                    if !state.params.set(i, v) {
                        return fail(col, "Parameter number out of range");
                    }
                }
                Target::Named(name) => {
                    let map = if name.starts_with('_') {
                        &mut self.globals
                    } else {
                        let Some(m) = self.locals.last_mut() else {
                            continue;
                        };
                        m
                    };
                    if map.len() >= MAX_NAMED && !map.contains_key(&name) {
                        return fail(col, format!("more than {MAX_NAMED} named parameters"));
                    }
                    map.insert(name, v);
                }
            }
        }
        for (kind, text) in std::mem::take(&mut self.messages) {
            let (code, text) = match kind {
                MsgKind::Msg => (EventCode::Msg, text),
                MsgKind::Debug => (EventCode::Debug, self.substitute(state, &text, line_no)),
                MsgKind::Print => (EventCode::Print, self.substitute(state, &text, line_no)),
                // Kerf writes no file: the log calls are events for the control to act on.
                MsgKind::Log("LOGCLOSE") => (EventCode::Log, "LOGCLOSE".to_string()),
                MsgKind::Log("LOG") => (
                    EventCode::Log,
                    format!("LOG,{}", self.substitute(state, &text, line_no)),
                ),
                MsgKind::Log(call) => (EventCode::Log, format!("{call},{text}")),
            };
            let mut e = Event::new(line_no, code, None);
            e.text = Some(Arc::from(text));
            items.push(Item::Event(e));
        }
        Ok(())
    }

    /// DEBUG and PRINT text: each `#n`, `##n` or `#<name>` replaced by its value as
    /// LinuxCNC prints it (six decimals), or `######` when it cannot be read.
    fn substitute(&self, state: &State, text: &str, line_no: u32) -> String {
        let ctx = self.ctx(state, line_no);
        let bytes = text.as_bytes();
        let mut out = String::with_capacity(text.len());
        let mut i = 0;
        while i < bytes.len() {
            if bytes[i] != b'#' {
                let ch_len = text[i..].chars().next().map_or(1, char::len_utf8);
                out.push_str(&text[i..i + ch_len]);
                i += ch_len;
                continue;
            }
            // The parameter reference: `#<name>` or `#`s followed by digits.
            let start = i;
            let mut j = i;
            let value = if bytes.get(i + 1) == Some(&b'<') {
                match bytes[i + 1..].iter().position(|&b| b == b'>') {
                    Some(off) => {
                        j = i + 2 + off;
                        let name: String = text[i + 2..j - 1]
                            .chars()
                            .filter(|c| !c.is_whitespace())
                            .map(|c| c.to_ascii_lowercase())
                            .collect();
                        expr::Params::named(&ctx, &name, 1).ok()
                    }
                    None => {
                        j = bytes.len();
                        None
                    }
                }
            } else {
                let mut hashes = 0;
                while bytes.get(j) == Some(&b'#') {
                    hashes += 1;
                    j += 1;
                }
                let d0 = j;
                while bytes.get(j).is_some_and(u8::is_ascii_digit) {
                    j += 1;
                }
                if j == d0 {
                    out.push_str(&text[start..j]);
                    i = j;
                    continue;
                }
                let mut v = text[d0..j].parse::<f64>().ok();
                for _ in 0..hashes {
                    v = v.and_then(|n| expr::Params::numbered(&ctx, n, 1).ok());
                }
                v
            };
            match value {
                Some(v) => out.push_str(&format!("{v:.6}")),
                None => out.push_str("######"),
            }
            i = j.max(start + 1);
        }
        out
    }
}

impl Ngc {
    /// Reads the optional `[expr]` after an O-word keyword.
    fn o_value(
        &self,
        state: &State,
        line_no: u32,
        norm: &[u8],
        cols: &[u32],
        after: usize,
    ) -> Result<Option<f64>, BlockError> {
        let mut r = expr::Reader::new(norm, cols, after);
        match r.peek() {
            Some(b'[') => {
                let v = r.expression(&self.ctx(state, line_no))?;
                Ok(Some(v))
            }
            _ => Ok(None),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn o_cond(
        &self,
        state: &State,
        line_no: u32,
        norm: &[u8],
        cols: &[u32],
        after: usize,
        ocol: u32,
        kw: Kw,
    ) -> Result<f64, BlockError> {
        match self.o_value(state, line_no, norm, cols, after)? {
            Some(v) => Ok(v),
            None => fail(
                ocol,
                format!("Left bracket missing after '{}'", kw_name(kw)),
            ),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn o_word(
        &mut self,
        text: &[u8],
        line_no: u32,
        state: &mut State,
        label: &Arc<str>,
        kw: Kw,
        after: usize,
        ocol: u32,
        norm: &[u8],
        cols: &[u32],
    ) -> Result<(), BlockError> {
        let name = label_name(label);
        check_o_tail(norm, cols, after, kw)?;
        if !self.from_frame {
            // The main program, read from the reader.
            return match kw {
                Kw::Sub if self.forward.contains(label) => fail(
                    ocol,
                    format!(
                        "sub: {name} found in illegal location (it was called before this definition)"
                    ),
                ),
                Kw::Sub | Kw::If | Kw::While | Kw::Do | Kw::Repeat => {
                    self.capture = Some(Capture {
                        label: label.clone(),
                        kind: kw,
                        lines: vec![make_src(text, line_no)],
                    });
                    Ok(())
                }
                Kw::Call => self.call(state, line_no, label, norm, cols, after, ocol),
                _ => fail(
                    ocol,
                    format!("{name} {} outside its structure", kw_name(kw)),
                ),
            };
        }
        let depth = self.frames.len();
        let Some(frame) = self.frames.last_mut() else {
            return fail(ocol, "internal: no frame");
        };
        let here = frame.pc.saturating_sub(1);
        let body = frame.body.clone();
        let find = |from: usize, kws: &[Kw]| -> Option<usize> {
            body.lines
                .iter()
                .enumerate()
                .skip(from)
                .find(|(_, l)| matches!(&l.head, Some((lb, k)) if lb == label && kws.contains(k)))
                .map(|(i, _)| i)
        };
        let missing = |what: &str| BlockError {
            col: ocol,
            message: format!("{name}: matching '{what}' not found"),
        };
        match kw {
            Kw::Sub => {
                if self.frames.iter().any(|f| f.call.is_some()) {
                    return fail(ocol, "Nested subroutine definition");
                }
                let end = find(here + 1, &[Kw::EndSub]).ok_or_else(|| missing("endsub"))?;
                let lines = body.lines[here..=end]
                    .iter()
                    .map(|l| make_src(&l.text, l.line))
                    .collect();
                let sub = Arc::new(Body {
                    lines,
                    file: body.file.clone(),
                });
                self.subs.insert(label.clone(), sub);
                if let Some(f) = self.frames.last_mut() {
                    f.pc = end + 1;
                }
                Ok(())
            }
            Kw::EndSub | Kw::Return => {
                let v = self.o_value(state, line_no, norm, cols, after)?;
                self.value = v.unwrap_or(0.0);
                self.value_returned = v.is_some();
                // Leave every top-level structure frame above the call frame: there are
                // none inside a call (structures in a sub run in its frame).
                match self.frames.last().map(|f| f.call.is_some()) {
                    Some(true) => {
                        if let Some(Frame { call: Some(c), .. }) = self.frames.pop() {
                            self.locals.pop();
                            if self.locals.is_empty() {
                                self.locals.push(HashMap::new());
                            }
                            for (k, v) in c.saved.iter().enumerate() {
                                state.params.set(k + 1, *v);
                            }
                            // M73 in the sub: the caller's modal state comes back.
                            state.modal_leave_call(&mut self.restored, line_no);
                        }
                        Ok(())
                    }
                    _ => fail(ocol, format!("{name} {} outside a subroutine", kw_name(kw))),
                }
            }
            Kw::Call => {
                let _ = depth;
                self.call(state, line_no, label, norm, cols, after, ocol)
            }
            Kw::If => {
                let c = self.o_cond(state, line_no, norm, cols, after, ocol, kw)?;
                if c == 0.0 {
                    self.skip_branch(here, label, &name, state, ocol)?;
                }
                Ok(())
            }
            Kw::ElseIf | Kw::Else => {
                // Reached from a branch that ran: skip to the endif.
                let end = find(here + 1, &[Kw::EndIf]).ok_or_else(|| missing("endif"))?;
                self.set_pc(end + 1);
                Ok(())
            }
            Kw::EndIf => Ok(()),
            Kw::Do => {
                self.enter_loop(label, LoopKind::Do, here, 0.0)?;
                Ok(())
            }
            Kw::While => {
                let in_do = self.frames.last().is_some_and(|f| {
                    f.loops
                        .last()
                        .is_some_and(|l| l.label == *label && l.kind == LoopKind::Do)
                });
                let c = self.o_cond(state, line_no, norm, cols, after, ocol, kw)?;
                if in_do {
                    if c != 0.0 {
                        let start = self.top_loop_start();
                        self.count_iteration(&name, ocol)?;
                        self.set_pc(start + 1);
                    } else {
                        self.pop_loop();
                    }
                    return Ok(());
                }
                if c != 0.0 {
                    self.enter_loop(label, LoopKind::While, here, 0.0)?;
                } else {
                    let end = find(here + 1, &[Kw::EndWhile]).ok_or_else(|| missing("endwhile"))?;
                    self.leave_loop_if(label, here);
                    self.set_pc(end + 1);
                }
                Ok(())
            }
            Kw::EndWhile => {
                let start = self
                    .loop_start(label, LoopKind::While)
                    .ok_or_else(|| missing("while"))?;
                self.count_iteration(&name, ocol)?;
                self.set_pc(start);
                Ok(())
            }
            Kw::Repeat => {
                let n = self.o_cond(state, line_no, norm, cols, after, ocol, kw)?;
                // rs274 rounds the count to the nearest whole number (2.7 runs 3 times).
                let n = n.round();
                if n >= 1.0 {
                    self.enter_loop(label, LoopKind::Repeat, here, n)?;
                } else {
                    let end =
                        find(here + 1, &[Kw::EndRepeat]).ok_or_else(|| missing("endrepeat"))?;
                    self.set_pc(end + 1);
                }
                Ok(())
            }
            Kw::EndRepeat => {
                let Some(frame) = self.frames.last_mut() else {
                    return Ok(());
                };
                let Some(l) = frame
                    .loops
                    .last_mut()
                    .filter(|l| l.label == *label && l.kind == LoopKind::Repeat)
                else {
                    return Err(missing("repeat"));
                };
                l.remaining -= 1.0;
                if l.remaining >= 1.0 {
                    let start = l.start;
                    self.count_iteration(&name, ocol)?;
                    self.set_pc(start + 1);
                } else {
                    self.pop_loop();
                }
                Ok(())
            }
            Kw::Break | Kw::Continue => {
                let Some(kind) = self.frames.last().and_then(|f| {
                    f.loops
                        .iter()
                        .rev()
                        .find(|l| l.label == *label)
                        .map(|l| l.kind)
                }) else {
                    return fail(ocol, format!("{name} {} outside its loop", kw_name(kw)));
                };
                // Structures nested inside the loop are left with it.
                if let Some(f) = self.frames.last_mut() {
                    while f.loops.last().is_some_and(|l| l.label != *label) {
                        f.loops.pop();
                    }
                }
                let end_kw = match kind {
                    LoopKind::While => Kw::EndWhile,
                    LoopKind::Do => Kw::While,
                    LoopKind::Repeat => Kw::EndRepeat,
                };
                let end = find(here + 1, &[end_kw]).ok_or_else(|| missing(kw_name(end_kw)))?;
                if kw == Kw::Break {
                    self.pop_loop();
                    self.set_pc(end + 1);
                } else {
                    // Continue: run the loop's end line (it tests and counts the iteration).
                    self.set_pc(end);
                }
                Ok(())
            }
        }
    }

    /// After a false `if`/`elseif` at line `from`: runs on at the next `elseif` (testing
    /// it), the `else`, or after the `endif`.
    fn skip_branch(
        &mut self,
        mut from: usize,
        label: &Arc<str>,
        name: &str,
        state: &State,
        ocol: u32,
    ) -> Result<(), BlockError> {
        let Some(body) = self.frames.last().map(|f| f.body.clone()) else {
            return Ok(());
        };
        loop {
            let next = body
                .lines
                .iter()
                .enumerate()
                .skip(from + 1)
                .find(|(_, l)| {
                    matches!(&l.head, Some((lb, k)) if lb == label
                        && matches!(k, Kw::ElseIf | Kw::Else | Kw::EndIf))
                })
                .map(|(i, l)| (i, l.head.as_ref().map(|h| h.1)));
            let Some((i, kw)) = next else {
                return fail(ocol, format!("{name}: matching 'endif' not found"));
            };
            match kw {
                Some(Kw::ElseIf) => {
                    let l = &body.lines[i];
                    let mut norm = Vec::new();
                    let mut cols = Vec::new();
                    normalize(&l.text, &mut norm, &mut cols)?;
                    let Some((_, _, after)) = o_head(&norm, &cols)? else {
                        return fail(ocol, "internal: elseif");
                    };
                    let c = self.o_cond(state, l.line, &norm, &cols, after, ocol, Kw::ElseIf)?;
                    if c != 0.0 {
                        self.set_pc(i + 1);
                        return Ok(());
                    }
                    from = i;
                }
                _ => {
                    self.set_pc(i + 1);
                    return Ok(());
                }
            }
        }
    }

    fn set_pc(&mut self, pc: usize) {
        if let Some(f) = self.frames.last_mut() {
            f.pc = pc;
        }
    }

    fn top_loop_start(&self) -> usize {
        self.frames
            .last()
            .and_then(|f| f.loops.last())
            .map_or(0, |l| l.start)
    }

    fn pop_loop(&mut self) {
        if let Some(f) = self.frames.last_mut() {
            f.loops.pop();
        }
    }

    fn loop_start(&self, label: &Arc<str>, kind: LoopKind) -> Option<usize> {
        self.frames
            .last()?
            .loops
            .last()
            .filter(|l| l.label == *label && l.kind == kind)
            .map(|l| l.start)
    }

    fn leave_loop_if(&mut self, label: &Arc<str>, start: usize) {
        if let Some(f) = self.frames.last_mut()
            && f.loops
                .last()
                .is_some_and(|l| l.label == *label && l.start == start)
        {
            f.loops.pop();
        }
    }

    /// Enters a loop at line `start`, unless it is the loop already running there (a
    /// `while` line is run again at each iteration).
    fn enter_loop(
        &mut self,
        label: &Arc<str>,
        kind: LoopKind,
        start: usize,
        count: f64,
    ) -> Result<(), BlockError> {
        let Some(f) = self.frames.last_mut() else {
            return Ok(());
        };
        if f.loops
            .last()
            .is_some_and(|l| l.label == *label && l.start == start)
        {
            return Ok(());
        }
        if f.loops.len() >= 1000 {
            return fail(1, "loops nested too deeply");
        }
        f.loops.push(LoopState {
            label: label.clone(),
            kind,
            start,
            remaining: count,
            iterations: 0,
        });
        Ok(())
    }

    fn count_iteration(&mut self, name: &str, ocol: u32) -> Result<(), BlockError> {
        let max = self.max_loop_iterations;
        if let Some(l) = self.frames.last_mut().and_then(|f| f.loops.last_mut()) {
            l.iterations += 1;
            if l.iterations >= max {
                return fail(
                    ocol,
                    format!(
                        "loop {name} ran {max} times: stopped as endless (max_loop_iterations)"
                    ),
                );
            }
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn call(
        &mut self,
        state: &mut State,
        line_no: u32,
        label: &Arc<str>,
        norm: &[u8],
        cols: &[u32],
        after: usize,
        ocol: u32,
    ) -> Result<(), BlockError> {
        let name = label_name(label);
        // Arguments: `[expr]` each, read before the call.
        let mut args = [0.0f64; 30];
        let mut n = 0;
        {
            let ctx = self.ctx(state, line_no);
            let mut r = expr::Reader::new(norm, cols, after);
            while let Some(c) = r.peek() {
                match c {
                    b'[' => {
                        if n == args.len() {
                            return fail(r.col(), "Too many arguments to subroutine call");
                        }
                        args[n] = r.expression(&ctx)?;
                        n += 1;
                    }
                    b'(' => break,
                    _ => return fail(r.col(), "Left bracket missing in subroutine call argument"),
                }
            }
        }
        if self.call_level() >= MAX_CALL_LEVELS {
            return fail(ocol, "Too many subroutine levels");
        }
        let body = match self.subs.get(label) {
            Some(b) => b.clone(),
            None => {
                let b = match self.find_forward(label) {
                    Ok(Some(b)) => Ok(Some(b)),
                    Ok(None) => self.load_file(label),
                    Err(e) => Err(e),
                }
                .map_err(|message| BlockError { col: ocol, message })?;
                match b {
                    Some(b) => b,
                    None => {
                        return fail(
                            ocol,
                            format!(
                                "{name} called but not defined: no sub in the program and no file {}.ngc on the subroutine path",
                                label
                            ),
                        );
                    }
                }
            }
        };
        let mut saved = [0.0; 30];
        for (k, s) in saved.iter_mut().enumerate() {
            *s = state.params.get(k + 1).unwrap_or(0.0);
        }
        // rs274 sets #1..#30 to the arguments and the ones without an argument to 0 (the
        // manual says they keep the caller's values; rs274 reads 0).
        for (k, v) in args.iter().enumerate() {
            state.params.set(k + 1, *v);
        }
        self.value_returned = false;
        self.locals.push(HashMap::new());
        self.frames.push(Frame {
            body,
            pc: 1,
            call: Some(Call {
                saved,
                from_file: self.cur_file.clone(),
                from_line: line_no,
            }),
            loops: Vec::new(),
        });
        state.modal_enter_call();
        Ok(())
    }

    /// A sub called before its definition: its `sub` … `endsub` later in the program's
    /// file (read again, line by line), as LinuxCNC seeks forward for it.
    fn find_forward(&mut self, label: &Arc<str>) -> Result<Option<Arc<Body>>, String> {
        let Some(path) = self.program_file.clone() else {
            return Ok(None);
        };
        let Ok(file) = std::fs::File::open(&path) else {
            return Ok(None);
        };
        let found = read_sub(std::io::BufReader::new(file), label, None)?;
        if let Some(b) = &found {
            self.forward.insert(label.clone());
            self.subs.insert(label.clone(), b.clone());
        }
        Ok(found)
    }

    /// Finds `NAME.ngc` on the search path and keeps its `o<NAME> sub` … `endsub`.
    fn load_file(&mut self, label: &Arc<str>) -> Result<Option<Arc<Body>>, String> {
        if label.starts_with(|c: char| c.is_ascii_digit()) {
            return Ok(None);
        }
        let file_name = format!("{label}.ngc");
        let Some(path) = self
            .search_path
            .iter()
            .map(|d| d.join(&file_name))
            .find(|p| p.is_file())
        else {
            return Ok(None);
        };
        let shown: Arc<str> = Arc::from(path.display().to_string());
        let file = std::fs::File::open(&path).map_err(|e| format!("{shown}: cannot read: {e}"))?;
        match read_sub(std::io::BufReader::new(file), label, Some(shown.clone()))? {
            Some(body) => {
                self.subs.insert(label.clone(), body.clone());
                Ok(Some(body))
            }
            None => Err(format!(
                "{shown}: no {} sub ... endsub in the file",
                label_name(label)
            )),
        }
    }
}

/// The lines of `o<label> sub` … `endsub` in `reader`, or `None` when it has none. Only the
/// sub's own lines are kept.
fn read_sub<R: std::io::BufRead>(
    mut reader: R,
    label: &Arc<str>,
    file: Option<Arc<str>>,
) -> Result<Option<Arc<Body>>, String> {
    use std::io::{BufRead, Read};
    let shown = file.as_deref().unwrap_or("the program").to_string();
    let mut lines = Vec::new();
    let mut inside = false;
    let mut raw = Vec::new();
    let mut i = 0usize;
    loop {
        raw.clear();
        let n = (&mut reader)
            .take(crate::MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut raw)
            .map_err(|e| format!("{shown}: cannot read: {e}"))?;
        if n == 0 {
            return Ok(None);
        }
        i += 1;
        let text = raw.strip_suffix(b"\n").unwrap_or(&raw);
        let text = text.strip_suffix(b"\r").unwrap_or(text);
        if !inside && !text.iter().any(|&b| b == b'o' || b == b'O') {
            continue;
        }
        let src = make_src(text, u32::try_from(i).unwrap_or(u32::MAX));
        let head = src.head.clone();
        if !inside && matches!(&head, Some((l, Kw::Sub)) if l == label) {
            inside = true;
        }
        if inside {
            if lines.len() >= MAX_BODY_LINES {
                return Err(format!(
                    "{shown}: subroutine longer than {MAX_BODY_LINES} lines"
                ));
            }
            lines.push(src);
            if matches!(&head, Some((l, Kw::EndSub)) if l == label) {
                return Ok(Some(Arc::new(Body { lines, file })));
            }
        }
    }
}
