//! The machine model's configuration: plain data, built from the TOML file by
//! `kerf-config`, checked once by [`MachineConfig::check`] (which
//! [`Machine::new`](super::Machine::new) calls).

use super::io::{ANALOG_IO, DIGITAL_IO};

/// Whether the spindle or a coolant output is switched off when a program ends (M2, M30),
/// is aborted, or a fault stops it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OffPolicy {
    /// Off at M2/M30 (LinuxCNC: always).
    pub at_end: bool,
    /// Off when the program is aborted.
    pub at_abort: bool,
    /// Off when a fault drops the program.
    pub at_fault: bool,
}

impl Default for OffPolicy {
    /// Off in every case, as LinuxCNC does.
    fn default() -> Self {
        OffPolicy {
            at_end: true,
            at_abort: true,
            at_fault: true,
        }
    }
}

/// The spindle switched by digital outputs plus an analog speed output (a VFD with its
/// own ramp, or a router switched on and off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpindleOutputs {
    /// Digital output on while the spindle is commanded to turn (M3 or M4).
    pub enable_output: u8,
    /// Digital output on while the spindle is commanded counter-clockwise (M4); `None`
    /// for a spindle that turns one way.
    pub reverse_output: Option<u8>,
    /// Analog output that gets the commanded speed (after override and clamping) times
    /// `speed_units_per_rpm`; `None` for a fixed-speed spindle.
    pub speed_output: Option<u8>,
    /// Scale of the speed output, output units (e.g. volts) per rpm.
    pub speed_units_per_rpm: f64,
    /// Digital input that is on while the spindle is at speed (a VFD's "at frequency"
    /// relay); `None`: the spindle counts as at speed `spin_up_s` after the last change.
    pub at_speed_input: Option<u8>,
    /// Time the spindle takes to reach a new speed (and to come to rest), s.
    pub spin_up_s: f64,
}

/// How the spindle is driven.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpindleKind {
    /// A drive in cyclic synchronous velocity mode: the machine ramps the velocity
    /// setpoint at `acceleration_rpm_s` ([`Machine::spindle_velocity_setpoint_rpm`]).
    /// `simulated`: the machine's own simulated spindle drive follows the setpoint (and
    /// can be stalled, [`Machine::inject_spindle_stall`]); otherwise the fieldbus sends
    /// the setpoint to the drive and reports its actual speed every cycle
    /// ([`Machine::set_spindle_actual_rpm`]).
    ///
    /// [`Machine::spindle_velocity_setpoint_rpm`]: super::Machine::spindle_velocity_setpoint_rpm
    /// [`Machine::inject_spindle_stall`]: super::Machine::inject_spindle_stall
    /// [`Machine::set_spindle_actual_rpm`]: super::Machine::set_spindle_actual_rpm
    Drive {
        /// The simulated spindle drive rather than a fieldbus drive.
        simulated: bool,
    },
    /// Digital enable and direction outputs and an analog speed output.
    Outputs(SpindleOutputs),
}

/// The spindle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpindleConfig {
    /// How it is driven.
    pub kind: SpindleKind,
    /// Highest speed, rpm: faster commands are clamped to it.
    pub max_rpm: f64,
    /// Lowest speed while turning, rpm: slower commands (but not 0) are raised to it.
    pub min_rpm: f64,
    /// Acceleration of the velocity ramp (drive kind), rpm/s.
    pub acceleration_rpm_s: f64,
    /// At-speed band as a fraction of the commanded speed (0.02: ±2 %).
    pub at_speed_tolerance: f64,
    /// Most time a feed move waits for the spindle to reach speed (and a tool change for
    /// it to stop) before the machine faults, s.
    pub at_speed_timeout_s: f64,
    /// A spindle that leaves its band while the motion feeds (after it was at speed
    /// since the last change) is a fault, as a broken belt would be.
    pub fault_out_of_band: bool,
    /// Most time an orient (M19) without a Q word may take, s.
    pub orient_timeout_s: f64,
    /// When the spindle is switched off.
    pub off: OffPolicy,
}

/// A coolant output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoolantOutput {
    /// Digital output number.
    pub output: u8,
    /// When it is switched off.
    pub off: OffPolicy,
}

/// The coolant outputs (each optional).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CoolantConfig {
    /// Mist (M7).
    pub mist: Option<CoolantOutput>,
    /// Flood (M8).
    pub flood: Option<CoolantOutput>,
}

/// Which inputs and outputs exist, and how the inputs are fed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IoConfig {
    /// Bit n set: digital output n exists (0–63).
    pub digital_outputs: u64,
    /// Bit n set: digital input n exists (0–63).
    pub digital_inputs: u64,
    /// Bit n set: analog output n exists (0–15).
    pub analog_outputs: u16,
    /// Bit n set: analog input n exists (0–15).
    pub analog_inputs: u16,
    /// The inputs are simulated (no fieldbus feeds them): set by
    /// [`Machine::set_input_digital`](super::Machine::set_input_digital) and
    /// [`Machine::set_input_analog`](super::Machine::set_input_analog), and by the
    /// machine's simulations of the tool changer's answer and a VFD's at-speed signal.
    /// Otherwise the fieldbus writes them every cycle
    /// ([`Machine::set_bus_inputs`](super::Machine::set_bus_inputs)).
    pub simulated_inputs: bool,
    /// Simulated digital inputs at start (bits of inputs that do not exist are ignored).
    pub initial_digital_inputs: u64,
    /// Simulated analog inputs at start.
    pub initial_analog_inputs: [f64; ANALOG_IO],
}

impl Default for IoConfig {
    /// No inputs or outputs, simulated.
    fn default() -> Self {
        IoConfig {
            digital_outputs: 0,
            digital_inputs: 0,
            analog_outputs: 0,
            analog_inputs: 0,
            simulated_inputs: true,
            initial_digital_inputs: 0,
            initial_analog_inputs: [0.0; ANALOG_IO],
        }
    }
}

impl IoConfig {
    /// Simulated I/O with the first `digital_outputs`, `digital_inputs`, `analog_outputs`
    /// and `analog_inputs` of each kind (counts above 64 or 16 are cut to them).
    pub fn counts(
        digital_outputs: u32,
        digital_inputs: u32,
        analog_outputs: u32,
        analog_inputs: u32,
    ) -> Self {
        IoConfig {
            digital_outputs: low_bits_u64(digital_outputs),
            digital_inputs: low_bits_u64(digital_inputs),
            analog_outputs: low_bits_u64(analog_outputs.min(ANALOG_IO as u32)) as u16,
            analog_inputs: low_bits_u64(analog_inputs.min(ANALOG_IO as u32)) as u16,
            ..IoConfig::default()
        }
    }

    /// `true` if digital output `n` exists.
    pub fn has_digital_output(&self, n: u8) -> bool {
        has_bit(self.digital_outputs, n, DIGITAL_IO)
    }

    /// `true` if digital input `n` exists.
    pub fn has_digital_input(&self, n: u8) -> bool {
        has_bit(self.digital_inputs, n, DIGITAL_IO)
    }

    /// `true` if analog output `n` exists.
    pub fn has_analog_output(&self, n: u8) -> bool {
        has_bit(u64::from(self.analog_outputs), n, ANALOG_IO)
    }

    /// `true` if analog input `n` exists.
    pub fn has_analog_input(&self, n: u8) -> bool {
        has_bit(u64::from(self.analog_inputs), n, ANALOG_IO)
    }
}

fn low_bits_u64(count: u32) -> u64 {
    if count >= 64 {
        u64::MAX
    } else {
        (1u64 << count) - 1
    }
}

fn has_bit(mask: u64, n: u8, size: usize) -> bool {
    usize::from(n) < size && mask & (1u64 << n) != 0
}

/// The tool changer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum ToolChanger {
    /// The operator changes the tool: M6 pauses until cycle start.
    #[default]
    Manual,
    /// A handshake as LinuxCNC's iocontrol: the tool number on an analog output, a change
    /// request on a digital output, the changer's answer on a digital input.
    Automatic(AutomaticChanger),
    /// No tool changer (the planner refuses M6 before motion).
    None,
}

/// The automatic tool changer's handshake.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutomaticChanger {
    /// Analog output that gets the tool number.
    pub number_output: u8,
    /// Digital output: the change request (LinuxCNC's `tool-change`).
    pub change_output: u8,
    /// Digital input: the change is done (LinuxCNC's `tool-changed`).
    pub changed_input: u8,
    /// Most time the change may take, s: then the machine faults.
    pub timeout_s: f64,
    /// With simulated inputs: the simulated changer answers this long after the request,
    /// s (the configuration's default is [`DEFAULT_SIM_CHANGE_S`]).
    pub sim_change_s: f64,
}

/// The simulated tool changer's change time unless configured, s.
pub const DEFAULT_SIM_CHANGE_S: f64 = 2.0;

/// The runtime switches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Switches {
    /// M1 pauses.
    pub optional_stop: bool,
    /// The program pauses after every block (acted on by the planner side).
    pub single_block: bool,
    /// Lines starting with `/` are skipped (acted on by the interpreter).
    pub block_delete: bool,
}

/// The machine model's configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineConfig {
    /// The cycle period, s.
    pub period_s: f64,
    /// The spindle, if the machine has one.
    pub spindle: Option<SpindleConfig>,
    /// The coolant outputs.
    pub coolant: CoolantConfig,
    /// The inputs and outputs.
    pub io: IoConfig,
    /// The tool changer.
    pub tool_changer: ToolChanger,
    /// The switches at start.
    pub switches: Switches,
    /// The tool in the spindle at start (0: none).
    pub tool_in_spindle: u32,
}

impl MachineConfig {
    /// A machine without spindle, coolant or I/O, with a manual tool changer, the
    /// switches off and no tool in the spindle.
    pub fn new(period_s: f64) -> Self {
        MachineConfig {
            period_s,
            spindle: None,
            coolant: CoolantConfig::default(),
            io: IoConfig::default(),
            tool_changer: ToolChanger::Manual,
            switches: Switches::default(),
            tool_in_spindle: 0,
        }
    }

    /// Checks the configuration: a positive period, positive limits and times, every
    /// input and output it names existing in `io`, and no output named twice.
    pub fn check(&self) -> Result<(), MachineConfigError> {
        use MachineConfigError as E;
        if !(self.period_s.is_finite() && self.period_s > 0.0) {
            return Err(E::Period(self.period_s));
        }
        let io = &self.io;
        // Outputs taken so far: each serves one purpose.
        let taken = core::cell::Cell::new((0u64, 0u64));
        let dout = |what, n| {
            if !io.has_digital_output(n) {
                return Err(E::NoDigitalOutput { what, output: n });
            }
            let (digital, analog) = taken.get();
            if digital & (1 << n) != 0 {
                return Err(E::OutputTwice {
                    what,
                    analog: false,
                    output: n,
                });
            }
            taken.set((digital | 1 << n, analog));
            Ok(())
        };
        let din = |what, n| {
            if io.has_digital_input(n) {
                Ok(())
            } else {
                Err(E::NoDigitalInput { what, input: n })
            }
        };
        let aout = |what, n| {
            if !io.has_analog_output(n) {
                return Err(E::NoAnalogOutput { what, output: n });
            }
            let (digital, analog) = taken.get();
            if analog & (1 << n) != 0 {
                return Err(E::OutputTwice {
                    what,
                    analog: true,
                    output: n,
                });
            }
            taken.set((digital, analog | 1 << n));
            Ok(())
        };
        let positive = |what, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(E::Value { what, value })
            }
        };
        if let Some(s) = &self.spindle {
            positive("spindle max_rpm", s.max_rpm)?;
            if !(s.min_rpm.is_finite() && s.min_rpm >= 0.0 && s.min_rpm <= s.max_rpm) {
                return Err(E::Value {
                    what: "spindle min_rpm (0 to max_rpm)",
                    value: s.min_rpm,
                });
            }
            positive("spindle acceleration_rpm_s", s.acceleration_rpm_s)?;
            if !(s.at_speed_tolerance.is_finite()
                && s.at_speed_tolerance > 0.0
                && s.at_speed_tolerance < 1.0)
            {
                return Err(E::Value {
                    what: "spindle at_speed_tolerance (above 0, below 1)",
                    value: s.at_speed_tolerance,
                });
            }
            positive("spindle at_speed_timeout_s", s.at_speed_timeout_s)?;
            positive("spindle orient_timeout_s", s.orient_timeout_s)?;
            if let SpindleKind::Outputs(o) = &s.kind {
                dout("spindle enable", o.enable_output)?;
                if let Some(n) = o.reverse_output {
                    dout("spindle reverse", n)?;
                }
                if let Some(n) = o.speed_output {
                    aout("spindle speed", n)?;
                    positive("spindle speed_units_per_rpm", o.speed_units_per_rpm)?;
                }
                if let Some(n) = o.at_speed_input {
                    din("spindle at-speed", n)?;
                }
                if !(o.spin_up_s.is_finite() && o.spin_up_s >= 0.0) {
                    return Err(E::Value {
                        what: "spindle spin_up_s",
                        value: o.spin_up_s,
                    });
                }
            }
        }
        if let Some(c) = &self.coolant.mist {
            dout("mist coolant", c.output)?;
        }
        if let Some(c) = &self.coolant.flood {
            dout("flood coolant", c.output)?;
        }
        if let ToolChanger::Automatic(a) = &self.tool_changer {
            aout("tool changer tool number", a.number_output)?;
            dout("tool changer change request", a.change_output)?;
            din("tool changer change done", a.changed_input)?;
            positive("tool changer timeout_s", a.timeout_s)?;
            positive("tool changer sim_change_s", a.sim_change_s)?;
        }
        if let Some(i) = io.initial_analog_inputs.iter().position(|v| !v.is_finite()) {
            return Err(E::Value {
                what: "initial analog input",
                value: io.initial_analog_inputs[i],
            });
        }
        Ok(())
    }
}

/// A configuration [`Machine::new`](super::Machine::new) refuses.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MachineConfigError {
    /// The period is not a positive finite number.
    #[error("machine: the cycle period must be positive, got {0} s")]
    Period(f64),
    /// A value out of its range.
    #[error("machine: {what} out of range: {value}")]
    Value {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A digital output that the I/O does not have.
    #[error("machine: the {what} output is digital output {output}, which does not exist")]
    NoDigitalOutput {
        /// What it is for.
        what: &'static str,
        /// Its number.
        output: u8,
    },
    /// A digital input that the I/O does not have.
    #[error("machine: the {what} input is digital input {input}, which does not exist")]
    NoDigitalInput {
        /// What it is for.
        what: &'static str,
        /// Its number.
        input: u8,
    },
    /// An output given two purposes (the spindle's, the coolant's, the changer's).
    #[error(
        "machine: the {what} output is {} output {output}, which another setting already uses",
        if *analog { "analog" } else { "digital" }
    )]
    OutputTwice {
        /// The second purpose.
        what: &'static str,
        /// An analog output.
        analog: bool,
        /// Its number.
        output: u8,
    },
    /// An analog output that the I/O does not have.
    #[error("machine: the {what} output is analog output {output}, which does not exist")]
    NoAnalogOutput {
        /// What it is for.
        what: &'static str,
        /// Its number.
        output: u8,
    },
}
