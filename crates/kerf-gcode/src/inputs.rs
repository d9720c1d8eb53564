//! The machine's inputs as a program sees them: where the answer to an `M66` wait comes
//! from when the program reads `#5399` ([`InputWait`]), and the offline answer
//! ([`SimulatedInputs`]) that `kerf plan` and `kerf sim` use.
//!
//! LinuxCNC's interpreter stops reading ahead after an `M66`: the next line is only read
//! when the motion queue has drained and the wait is over, and `#5399` then holds the
//! input's value (or -1 after a timeout). Kerf's interpreter hands the `M66` event on like
//! any other and reads on; only when a later line *reads* `#5399` while an `M66` is
//! outstanding does it ask its [`InputWait`], once, and keep the answer in `#5399` until
//! the next `M66` (or an assignment to `#5399`). A program that never reads `#5399` is
//! never held up; one that branches on it waits exactly where it must, since every item
//! before that line (the `M66` event included) has already been handed on.

use crate::{Event, EventCode};

/// The highest digital and analog input or output number a program may name (LinuxCNC's
/// compile-time limits `EMCMOT_MAX_DIO` and `EMCMOT_MAX_AIO` are 64 each). Whether the
/// machine has that input or output is the machine configuration's business.
pub const MAX_IO_NUMBER: u8 = 63;

/// Answers an `M66` wait when the program reads `#5399`.
///
/// `kerf run` gives the interpreter one that asks the daemon (which waits on the real
/// input); without one the interpreter answers from [`crate::Settings::simulated_inputs`].
pub trait InputWait {
    /// The value for `#5399` after the wait `event` asks for: the input's state (1 or 0)
    /// or an analog input's value, or -1 when the wait timed out. `event` is the `M66`
    /// event as the interpreter yielded it ([`EventCode::M66`] or
    /// [`EventCode::M66Analog`]: `value` the input number, `p` the wait mode L 0–4, `q`
    /// the timeout in seconds or `None`). Called at most once per `M66`, from the
    /// interpreter's thread, and may block until the machine answers. An `Err` stops the
    /// program with its message at the line that reads `#5399`.
    fn wait(&mut self, event: &Event) -> Result<f64, String>;
}

/// Inputs that hold fixed values: the offline answer to `M66`.
///
/// A simulated input never changes, so a wait ends at once or never: L0 (immediate) gives
/// the value; L3 (wait for high) gives 1 when the input is on and L4 (wait for low) 0 when
/// it is off, otherwise the wait times out (-1); L1 and L2 wait for an edge, which a
/// constant input never makes, so they time out (-1), as they would on a machine whose
/// input does not move. An analog input (L0 only) gives its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimulatedInputs {
    /// Digital inputs 0–63: bit n is input n (1 on, 0 off).
    pub digital: u64,
    /// Analog inputs 0–63, their values.
    pub analog: [f64; MAX_IO_NUMBER as usize + 1],
}

impl Default for SimulatedInputs {
    /// Every digital input off, every analog input 0.
    fn default() -> Self {
        SimulatedInputs {
            digital: 0,
            analog: [0.0; MAX_IO_NUMBER as usize + 1],
        }
    }
}

impl SimulatedInputs {
    /// The `#5399` value of the wait `event` on these inputs (see the type's rules).
    pub fn answer(&self, event: &Event) -> Result<f64, String> {
        let number = event
            .value
            .filter(|n| n.fract() == 0.0 && (0.0..=f64::from(MAX_IO_NUMBER)).contains(n))
            .ok_or_else(|| format!("no simulated input {:?}", event.value))?
            as usize;
        match event.code {
            EventCode::M66Analog => Ok(self.analog[number]),
            EventCode::M66 => {
                let on = self.digital >> number & 1 == 1;
                Ok(match (event.p.unwrap_or(0.0) as u32, on) {
                    (0, _) => f64::from(u8::from(on)),
                    (3, true) => 1.0,
                    (4, false) => 0.0,
                    _ => -1.0,
                })
            }
            other => Err(format!("{} is not a wait on an input", other.as_str())),
        }
    }
}

impl InputWait for SimulatedInputs {
    fn wait(&mut self, event: &Event) -> Result<f64, String> {
        self.answer(event)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m66(code: EventCode, input: f64, l: f64) -> Event {
        let mut e = Event::new(1, code, Some(input));
        e.p = Some(l);
        e.q = Some(2.0);
        e
    }

    #[test]
    fn a_constant_input_ends_a_wait_at_once_or_times_out() {
        let sim = SimulatedInputs {
            digital: 1 << 5,
            ..SimulatedInputs::default()
        };
        // Input 5 on, input 4 off. L0 reads the state.
        assert_eq!(sim.answer(&m66(EventCode::M66, 5.0, 0.0)), Ok(1.0));
        assert_eq!(sim.answer(&m66(EventCode::M66, 4.0, 0.0)), Ok(0.0));
        // No edge ever comes.
        for l in [1.0, 2.0] {
            assert_eq!(sim.answer(&m66(EventCode::M66, 5.0, l)), Ok(-1.0));
            assert_eq!(sim.answer(&m66(EventCode::M66, 4.0, l)), Ok(-1.0));
        }
        // High: met by the input that is on; low: by the one that is off.
        assert_eq!(sim.answer(&m66(EventCode::M66, 5.0, 3.0)), Ok(1.0));
        assert_eq!(sim.answer(&m66(EventCode::M66, 4.0, 3.0)), Ok(-1.0));
        assert_eq!(sim.answer(&m66(EventCode::M66, 4.0, 4.0)), Ok(0.0));
        assert_eq!(sim.answer(&m66(EventCode::M66, 5.0, 4.0)), Ok(-1.0));
    }

    #[test]
    fn an_analog_input_gives_its_value_and_bad_numbers_are_errors() {
        let mut sim = SimulatedInputs::default();
        sim.analog[63] = -2.5;
        assert_eq!(sim.answer(&m66(EventCode::M66Analog, 63.0, 0.0)), Ok(-2.5));
        assert_eq!(sim.answer(&m66(EventCode::M66Analog, 0.0, 0.0)), Ok(0.0));
        assert!(sim.answer(&m66(EventCode::M66, 64.0, 0.0)).is_err());
        assert!(sim.answer(&m66(EventCode::M66, 1.5, 0.0)).is_err());
        assert!(
            sim.answer(&Event::new(1, EventCode::M62, Some(1.0)))
                .is_err()
        );
    }
}
