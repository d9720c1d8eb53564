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
use crate::lex::{Form, K_AT, K_CARET};
use crate::{Event, EventCode, Item};

mod context;
pub(crate) mod expr;
mod flow;
mod line;
mod normalize;
mod subs;

use context::param_index;
use normalize::{check_o_tail, normalize, o_head};

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
                if crate::lex::is_message_comment(rest) {
                    return true;
                }
                match rest.iter().position(|&b| b == b')') {
                    Some(off) => i += 1 + off,
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

    /// MDI, after an error: every call, loop and structure being collected is dropped
    /// (the next line is read from the input, in the main program's scope). Definitions
    /// of subroutines already complete are kept.
    pub(crate) fn abandon(&mut self) {
        self.frames.clear();
        self.capture = None;
        self.from_frame = false;
        self.cur_file = None;
        self.locals.truncate(1);
        self.assignments.clear();
        self.messages.clear();
        self.restored.clear();
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
