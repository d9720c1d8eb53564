//! Subroutines: `call` with its arguments and saved parameters, and finding a sub's body
//! (defined earlier, forward in the program, or in a file of the program directory).

use super::flow::OLine;
use super::*;

impl Ngc {
    /// `sub` met while running a frame: its body up to the `endsub` is kept for later
    /// calls and the run goes on after it.
    pub(super) fn o_sub(&mut self, o: &OLine<'_>) -> Result<(), BlockError> {
        if self.frames.iter().any(|f| f.call.is_some()) {
            return fail(o.ocol, "Nested subroutine definition");
        }
        let end = o
            .find(o.here + 1, &[Kw::EndSub])
            .ok_or_else(|| o.missing("endsub"))?;
        let body = &o.body;
        let lines = body.lines[o.here..=end]
            .iter()
            .map(|l| make_src(&l.text, l.line))
            .collect();
        let sub = Arc::new(Body {
            lines,
            file: body.file.clone(),
        });
        self.subs.insert(o.label.clone(), sub);
        if let Some(f) = self.frames.last_mut() {
            f.pc = end + 1;
        }
        Ok(())
    }

    /// `endsub` and `return`: the value (if any) is kept, the call frame left, the
    /// caller's parameters and (after M73) its modal state restored.
    pub(super) fn o_return(&mut self, state: &mut State, o: &OLine<'_>) -> Result<(), BlockError> {
        let v = self.o_value(state, o.line_no, o.norm, o.cols, o.after)?;
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
                    state.modal_leave_call(&mut self.restored, o.line_no);
                }
                Ok(())
            }
            _ => fail(
                o.ocol,
                format!("{} {} outside a subroutine", o.name, kw_name(o.kw)),
            ),
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn call(
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
    pub(super) fn find_forward(&mut self, label: &Arc<str>) -> Result<Option<Arc<Body>>, String> {
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
    pub(super) fn load_file(&mut self, label: &Arc<str>) -> Result<Option<Arc<Body>>, String> {
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
pub(super) fn read_sub<R: std::io::BufRead>(
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
