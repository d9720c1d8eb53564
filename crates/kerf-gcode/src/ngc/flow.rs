//! O-word flow control: `if`/`elseif`/`else`/`endif`, `while`/`endwhile`, `do`/`while`,
//! `repeat`/`endrepeat`, `break` and `continue`, and the definition of a `sub` met while
//! running, on the frame stack of [`Ngc`].

use super::*;

/// An O-word line run from a frame: its label, keyword and value, and its place in the
/// body of the frame.
pub(super) struct OLine<'a> {
    pub(super) label: &'a Arc<str>,
    /// The display form of the label.
    pub(super) name: String,
    pub(super) kw: Kw,
    pub(super) line_no: u32,
    pub(super) norm: &'a [u8],
    pub(super) cols: &'a [u32],
    /// Where the value after the keyword starts in `norm`.
    pub(super) after: usize,
    /// The column of the O-word.
    pub(super) ocol: u32,
    /// The index of the line in `body`.
    pub(super) here: usize,
    pub(super) body: Arc<Body>,
}

impl OLine<'_> {
    /// The first line from `from` on that holds this label with one of `kws`.
    pub(super) fn find(&self, from: usize, kws: &[Kw]) -> Option<usize> {
        self.body
            .lines
            .iter()
            .enumerate()
            .skip(from)
            .find(|(_, l)| matches!(&l.head, Some((lb, k)) if lb == self.label && kws.contains(k)))
            .map(|(i, _)| i)
    }

    /// The error for a matching line that is not there.
    pub(super) fn missing(&self, what: &str) -> BlockError {
        BlockError {
            col: self.ocol,
            message: format!("{}: matching '{what}' not found", self.name),
        }
    }
}

impl Ngc {
    /// Reads the optional `[expr]` after an O-word keyword.
    pub(super) fn o_value(
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
    pub(super) fn o_cond(
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
    pub(super) fn o_word(
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
        let Some(frame) = self.frames.last_mut() else {
            return fail(ocol, "internal: no frame");
        };
        let o = OLine {
            label,
            name,
            kw,
            line_no,
            norm,
            cols,
            after,
            ocol,
            here: frame.pc.saturating_sub(1),
            body: frame.body.clone(),
        };
        match kw {
            Kw::Sub => self.o_sub(&o),
            Kw::EndSub | Kw::Return => self.o_return(state, &o),
            Kw::Call => self.call(state, line_no, label, norm, cols, after, ocol),
            Kw::If => {
                let c = self.o_cond_of(state, &o)?;
                if c == 0.0 {
                    self.skip_branch(o.here, label, &o.name, state, ocol)?;
                }
                Ok(())
            }
            Kw::ElseIf | Kw::Else => {
                // Reached from a branch that ran: skip to the endif.
                let end = o
                    .find(o.here + 1, &[Kw::EndIf])
                    .ok_or_else(|| o.missing("endif"))?;
                self.set_pc(end + 1);
                Ok(())
            }
            Kw::EndIf => Ok(()),
            Kw::Do => {
                self.enter_loop(label, LoopKind::Do, o.here, 0.0)?;
                Ok(())
            }
            Kw::While => self.o_while(state, &o),
            Kw::EndWhile => {
                let start = self
                    .loop_start(label, LoopKind::While)
                    .ok_or_else(|| o.missing("while"))?;
                self.count_iteration(&o.name, ocol)?;
                self.set_pc(start);
                Ok(())
            }
            Kw::Repeat => self.o_repeat(state, &o),
            Kw::EndRepeat => self.o_end_repeat(&o),
            Kw::Break | Kw::Continue => self.o_break_continue(&o),
        }
    }

    /// The condition of an O-word line run from a frame.
    fn o_cond_of(&self, state: &State, o: &OLine<'_>) -> Result<f64, BlockError> {
        self.o_cond(state, o.line_no, o.norm, o.cols, o.after, o.ocol, o.kw)
    }

    /// `while`: the end of a `do` loop (tests and counts the iteration) or the start of a
    /// `while` loop (entered, or skipped past its `endwhile`).
    fn o_while(&mut self, state: &State, o: &OLine<'_>) -> Result<(), BlockError> {
        let label = o.label;
        let in_do = self.frames.last().is_some_and(|f| {
            f.loops
                .last()
                .is_some_and(|l| l.label == *label && l.kind == LoopKind::Do)
        });
        let c = self.o_cond_of(state, o)?;
        if in_do {
            if c != 0.0 {
                let start = self.top_loop_start();
                self.count_iteration(&o.name, o.ocol)?;
                self.set_pc(start + 1);
            } else {
                self.pop_loop();
            }
            return Ok(());
        }
        if c != 0.0 {
            self.enter_loop(label, LoopKind::While, o.here, 0.0)?;
        } else {
            let end = o
                .find(o.here + 1, &[Kw::EndWhile])
                .ok_or_else(|| o.missing("endwhile"))?;
            self.leave_loop_if(label, o.here);
            self.set_pc(end + 1);
        }
        Ok(())
    }

    /// `repeat [n]`: entered with its count, or skipped past its `endrepeat`.
    fn o_repeat(&mut self, state: &State, o: &OLine<'_>) -> Result<(), BlockError> {
        let n = self.o_cond_of(state, o)?;
        // rs274 rounds the count to the nearest whole number (2.7 runs 3 times).
        let n = n.round();
        if n >= 1.0 {
            self.enter_loop(o.label, LoopKind::Repeat, o.here, n)?;
        } else {
            let end = o
                .find(o.here + 1, &[Kw::EndRepeat])
                .ok_or_else(|| o.missing("endrepeat"))?;
            self.set_pc(end + 1);
        }
        Ok(())
    }

    /// `endrepeat`: counts the iteration down and runs the loop again or leaves it.
    fn o_end_repeat(&mut self, o: &OLine<'_>) -> Result<(), BlockError> {
        let label = o.label;
        let Some(frame) = self.frames.last_mut() else {
            return Ok(());
        };
        let Some(l) = frame
            .loops
            .last_mut()
            .filter(|l| l.label == *label && l.kind == LoopKind::Repeat)
        else {
            return Err(o.missing("repeat"));
        };
        l.remaining -= 1.0;
        if l.remaining >= 1.0 {
            let start = l.start;
            self.count_iteration(&o.name, o.ocol)?;
            self.set_pc(start + 1);
        } else {
            self.pop_loop();
        }
        Ok(())
    }

    /// `break` and `continue`: leave the loop of the label (and the structures nested in
    /// it), or run its end line.
    fn o_break_continue(&mut self, o: &OLine<'_>) -> Result<(), BlockError> {
        let label = o.label;
        let Some(kind) = self.frames.last().and_then(|f| {
            f.loops
                .iter()
                .rev()
                .find(|l| l.label == *label)
                .map(|l| l.kind)
        }) else {
            return fail(
                o.ocol,
                format!("{} {} outside its loop", o.name, kw_name(o.kw)),
            );
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
        let end = o
            .find(o.here + 1, &[end_kw])
            .ok_or_else(|| o.missing(kw_name(end_kw)))?;
        if o.kw == Kw::Break {
            self.pop_loop();
            self.set_pc(end + 1);
        } else {
            // Continue: run the loop's end line (it tests and counts the iteration).
            self.set_pc(end);
        }
        Ok(())
    }

    /// After a false `if`/`elseif` at line `from`: runs on at the next `elseif` (testing
    /// it), the `else`, or after the `endif`.
    pub(super) fn skip_branch(
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

    pub(super) fn set_pc(&mut self, pc: usize) {
        if let Some(f) = self.frames.last_mut() {
            f.pc = pc;
        }
    }

    pub(super) fn top_loop_start(&self) -> usize {
        self.frames
            .last()
            .and_then(|f| f.loops.last())
            .map_or(0, |l| l.start)
    }

    pub(super) fn pop_loop(&mut self) {
        if let Some(f) = self.frames.last_mut() {
            f.loops.pop();
        }
    }

    pub(super) fn loop_start(&self, label: &Arc<str>, kind: LoopKind) -> Option<usize> {
        self.frames
            .last()?
            .loops
            .last()
            .filter(|l| l.label == *label && l.kind == kind)
            .map(|l| l.start)
    }

    pub(super) fn leave_loop_if(&mut self, label: &Arc<str>, start: usize) {
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
    pub(super) fn enter_loop(
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

    pub(super) fn count_iteration(&mut self, name: &str, ocol: u32) -> Result<(), BlockError> {
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
}
