//! One LinuxCNC line: collected into a structure, run as an O-word, or read into words,
//! assignments and messages (every value of the line is read before any assignment takes
//! effect), then committed after the block ran; `(debug,…)` message substitution.

use super::*;
use crate::lex::Word;

impl Ngc {
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

    pub(super) fn line_inner(
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

    pub(super) fn read_words(
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
        // A #5399 answer read on this line goes into the table before the assignments.
        state.settle_input();
        for (target, v, col) in std::mem::take(&mut self.assignments) {
            match target {
                Target::Numbered(i) => {
                    if !state.params.set(i, v) {
                        return fail(col, "Parameter number out of range");
                    }
                    if i == params::INPUT_RESULT {
                        state.input_result_assigned();
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
        // A wait a DEBUG or PRINT text asked for and could not show (`######`).
        if let Some(message) = state.input_failure() {
            return fail(1, message);
        }
        state.settle_input();
        Ok(())
    }

    /// DEBUG and PRINT text: each `#n`, `##n` or `#<name>` replaced by its value as
    /// LinuxCNC prints it (six decimals), or `######` when it cannot be read.
    pub(super) fn substitute(&self, state: &State, text: &str, line_no: u32) -> String {
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
