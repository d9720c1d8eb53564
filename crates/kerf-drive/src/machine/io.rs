//! The I/O image: the machine's digital and analog outputs and inputs as one `Copy`
//! record, which the fieldbus copies to and from its process data every cycle.

/// Digital inputs and outputs, each: numbers 0–63.
pub const DIGITAL_IO: usize = 64;

/// Analog inputs and outputs, each: numbers 0–15.
pub const ANALOG_IO: usize = 16;

/// The machine's outputs and inputs. Bits and values of inputs or outputs that do not
/// exist stay 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IoImage {
    /// Digital outputs, bit n = output n.
    pub digital_outputs: u64,
    /// Digital inputs, bit n = input n.
    pub digital_inputs: u64,
    /// Analog outputs.
    pub analog_outputs: [f64; ANALOG_IO],
    /// Analog inputs.
    pub analog_inputs: [f64; ANALOG_IO],
}

impl Default for IoImage {
    /// Everything off and 0.
    fn default() -> Self {
        IoImage {
            digital_outputs: 0,
            digital_inputs: 0,
            analog_outputs: [0.0; ANALOG_IO],
            analog_inputs: [0.0; ANALOG_IO],
        }
    }
}

impl IoImage {
    /// Digital output `n` (off for a number above 63).
    pub fn digital_output(&self, n: u8) -> bool {
        bit(self.digital_outputs, n)
    }

    /// Digital input `n` (off for a number above 63).
    pub fn digital_input(&self, n: u8) -> bool {
        bit(self.digital_inputs, n)
    }

    /// Analog output `n` (0 for a number above 15).
    pub fn analog_output(&self, n: u8) -> f64 {
        self.analog_outputs
            .get(usize::from(n))
            .copied()
            .unwrap_or(0.0)
    }

    /// Analog input `n` (0 for a number above 15).
    pub fn analog_input(&self, n: u8) -> f64 {
        self.analog_inputs
            .get(usize::from(n))
            .copied()
            .unwrap_or(0.0)
    }

    /// Sets digital output `n` (the caller checked that it exists).
    pub(crate) fn set_digital_output(&mut self, n: u8, on: bool) {
        set_bit(&mut self.digital_outputs, n, on);
    }

    /// Sets digital input `n` (the caller checked that it exists).
    pub(crate) fn set_digital_input(&mut self, n: u8, on: bool) {
        set_bit(&mut self.digital_inputs, n, on);
    }
}

fn bit(word: u64, n: u8) -> bool {
    usize::from(n) < DIGITAL_IO && word & (1u64 << n) != 0
}

fn set_bit(word: &mut u64, n: u8, on: bool) {
    if usize::from(n) < DIGITAL_IO {
        if on {
            *word |= 1u64 << n;
        } else {
            *word &= !(1u64 << n);
        }
    }
}

/// Why setting a simulated input was refused.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum InputError {
    /// No digital input with this number.
    #[error("digital input {0} does not exist")]
    NoDigitalInput(u8),
    /// No analog input with this number.
    #[error("analog input {0} does not exist")]
    NoAnalogInput(u8),
    /// The value is not finite.
    #[error("analog input {input}: the value {value} is not a number")]
    NotFinite {
        /// The input.
        input: u8,
        /// The value.
        value: f64,
    },
    /// The inputs come from the fieldbus, not from the simulation.
    #[error("the inputs are not simulated: they come from the fieldbus")]
    NotSimulated,
    /// The input is driven by one of the machine's own simulations (the tool changer's
    /// answer, the spindle's at-speed signal).
    #[error("digital input {input} is the simulated {what}: the simulation sets it")]
    Simulated {
        /// The input.
        input: u8,
        /// What drives it.
        what: &'static str,
    },
}
