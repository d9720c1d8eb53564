//! LinuxCNC's machine I/O codes M62–M68 (the manual's "HAL pin I/O", step 7 of the order
//! of execution: after T, before M6) and the `#5399` result of an `M66` wait.
//!
//! - M62/M63 switch digital output P on/off with the start of the next move, M64/M65 at
//!   once; M67/M68 set analog output E to Q with the next move / at once. Each is an
//!   event with `value` = the output number (M67/M68: `q` = the value).
//! - M66 waits on digital input P (`M66` event) or analog input E (`M66Analog`), with
//!   the wait mode L (0 immediate, 1 rise, 2 fall, 3 high, 4 low; analog inputs only 0)
//!   in `p` and the timeout Q (seconds) in `q`.
//!
//! rs274's checks and words are kept (`convert_m`): the cutter compensation check, "No
//! valid P word with M62", "Need to have either a valid P or a valid E word with M66",
//! "Zero timeout with wait type != immediate return", ... Kerf is stricter where rs274
//! hands on a number the machine cannot have: an input or output number must be a whole
//! number from 0 to [`MAX_IO_NUMBER`] (rs274 rounds it and takes negative ones for
//! outputs), L at most 4, and M67/M68 need their Q word (rs274 sets -1 without one).

use std::cell::RefCell;

use super::mcodes::MCodes;
use super::params::INPUT_RESULT;
use super::{Block, BlockError, Out, State, fail};
use crate::codes::{KE, KL, KP, KQ};
use crate::{Event, EventCode, InputWait, Item, MAX_IO_NUMBER};

/// LinuxCNC's tolerance for a number that must be an integer (rs274 reads such words
/// within it).
const INTEGER_TOLERANCE: f64 = 0.0001;

/// Where `#5399` comes from: the source of answers and the `M66` not yet answered.
#[derive(Default)]
pub(crate) struct Inputs {
    /// The machine's answers; `None`: the settings' simulated inputs.
    source: Option<Box<dyn InputWait + Send>>,
    /// The last `M66`, while no line has read `#5399` since it ran.
    outstanding: Option<Event>,
    /// The answer to the last `M66`, until it is settled into the parameter table.
    answer: Option<f64>,
    /// A failed wait: every later read of `#5399` fails with it.
    failure: Option<String>,
}

/// The interior-mutable slot: a read of `#5399` happens while the language layer holds
/// the state shared, and it may have to ask the machine.
pub(crate) type InputCell = RefCell<Inputs>;

impl State {
    /// The source of `M66` answers from now on.
    pub(crate) fn set_input_wait(&mut self, source: Box<dyn InputWait + Send>) {
        self.inputs.get_mut().source = Some(source);
    }

    /// `#5399` as a line reads it: after an `M66` that no line has read since, the wait's
    /// answer (asked once, here), else the parameter's value. A failed wait is the error,
    /// at `col`, for this read and every later one.
    pub(crate) fn read_input_result(&self, col: u32) -> Result<f64, BlockError> {
        let mut slot = self.inputs.borrow_mut();
        if let Some(msg) = &slot.failure {
            return fail(col, msg.clone());
        }
        if let Some(ev) = slot.outstanding.take() {
            let got = match slot.source.as_mut() {
                Some(source) => source.wait(&ev),
                None => self.settings.simulated_inputs.answer(&ev),
            };
            match got {
                Ok(v) if v.is_finite() => slot.answer = Some(v),
                Ok(v) => {
                    let msg = format!(
                        "#5399 after the M66 of line {}: the answer {v} is not a number",
                        ev.line
                    );
                    slot.failure = Some(msg.clone());
                    return fail(col, msg);
                }
                Err(e) => {
                    let msg = format!("#5399 after the M66 of line {}: {e}", ev.line);
                    slot.failure = Some(msg.clone());
                    return fail(col, msg);
                }
            }
        }
        Ok(slot.answer.unwrap_or_else(|| self.params.at(INPUT_RESULT)))
    }

    /// The failure of a wait asked for by a read whose error was not reported (a DEBUG or
    /// PRINT text, which shows `######` for a value it cannot read).
    pub(crate) fn input_failure(&self) -> Option<String> {
        self.inputs.borrow().failure.clone()
    }

    /// Puts an answer read since the last call into the parameter table.
    pub(crate) fn settle_input(&mut self) {
        if let Some(v) = self.inputs.get_mut().answer.take() {
            self.params.set(INPUT_RESULT, v);
        }
    }

    /// The program assigns `#5399`: an outstanding `M66` is no longer read through it.
    pub(crate) fn input_result_assigned(&mut self) {
        let slot = self.inputs.get_mut();
        slot.outstanding = None;
        slot.answer = None;
    }

    /// M62–M68 of a block (LinuxCNC): checked as rs274 checks them, then the event; an
    /// M66 becomes the outstanding wait.
    pub(super) fn exec_io(
        &mut self,
        blk: &Block,
        mc: &MCodes,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Some((code, col)) = mc.io else {
            return Ok(());
        };
        let event = match code {
            EventCode::M62 | EventCode::M63 | EventCode::M64 | EventCode::M65 => {
                self.digital_output(blk, code, col, out.line)?
            }
            EventCode::M67 | EventCode::M68 => self.analog_output(blk, code, col, out.line)?,
            _ => self.input_wait(blk, col, out.line)?,
        };
        if matches!(event.code, EventCode::M66 | EventCode::M66Analog) {
            self.settle_input();
            let slot = self.inputs.get_mut();
            slot.outstanding = Some(event.clone());
            slot.answer = None;
        }
        out.items.push(Item::Event(event));
        Ok(())
    }

    fn digital_output(
        &self,
        blk: &Block,
        code: EventCode,
        col: u32,
        line: u32,
    ) -> Result<Event, BlockError> {
        let name = code.as_str();
        self.comp_refuse(
            col,
            match code {
                EventCode::M62 => "Cannot set motion output with cutter radius compensation on",
                EventCode::M63 => {
                    "Cannot set motion digital output with cutter radius compensation on"
                }
                _ => "Cannot set auxiliary digital output with cutter radius compensation on",
            },
        )?;
        let Some(p) = blk.get(KP) else {
            return fail(col, format!("No valid P word with {name}"));
        };
        let Some(n) = io_number(p) else {
            return fail(
                blk.col(KP),
                format!(
                    "No valid P word with {name}: the output number is a whole number from 0 to {MAX_IO_NUMBER}"
                ),
            );
        };
        Ok(Event::new(line, code, Some(n)))
    }

    fn analog_output(
        &self,
        blk: &Block,
        code: EventCode,
        col: u32,
        line: u32,
    ) -> Result<Event, BlockError> {
        let name = code.as_str();
        self.comp_refuse(
            col,
            if code == EventCode::M67 {
                "Cannot set motion analog output with cutter radius compensation on"
            } else {
                "Cannot set auxiliary analog output with cutter radius compensation on"
            },
        )?;
        let e = match blk.get(KE) {
            Some(e) if e.round() >= 0.0 => e,
            Some(_) => return fail(blk.col(KE), format!("Invalid analog index with {name}")),
            None => return fail(col, format!("Invalid analog index with {name}")),
        };
        let Some(n) = io_number(e) else {
            return fail(
                blk.col(KE),
                format!(
                    "Invalid analog index with {name}: the output number is a whole number from 0 to {MAX_IO_NUMBER}"
                ),
            );
        };
        let Some(q) = blk.get(KQ) else {
            return fail(col, format!("Q word missing with {name}: the value to set"));
        };
        let mut event = Event::new(line, code, Some(n));
        event.q = Some(q);
        Ok(event)
    }

    /// M66, checked in rs274's order: P and E together, a zero timeout with a waiting L,
    /// an analog input with a waiting L, a missing or negative P/E; then Kerf's range
    /// checks, then the cutter compensation.
    fn input_wait(&self, blk: &Block, col: u32, line: u32) -> Result<Event, BlockError> {
        let l = match blk.get(KL) {
            None => None,
            Some(l) if l < 0.0 => return fail(blk.col(KL), "Negative l word used"),
            Some(l) => match integer(l) {
                Some(l) => Some(l),
                None => return fail(blk.col(KL), "Non integer value for integer"),
            },
        };
        let (p, e) = (blk.get(KP), blk.get(KE));
        if p.is_some() && e.is_some() {
            return fail(
                blk.col(KE),
                "Invalid to select both a digital and an analog input with M66",
            );
        }
        if let Some(l) = l
            && l > 0.0
            && blk.get(KQ).is_none_or(|q| q <= 0.0)
        {
            let at = if blk.has(KQ) {
                blk.col(KQ)
            } else {
                blk.col(KL)
            };
            return fail(at, "Zero timeout with wait type != immediate return");
        }
        if e.is_some()
            && let Some(l) = l
            && l != 0.0
        {
            return fail(
                blk.col(KL),
                "Can't select analog input with wait type != immediate return",
            );
        }
        let (word, number) = match (p, e) {
            (Some(p), _) => (KP, p),
            (_, Some(e)) => (KE, e),
            _ => {
                return fail(
                    col,
                    "Need to have either a valid P or a valid E word with M66",
                );
            }
        };
        if number.round() < 0.0 {
            return fail(
                blk.col(word),
                "Need to have either a valid P or a valid E word with M66",
            );
        }
        let analog = word == KE;
        let Some(n) = integer(number) else {
            return fail(
                blk.col(word),
                format!(
                    "Need to have either a valid P or a valid E word with M66: the input number is a whole number from 0 to {MAX_IO_NUMBER}"
                ),
            );
        };
        if n > f64::from(MAX_IO_NUMBER) {
            return fail(
                blk.col(word),
                if analog {
                    "Analog input selected out of bounds"
                } else {
                    "Digital input selected out of bounds"
                },
            );
        }
        let l = l.unwrap_or(0.0);
        if l > 4.0 {
            return fail(
                blk.col(KL),
                format!(
                    "Invalid wait mode L{l} with M66: L0 immediate, L1 rise, L2 fall, L3 high, L4 low"
                ),
            );
        }
        self.comp_refuse(
            col,
            if analog {
                "Cannot wait for analog input with cutter radius compensation on"
            } else {
                "Cannot wait for digital input with cutter radius compensation on"
            },
        )?;
        let code = if analog {
            EventCode::M66Analog
        } else {
            EventCode::M66
        };
        let mut event = Event::new(line, code, Some(n));
        event.p = Some(l);
        // rs274's timeout: Q when above zero, else none.
        event.q = blk.get(KQ).map(|q| q.max(0.0));
        Ok(event)
    }
}

/// `v` rounded when it is an integer within LinuxCNC's tolerance.
fn integer(v: f64) -> Option<f64> {
    let r = v.round();
    ((v - r).abs() <= INTEGER_TOLERANCE).then_some(r)
}

/// An input or output number: a whole number from 0 to [`MAX_IO_NUMBER`].
fn io_number(v: f64) -> Option<f64> {
    integer(v).filter(|n| (0.0..=f64::from(MAX_IO_NUMBER)).contains(n))
}

#[cfg(test)]
mod tests;
