//! The machine around the axes in the daemon: its model's configuration from the TOML file
//! ([`machine_config`]), the inputs an operator may set ([`SimInputs`]), the machine's
//! part of the status ([`fill_status`]), and the tool in the spindle kept across restarts
//! ([`load_tool`], [`save_tool`]).

use std::io::Write as _;
use std::path::Path;

use kerf_config::Config;
use kerf_drive::machine::{
    AutomaticChanger, CoolantConfig, CoolantOutput, DEFAULT_SIM_CHANGE_S, IoConfig, MachineConfig,
    MachineStatus, OffPolicy, PauseReason, SpindleConfig, SpindleKind, SpindleOutputs, Switches,
    ToolChanger,
};
use kerf_geom::machine::SpindleDir;
use kerf_proto::StatusMsg;

/// The machine model's configuration for `config`'s machine, with the tool in the spindle
/// from the state file (none when the file is missing).
pub fn machine_config(config: &Config) -> Result<MachineConfig, String> {
    let limits = kerf_config::machine_limits(config);
    let mut m = MachineConfig::new(limits.period_s);
    m.io = io_config(config);
    let s = &config.spindle;
    let off = |at_end, at_abort, at_fault| OffPolicy {
        at_end,
        at_abort,
        at_fault,
    };
    let kind = match &s.kind {
        kerf_config::SpindleKind::None => None,
        kerf_config::SpindleKind::Drive(d) => Some(SpindleKind::Drive {
            simulated: !d.on_bus,
        }),
        kerf_config::SpindleKind::Outputs(o) => Some(SpindleKind::Outputs(SpindleOutputs {
            enable_output: o.enable_output.number,
            reverse_output: o.reverse_output.as_ref().map(|r| r.number),
            speed_output: Some(o.speed_output.number),
            speed_units_per_rpm: o.speed_output_scale,
            at_speed_input: o.at_speed_input.as_ref().map(|r| r.number),
            spin_up_s: o.spin_up_s,
        })),
    };
    m.spindle = kind.map(|kind| SpindleConfig {
        kind,
        max_rpm: s.max_rpm,
        min_rpm: s.min_rpm,
        acceleration_rpm_s: s.acceleration_rpm_s,
        at_speed_tolerance: s.at_speed_tolerance,
        at_speed_timeout_s: s.at_speed_timeout_s,
        fault_out_of_band: s.fault_out_of_band,
        orient_timeout_s: s.orient_timeout_s,
        off: off(s.off_at_end, s.off_at_abort, s.off_at_fault),
    });
    let c = &config.coolant;
    let coolant_off = off(c.off_at_end, c.off_at_abort, c.off_at_fault);
    let output = |r: &Option<kerf_config::IoRef>| {
        r.as_ref().map(|r| CoolantOutput {
            output: r.number,
            off: coolant_off,
        })
    };
    m.coolant = CoolantConfig {
        mist: output(&c.mist),
        flood: output(&c.flood),
    };
    m.tool_changer = match &config.tool_changer {
        kerf_config::ToolChanger::Manual => ToolChanger::Manual,
        kerf_config::ToolChanger::None => ToolChanger::None,
        kerf_config::ToolChanger::Automatic(a) => ToolChanger::Automatic(AutomaticChanger {
            number_output: a.number_output.number,
            change_output: a.change_output.number,
            changed_input: a.changed_input.number,
            timeout_s: a.timeout_s,
            sim_change_s: DEFAULT_SIM_CHANGE_S,
        }),
    };
    m.switches = Switches {
        optional_stop: config.operator.optional_stop,
        single_block: config.operator.single_block,
        block_delete: config.block_delete,
    };
    m.tool_in_spindle = load_tool(&config.state_file())?;
    Ok(m)
}

/// Which inputs and outputs exist; the inputs are simulated unless they are on the bus.
fn io_config(config: &Config) -> IoConfig {
    let io = &config.io;
    let mut c = IoConfig::default();
    for o in &io.digital_outputs {
        c.digital_outputs |= 1 << o.number;
    }
    for i in &io.digital_inputs {
        c.digital_inputs |= 1 << i.number;
        if i.sim {
            c.initial_digital_inputs |= 1 << i.number;
        }
    }
    for o in &io.analog_outputs {
        c.analog_outputs |= 1 << o.number;
    }
    for i in &io.analog_inputs {
        c.analog_inputs |= 1 << i.number;
        c.initial_analog_inputs[usize::from(i.number)] = i.sim;
    }
    c.simulated_inputs = config.ethercat().is_none();
    c
}

/// The inputs an operator (or a test) may set with `kerf input`: the simulated ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimInputs {
    digital: u64,
    analog: u16,
    simulated: bool,
    /// Digital inputs the simulated axes drive (their home and limit switches).
    driven: u64,
}

impl SimInputs {
    /// The inputs of `config`'s machine.
    pub fn of(config: &Config) -> Self {
        let c = io_config(config);
        let mut driven = 0u64;
        for setup in config.axis_setups().iter().flatten() {
            for s in crate::worker::simulated_switches(setup)
                .into_iter()
                .flatten()
            {
                if s.input < 64 {
                    driven |= 1 << s.input;
                }
            }
        }
        SimInputs {
            digital: c.digital_inputs,
            analog: c.analog_inputs,
            simulated: c.simulated_inputs,
            driven,
        }
    }

    /// `Ok` when input `index` (analog or digital) exists and is simulated; else why not.
    pub fn check(&self, analog: bool, index: u32) -> Result<(), String> {
        let kind = if analog { "analog" } else { "digital" };
        let exists = if analog {
            index < 16 && self.analog & (1 << index) != 0
        } else {
            index < 64 && self.digital & (1 << index) != 0
        };
        if !exists {
            return Err(format!(
                "this machine has no {kind} input {index} (the configuration's [io] lists its inputs)"
            ));
        }
        if !self.simulated {
            return Err(format!(
                "{kind} input {index} is wired on the EtherCAT bus: only a simulated input can be set"
            ));
        }
        if !analog && self.driven & (1 << index) != 0 {
            return Err(format!(
                "digital input {index} is a simulated home or limit switch: it follows its axis's position ([axes.*.sim])"
            ));
        }
        Ok(())
    }
}

/// The machine's tool table as the status reports it: the configuration's tools with the
/// machine tool table file's entries (touched-off lengths) over them, read again when the
/// file changes.
pub struct ToolLengths {
    path: std::path::PathBuf,
    modified: Option<std::time::SystemTime>,
    tools: Vec<kerf_config::ToolEntry>,
}

impl ToolLengths {
    /// The table of `config`'s machine as it is now.
    pub fn of(config: &Config) -> ToolLengths {
        let mut t = ToolLengths {
            path: config.machine_tool_table(),
            modified: None,
            tools: config.tools.clone(),
        };
        t.refresh(config);
        t
    }

    /// Reads the table again when its file changed since the last read (a touch-off by
    /// `kerf tool`); a file that cannot be read keeps the table as it was.
    pub fn refresh(&mut self, config: &Config) {
        let modified = std::fs::metadata(&self.path)
            .and_then(|m| m.modified())
            .ok();
        if modified == self.modified {
            return;
        }
        self.modified = modified;
        match config.machine_tools() {
            Ok(tools) => self.tools = tools,
            Err(e) => tracing::warn!("the tool table: {e}; the status keeps the lengths it had"),
        }
    }

    /// The length of `tool` in the table, mm.
    pub fn length_mm(&self, tool: u32) -> Option<f64> {
        self.tools
            .iter()
            .find(|t| t.number == tool)
            .map(|t| t.length_mm)
    }
}

/// The machine's part of the status: the pause, switches, tool, spindle, coolant and I/O
/// from the cycle's report; `tool_length_mm` from the machine's tool table.
pub fn fill_status(msg: &mut StatusMsg, m: &MachineStatus, config: &Config, tools: &ToolLengths) {
    let length_of = |tool: u32| tools.length_mm(tool);
    if let Some(p) = m.pause {
        msg.pause_line = p.line;
        let (reason, value) = match p.reason {
            PauseReason::ProgramStop => (kerf_proto::PAUSE_PROGRAM_STOP, 0),
            PauseReason::OptionalStop => (kerf_proto::PAUSE_OPTIONAL_STOP, 0),
            PauseReason::PalletChange => (kerf_proto::PAUSE_PALLET_CHANGE, 0),
            PauseReason::SingleBlock => (kerf_proto::PAUSE_SINGLE_BLOCK, 0),
            PauseReason::ToolChange { tool } => (kerf_proto::PAUSE_TOOL_CHANGE, tool),
            PauseReason::ToolChanging { tool } | PauseReason::SpindleStop { tool } => {
                (kerf_proto::PAUSE_TOOL_CHANGING, tool)
            }
            PauseReason::WaitInput { input, .. } => {
                (kerf_proto::PAUSE_WAIT_INPUT, u32::from(input))
            }
            PauseReason::AtSpeed => (kerf_proto::PAUSE_AT_SPEED, 0),
            PauseReason::Orient => (kerf_proto::PAUSE_ORIENT, 0),
        };
        msg.pause_reason = reason;
        msg.pause_value = value;
        match p.reason {
            PauseReason::ToolChange { tool } => msg.set_pause_text(&match length_of(tool) {
                Some(l) => format!("insert tool T{tool} (length {l:.3} mm)"),
                None if tool == 0 => "unload the spindle (T0)".to_string(),
                None => format!("insert tool T{tool} (not in the tool table)"),
            }),
            PauseReason::SpindleStop { tool } => {
                msg.set_pause_text(&format!("stopping the spindle to change to tool T{tool}"))
            }
            PauseReason::WaitInput { input, analog, .. } => msg.set_pause_text(&format!(
                "waiting on {} input {input} (M66)",
                if analog { "analog" } else { "digital" }
            )),
            _ => {}
        }
    }
    let sw = m.switches;
    let bit = |on: bool, bit: u32| if on { bit } else { 0 };
    msg.switches = bit(sw.optional_stop, kerf_proto::SWITCH_OPTIONAL_STOP)
        | bit(sw.block_delete, kerf_proto::SWITCH_BLOCK_DELETE)
        | bit(sw.single_block, kerf_proto::SWITCH_SINGLE_BLOCK);
    msg.tool_in_spindle = m.tool_in_spindle;
    msg.tool_length_mm = length_of(m.tool_in_spindle).unwrap_or(0.0);
    msg.tool_changer = match &config.tool_changer {
        kerf_config::ToolChanger::Manual => kerf_proto::TOOL_CHANGER_MANUAL,
        kerf_config::ToolChanger::Automatic(_) => kerf_proto::TOOL_CHANGER_AUTOMATIC,
        kerf_config::ToolChanger::None => kerf_proto::TOOL_CHANGER_NONE,
    };
    msg.overrides_enabled = bit(m.feed_override_enabled, kerf_proto::OVERRIDES_FEED);
    if let Some(s) = m.spindle {
        msg.spindle_kind = match config.spindle.kind {
            kerf_config::SpindleKind::Outputs(_) => kerf_proto::SPINDLE_OUTPUTS,
            _ => kerf_proto::SPINDLE_DRIVE,
        };
        let sign = s.dir.sign();
        msg.spindle_dir = match s.dir {
            SpindleDir::Cw => 1,
            SpindleDir::Ccw => -1,
            SpindleDir::Off => 0,
        };
        msg.spindle_programmed_rpm = s.programmed_rpm;
        msg.spindle_commanded_rpm = sign * s.commanded_rpm.abs();
        // A spindle on outputs has no feedback: its speed is the command once at speed.
        msg.spindle_actual_rpm = s.actual_rpm.unwrap_or(if s.at_speed {
            sign * s.commanded_rpm.abs()
        } else {
            0.0
        });
        msg.spindle_override_pct = s.override_pct;
        msg.spindle_at_speed = u32::from(s.at_speed);
        if s.override_enabled {
            msg.overrides_enabled |= kerf_proto::OVERRIDES_SPINDLE;
        }
    }
    msg.coolant = bit(m.coolant.mist, kerf_proto::COOLANT_MIST)
        | bit(m.coolant.flood, kerf_proto::COOLANT_FLOOD);
    msg.digital_outputs = m.io.digital_outputs;
    msg.digital_inputs = m.io.digital_inputs;
    msg.analog_outputs = m.io.analog_outputs;
    msg.analog_inputs = m.io.analog_inputs;
    if let Some(r) = m.last_input {
        msg.input_result_seq = r.seq;
        msg.input_result_line = r.line;
        msg.input_result_value = r.value;
    }
}

/// The tool in the spindle as the state file keeps it: `tool_in_spindle = N`; 0 when the
/// file does not exist (a new machine, or one whose spindle was never loaded).
pub fn load_tool(path: &Path) -> Result<u32, String> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => {
            return Err(format!(
                "{}: error: cannot read the machine's state: {e}",
                path.display()
            ));
        }
    };
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = || {
            format!(
                "{}:{}:1: error: expected `tool_in_spindle = N` (the daemon writes this file; remove it to start with an empty spindle)",
                path.display(),
                i + 1
            )
        };
        let (key, value) = line.split_once('=').ok_or_else(bad)?;
        if key.trim() != "tool_in_spindle" {
            return Err(bad());
        }
        return value.trim().parse::<u32>().map_err(|_| bad());
    }
    Ok(0)
}

/// Writes the state file with `tool` in the spindle, atomically: a temporary file beside
/// it, synced, then renamed over it (a crash leaves the old or the new file, never half).
pub fn save_tool(path: &Path, tool: u32) -> std::io::Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    if let Some(dir) = dir {
        std::fs::create_dir_all(dir)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    {
        let mut f = std::fs::File::create(&tmp)?;
        writeln!(
            f,
            "# The machine's state, kept by kerfd across restarts. Do not edit while it runs.\ntool_in_spindle = {tool}"
        )?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, path)?;
    if let Some(dir) = dir {
        // The rename itself is durable once the directory is synced.
        std::fs::File::open(dir)?.sync_all()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tool_in_the_spindle_survives_a_write_and_a_read() {
        let dir = std::env::temp_dir().join(format!("kerfd-state-{}", std::process::id()));
        let path = dir.join("machine.state");
        assert_eq!(load_tool(&path), Ok(0), "no file: an empty spindle");
        save_tool(&path, 7).unwrap();
        assert_eq!(load_tool(&path), Ok(7));
        save_tool(&path, 0).unwrap();
        assert_eq!(load_tool(&path), Ok(0));
        std::fs::write(&path, "tool_in_spindle = seven\n").unwrap();
        let e = load_tool(&path).unwrap_err();
        assert!(
            e.contains(":1:1: error: expected `tool_in_spindle = N`"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn only_configured_simulated_inputs_may_be_set() {
        let inputs = SimInputs {
            digital: 0b1101,
            analog: 0b1,
            simulated: true,
            driven: 0b1000,
        };
        // Input 3 is a simulated switch: it follows its axis, nobody sets it.
        assert!(
            inputs
                .check(false, 3)
                .unwrap_err()
                .contains("simulated home or limit switch")
        );
        assert_eq!(inputs.check(false, 0), Ok(()));
        assert_eq!(inputs.check(false, 2), Ok(()));
        assert!(
            inputs
                .check(false, 1)
                .unwrap_err()
                .contains("no digital input 1")
        );
        assert_eq!(inputs.check(true, 0), Ok(()));
        assert!(
            inputs
                .check(true, 1)
                .unwrap_err()
                .contains("no analog input 1")
        );
        let wired = SimInputs {
            simulated: false,
            ..inputs
        };
        assert!(wired.check(false, 0).unwrap_err().contains("EtherCAT"));
    }
}
