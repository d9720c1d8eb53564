//! The machine's functions besides the axes, as plain records: the inputs and outputs
//! programs and the machine use (`[io]`), the spindle (`[spindle]`), coolant
//! (`[coolant]`), the tool changer (`[tool_changer]`) and the operator's switches at
//! start (`[operator]`); and [`MachineCaps`], what a program may command on this machine,
//! for refusing a program before any motion.

use crate::Config;

/// Where a digital input or output is on the EtherCAT bus: a named bit of an
/// `[[ethercat.io]]` subdevice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusBit {
    /// The subdevice's ring position.
    pub position: u16,
    /// The bit in the subdevice's inputs (for an input) or outputs (for an output), from
    /// 0 at bit 0 of the first byte.
    pub bit: u16,
}

/// One digital output (`[[io.digital_outputs]]`), `M62`-`M65 P<number>`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DigitalOutput {
    /// `number`: 0 to 63, unique among the digital outputs.
    pub number: u8,
    /// `name`: unique over all of `[io]`.
    pub name: String,
    /// With `[ethercat]`: the output bit of that name; `None`: simulated.
    pub bus_bit: Option<BusBit>,
}

/// One digital input (`[[io.digital_inputs]]`), `M66 P<number>`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DigitalInput {
    /// `number`: 0 to 63, unique among the digital inputs.
    pub number: u8,
    /// `name`: unique over all of `[io]`.
    pub name: String,
    /// `sim`: the simulated input's value at start (false without `[ethercat]` when not
    /// given; always false with `[ethercat]`, where the key is refused).
    pub sim: bool,
    /// With `[ethercat]`: the input bit of that name; `None`: simulated.
    pub bus_bit: Option<BusBit>,
}

/// One analog output (`[[io.analog_outputs]]`), `M67`/`M68 E<number>`. Simulated only:
/// analog I/O on EtherCAT is refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnalogOutput {
    /// `number`: 0 to 15, unique among the analog outputs.
    pub number: u8,
    /// `name`: unique over all of `[io]`.
    pub name: String,
}

/// One analog input (`[[io.analog_inputs]]`), `M66 E<number>`. Simulated only.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalogInput {
    /// `number`: 0 to 15, unique among the analog inputs.
    pub number: u8,
    /// `name`: unique over all of `[io]`.
    pub name: String,
    /// `sim`: the simulated input's value at start (0 when not given).
    pub sim: f64,
}

/// `[io]`: the machine's inputs and outputs, each list in ascending `number`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IoConfig {
    /// `digital_outputs`.
    pub digital_outputs: Vec<DigitalOutput>,
    /// `digital_inputs`.
    pub digital_inputs: Vec<DigitalInput>,
    /// `analog_outputs`.
    pub analog_outputs: Vec<AnalogOutput>,
    /// `analog_inputs`.
    pub analog_inputs: Vec<AnalogInput>,
}

impl IoConfig {
    /// The digital output named `name`.
    pub fn digital_output(&self, name: &str) -> Option<&DigitalOutput> {
        self.digital_outputs.iter().find(|o| o.name == name)
    }

    /// The digital input named `name`.
    pub fn digital_input(&self, name: &str) -> Option<&DigitalInput> {
        self.digital_inputs.iter().find(|o| o.name == name)
    }

    /// The analog output named `name`.
    pub fn analog_output(&self, name: &str) -> Option<&AnalogOutput> {
        self.analog_outputs.iter().find(|o| o.name == name)
    }

    /// The analog input named `name`.
    pub fn analog_input(&self, name: &str) -> Option<&AnalogInput> {
        self.analog_inputs.iter().find(|o| o.name == name)
    }
}

/// An `[io]` entry a machine function uses, by name and by its number in its list (the
/// kind of list is the field's: a digital output, an analog output, ...).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IoRef {
    /// The entry's `name`.
    pub name: String,
    /// The entry's `number`.
    pub number: u8,
}

/// `[spindle]`.
#[derive(Clone, Debug, PartialEq)]
pub struct SpindleConfig {
    /// `kind` and the keys of that kind.
    pub kind: SpindleKind,
    /// `max_rpm`: the fastest speed; a program asking more is refused before motion.
    pub max_rpm: f64,
    /// `min_rpm`: below `max_rpm`; a commanded speed above 0 and below it runs at it.
    pub min_rpm: f64,
    /// `acceleration_rpm_s`: the simulated drive's ramp, and the ramp the at-speed timeout
    /// was checked against (`at_speed_timeout_s` > `max_rpm` / `acceleration_rpm_s`).
    pub acceleration_rpm_s: f64,
    /// `at_speed_tolerance`: the at-speed band, a fraction of the commanded speed.
    pub at_speed_tolerance: f64,
    /// `at_speed_timeout_s`: a feed move waits at most this long for at-speed, then
    /// faults.
    pub at_speed_timeout_s: f64,
    /// `fault_out_of_band`: leaving the band while feeding is a fault (a broken belt).
    pub fault_out_of_band: bool,
    /// `orient_timeout_s`: the wait of an `M19` without `Q`.
    pub orient_timeout_s: f64,
    /// `off_at_end`: `M2`/`M30` stop the spindle.
    pub off_at_end: bool,
    /// `off_at_abort`: an abort stops the spindle.
    pub off_at_abort: bool,
    /// `off_at_fault`: a fault sets the spindle command to 0.
    pub off_at_fault: bool,
}

/// `spindle.kind`.
#[derive(Clone, Debug, PartialEq)]
pub enum SpindleKind {
    /// `"drive"`: a drive in velocity mode; simulated, or the `[[ethercat.drives]]` with
    /// `axis = "s"` ([`crate::ethercat::EthercatConfig::spindle_drive`]) with `[ethercat]`.
    Drive(SpindleDrive),
    /// `"outputs"`: enable and reverse digital outputs and a speed analog output.
    Outputs(SpindleOutputs),
    /// `"none"`: the machine has no spindle; a program that starts it is refused.
    None,
}

/// The keys of a `"drive"` spindle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpindleDrive {
    /// `counts_per_rev`: the drive's velocity counts per revolution (its velocity in
    /// counts/s is rpm × `counts_per_rev` / 60).
    pub counts_per_rev: f64,
    /// Whether the drive is on the EtherCAT bus (`[ethercat]`), else simulated.
    pub on_bus: bool,
}

/// The keys of an `"outputs"` spindle; each names an `[io]` entry of the right type.
#[derive(Clone, Debug, PartialEq)]
pub struct SpindleOutputs {
    /// `enable_output`: a digital output, on while the spindle turns.
    pub enable_output: IoRef,
    /// `reverse_output`: a digital output, on while it turns counter-clockwise (`M4`).
    pub reverse_output: Option<IoRef>,
    /// `speed_output`: an analog output, written as rpm × `speed_output_scale`.
    pub speed_output: IoRef,
    /// `speed_output_scale`: analog units per rpm.
    pub speed_output_scale: f64,
    /// `at_speed_input`: a digital input, on when the spindle is at speed.
    pub at_speed_input: Option<IoRef>,
    /// `spin_up_s`: without `at_speed_input`, the spindle counts as at speed this long
    /// after a change.
    pub spin_up_s: f64,
}

impl Default for SpindleConfig {
    /// A simulated drive spindle with the documented defaults.
    fn default() -> Self {
        SpindleConfig {
            kind: SpindleKind::Drive(SpindleDrive {
                counts_per_rev: crate::DEFAULT_SPINDLE_COUNTS_PER_REV,
                on_bus: false,
            }),
            max_rpm: crate::DEFAULT_SPINDLE_MAX_RPM,
            min_rpm: crate::DEFAULT_SPINDLE_MIN_RPM,
            acceleration_rpm_s: crate::DEFAULT_SPINDLE_ACCELERATION_RPM_S,
            at_speed_tolerance: crate::DEFAULT_AT_SPEED_TOLERANCE,
            at_speed_timeout_s: crate::DEFAULT_AT_SPEED_TIMEOUT_S,
            fault_out_of_band: true,
            orient_timeout_s: crate::DEFAULT_ORIENT_TIMEOUT_S,
            off_at_end: true,
            off_at_abort: true,
            off_at_fault: true,
        }
    }
}

impl SpindleConfig {
    /// Whether the machine has a spindle (`kind` is not `"none"`).
    pub fn exists(&self) -> bool {
        !matches!(self.kind, SpindleKind::None)
    }
}

/// `[coolant]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CoolantConfig {
    /// `mist`: the digital output `M7` switches on; without it `M7` is refused.
    pub mist: Option<IoRef>,
    /// `flood`: the digital output `M8` switches on; without it `M8` is refused.
    pub flood: Option<IoRef>,
    /// `off_at_end`: `M2`/`M30` switch the coolant off.
    pub off_at_end: bool,
    /// `off_at_abort`: an abort switches it off.
    pub off_at_abort: bool,
    /// `off_at_fault`: a fault switches it off.
    pub off_at_fault: bool,
}

impl Default for CoolantConfig {
    /// No coolant outputs, everything off at end, abort and fault.
    fn default() -> Self {
        CoolantConfig {
            mist: None,
            flood: None,
            off_at_end: true,
            off_at_abort: true,
            off_at_fault: true,
        }
    }
}

/// `[tool_changer]`.
#[derive(Clone, Debug, PartialEq)]
pub enum ToolChanger {
    /// `"manual"`: `M6` pauses with "insert tool T…"; cycle start confirms.
    Manual,
    /// `"automatic"`: the output/input handshake.
    Automatic(AutomaticToolChanger),
    /// `"none"`: `M6` is refused before motion.
    None,
}

/// The keys of an `"automatic"` tool changer (LinuxCNC iocontrol's
/// `tool-prep-number`, `tool-change`, `tool-changed`).
#[derive(Clone, Debug, PartialEq)]
pub struct AutomaticToolChanger {
    /// `number_output`: the analog output carrying the tool number.
    pub number_output: IoRef,
    /// `change_output`: the digital output requesting the change.
    pub change_output: IoRef,
    /// `changed_input`: the digital input that says the change is done.
    pub changed_input: IoRef,
    /// `timeout_s`: the change faults when `changed_input` has not come on after this.
    pub timeout_s: f64,
}

impl Default for ToolChanger {
    /// `"manual"`.
    fn default() -> Self {
        ToolChanger::Manual
    }
}

impl ToolChanger {
    /// The kind, without its keys.
    pub fn kind(&self) -> ToolChangerKind {
        match self {
            ToolChanger::Manual => ToolChangerKind::Manual,
            ToolChanger::Automatic(_) => ToolChangerKind::Automatic,
            ToolChanger::None => ToolChangerKind::None,
        }
    }
}

/// `tool_changer.kind`, without its keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToolChangerKind {
    /// `"manual"`.
    Manual,
    /// `"automatic"`.
    Automatic,
    /// `"none"`.
    None,
}

/// `[operator]`: the runtime switches' values when the daemon starts. The block delete
/// switch's is `gcode.block_delete` ([`Config::block_delete`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OperatorConfig {
    /// `optional_stop`: `M1` pauses.
    pub optional_stop: bool,
    /// `single_block`: the program pauses after each block.
    pub single_block: bool,
}

impl Default for OperatorConfig {
    fn default() -> Self {
        OperatorConfig {
            optional_stop: crate::DEFAULT_OPTIONAL_STOP,
            single_block: crate::DEFAULT_SINGLE_BLOCK,
        }
    }
}

/// What a program may command on this machine ([`Config::machine_check`]), for refusing
/// it before any motion: plain copyable data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineCaps {
    /// `spindle.max_rpm` when the machine has a spindle; `None`: `M3`/`M4`/`M19` refused.
    pub spindle_max_rpm: Option<f64>,
    /// Whether the spindle can orient (`M19`): only the simulated drive does; a velocity
    /// drive on EtherCAT and a spindle on outputs have no position to stop at.
    pub spindle_orients: bool,
    /// Whether `M7` (mist) has an output.
    pub mist: bool,
    /// Whether `M8` (flood) has an output.
    pub flood: bool,
    /// The digital output numbers that exist: bit `n` set for output `n`.
    pub digital_outputs: u64,
    /// The digital input numbers that exist: bit `n` set for input `n`.
    pub digital_inputs: u64,
    /// The analog output numbers that exist: bit `n` set for output `n`.
    pub analog_outputs: u16,
    /// The analog input numbers that exist: bit `n` set for input `n`.
    pub analog_inputs: u16,
    /// The tool changer's kind (`None`: `M6` refused).
    pub tool_changer: ToolChangerKind,
}

impl MachineCaps {
    /// Whether digital output `n` (`M62`-`M65 P<n>`) exists.
    pub fn has_digital_output(&self, n: u32) -> bool {
        n < 64 && self.digital_outputs & (1 << n) != 0
    }

    /// Whether digital input `n` (`M66 P<n>`) exists.
    pub fn has_digital_input(&self, n: u32) -> bool {
        n < 64 && self.digital_inputs & (1 << n) != 0
    }

    /// Whether analog output `n` (`M67`/`M68 E<n>`) exists.
    pub fn has_analog_output(&self, n: u32) -> bool {
        n < 16 && self.analog_outputs & (1 << n) != 0
    }

    /// Whether analog input `n` (`M66 E<n>`) exists.
    pub fn has_analog_input(&self, n: u32) -> bool {
        n < 16 && self.analog_inputs & (1 << n) != 0
    }
}

impl Config {
    /// What a program may command on this machine: spindle, coolant, I/O numbers, tool
    /// changer.
    pub fn machine_check(&self) -> MachineCaps {
        fn mask<T>(list: &[T], number: impl Fn(&T) -> u8) -> u64 {
            list.iter().fold(0, |m, e| m | 1 << number(e))
        }
        let io = &self.io;
        MachineCaps {
            spindle_max_rpm: self.spindle.exists().then_some(self.spindle.max_rpm),
            spindle_orients: matches!(self.spindle.kind, SpindleKind::Drive(d) if !d.on_bus),
            mist: self.coolant.mist.is_some(),
            flood: self.coolant.flood.is_some(),
            digital_outputs: mask(&io.digital_outputs, |e| e.number),
            digital_inputs: mask(&io.digital_inputs, |e| e.number),
            // Analog numbers are at most 15: the masks fit in 16 bits.
            analog_outputs: mask(&io.analog_outputs, |e| e.number) as u16,
            analog_inputs: mask(&io.analog_inputs, |e| e.number) as u16,
            tool_changer: self.tool_changer.kind(),
        }
    }
}

impl MachineCaps {
    /// `Err` with the reason when this machine cannot do what event `e` asks (a spindle it
    /// does not have, a speed above its top speed, coolant or an input or output it has no
    /// wiring for, a tool change without a tool changer): such a program is refused before
    /// any motion.
    pub fn check_event(&self, e: &kerf_geom::Event) -> Result<(), String> {
        use kerf_geom::EventCode as C;
        let code = e.code.as_str();
        let number = e.value.unwrap_or(0.0);
        let n = if number >= 0.0 && number.fract() == 0.0 && number < 64.0 {
            number as u32
        } else {
            u32::MAX
        };
        let missing = |what: &str, key: &str| {
            Err(format!(
                "{code}{}: this machine has no {what} ({key})",
                match e.code {
                    C::M62 | C::M63 | C::M64 | C::M65 | C::M66 => format!(" P{number}"),
                    C::M66Analog | C::M67 | C::M68 => format!(" E{number}"),
                    _ => String::new(),
                }
            ))
        };
        match e.code {
            C::M3 | C::M4 | C::M19 if self.spindle_max_rpm.is_none() => {
                missing("spindle", "spindle.kind = \"none\"")
            }
            C::M19 if !self.spindle_orients => Err(
                "M19: this machine's spindle cannot orient: it is a velocity drive or switched by outputs, with no position to stop at (spindle.kind)"
                    .to_string(),
            ),
            C::S => match (self.spindle_max_rpm, e.value) {
                (Some(max), Some(rpm)) if rpm > max => Err(format!(
                    "S{rpm} is above the spindle's top speed, {max} rpm (spindle.max_rpm)"
                )),
                _ => Ok(()),
            },
            C::M7 if !self.mist => missing("mist coolant output", "coolant.mist"),
            C::M8 if !self.flood => missing("flood coolant output", "coolant.flood"),
            C::M6 if self.tool_changer == ToolChangerKind::None => {
                missing("tool changer", "tool_changer.kind = \"none\"")
            }
            C::M62 | C::M63 | C::M64 | C::M65 if !self.has_digital_output(n) => {
                missing(&format!("digital output {number}"), "[io] digital_outputs")
            }
            C::M66 if !self.has_digital_input(n) => {
                missing(&format!("digital input {number}"), "[io] digital_inputs")
            }
            C::M66Analog if !self.has_analog_input(n) => {
                missing(&format!("analog input {number}"), "[io] analog_inputs")
            }
            C::M67 | C::M68 if !self.has_analog_output(n) => {
                missing(&format!("analog output {number}"), "[io] analog_outputs")
            }
            _ => Ok(()),
        }
    }
}
