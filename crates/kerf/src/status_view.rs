//! The daemon's status in the shapes `kerf status` prints: one line, the EtherCAT block,
//! and the JSON object of `--json`.

use std::fmt::Write as _;

use kerf_proto::{MachineState, StatusMsg};

use kerfd::fault_text::check_name;

use crate::dro::Dro;

/// The name of a status state in `kerf status`.
pub(crate) fn state_name(s: &StatusMsg) -> &'static str {
    match s.state() {
        Ok(MachineState::Idle) => "idle",
        Ok(MachineState::Running) => "running",
        Ok(MachineState::Holding) => "holding",
        Ok(MachineState::Starved) => "starved",
        Ok(MachineState::Fault) => "fault",
        Ok(MachineState::Stopping) => "stopping",
        Ok(MachineState::Paused) => "paused",
        Ok(MachineState::Manual) => "manual",
        Err(_) => "unknown",
    }
}

const AXIS_KEYS: [&str; 6] = ["x", "y", "z", "a", "b", "c"];

/// The pause reason's name in `kerf status --json` (`none` when nothing).
pub fn pause_name(reason: u32) -> &'static str {
    match reason {
        kerf_proto::PAUSE_PROGRAM_STOP => "program_stop",
        kerf_proto::PAUSE_OPTIONAL_STOP => "optional_stop",
        kerf_proto::PAUSE_PALLET_CHANGE => "pallet_change",
        kerf_proto::PAUSE_SINGLE_BLOCK => "single_block",
        kerf_proto::PAUSE_TOOL_CHANGE => "tool_change",
        kerf_proto::PAUSE_TOOL_CHANGING => "tool_changing",
        kerf_proto::PAUSE_WAIT_INPUT => "wait_input",
        kerf_proto::PAUSE_AT_SPEED => "spindle_at_speed",
        kerf_proto::PAUSE_ORIENT => "spindle_orient",
        _ => "none",
    }
}

/// `true` when the pause waits for cycle start (`kerf resume`) rather than for the
/// machine.
pub fn pause_waits_for_operator(reason: u32) -> bool {
    matches!(
        reason,
        kerf_proto::PAUSE_PROGRAM_STOP
            | kerf_proto::PAUSE_OPTIONAL_STOP
            | kerf_proto::PAUSE_PALLET_CHANGE
            | kerf_proto::PAUSE_SINGLE_BLOCK
            | kerf_proto::PAUSE_TOOL_CHANGE
    )
}

/// What the program waits for, for a person: "paused at line 12 (M0, program stop):
/// `kerf resume` to continue", "paused at line 30 (M6): insert tool T3 (length 45.200 mm),
/// then `kerf resume`", "waiting at line 8 for the spindle to reach its speed"; `None`
/// when it waits for nothing.
pub fn pause_text(s: &StatusMsg) -> Option<String> {
    let line = s.pause_line;
    let resume = "`kerf resume` to continue";
    Some(match s.pause_reason {
        kerf_proto::PAUSE_PROGRAM_STOP => {
            format!("paused at line {line} (M0, program stop): {resume}")
        }
        kerf_proto::PAUSE_OPTIONAL_STOP => {
            format!("paused at line {line} (M1, optional stop): {resume}")
        }
        kerf_proto::PAUSE_PALLET_CHANGE => {
            format!("paused at line {line} (M60, pallet change): {resume}")
        }
        kerf_proto::PAUSE_SINGLE_BLOCK => {
            format!("paused after line {line} (single block): {resume}")
        }
        kerf_proto::PAUSE_TOOL_CHANGE => match s.pause_text() {
            "" => format!(
                "paused at line {line} (M6): insert tool T{}, then `kerf resume`",
                s.pause_value
            ),
            what => format!("paused at line {line} (M6): {what}, then `kerf resume`"),
        },
        kerf_proto::PAUSE_TOOL_CHANGING => {
            format!(
                "waiting at line {line} for the tool changer to load tool T{}",
                s.pause_value
            )
        }
        kerf_proto::PAUSE_WAIT_INPUT => {
            format!("waiting at line {line} for input {} (M66)", s.pause_value)
        }
        kerf_proto::PAUSE_AT_SPEED => {
            format!("waiting at line {line} for the spindle to reach its speed")
        }
        kerf_proto::PAUSE_ORIENT => {
            format!("waiting at line {line} for the spindle's orientation (M19)")
        }
        _ => return None,
    })
}

/// The numbers of the bits set in `bits`, comma-separated ("0,3"; "none").
fn bit_list(bits: u64) -> String {
    let on: Vec<String> = (0..64)
        .filter(|i| bits & (1 << i) != 0)
        .map(|i| i.to_string())
        .collect();
    if on.is_empty() {
        "none".to_string()
    } else {
        on.join(",")
    }
}

/// `kerf status`'s machine line: the spindle, coolant, tool, switches and I/O.
pub fn machine_text(s: &StatusMsg) -> String {
    let mut out = String::from("  spindle: ");
    if s.spindle_kind == kerf_proto::SPINDLE_NONE {
        out.push_str("none");
    } else {
        let dir = match s.spindle_dir {
            1 => "cw",
            -1 => "ccw",
            _ => "stopped",
        };
        let _ = write!(
            out,
            "{dir}, S{} → {:.0} rpm commanded, {:.0} rpm actual{}, override {} %{}",
            s.spindle_programmed_rpm,
            s.spindle_commanded_rpm,
            s.spindle_actual_rpm,
            if s.spindle_at_speed != 0 {
                ", at speed"
            } else {
                ""
            },
            s.spindle_override_pct,
            if s.overrides_enabled & kerf_proto::OVERRIDES_SPINDLE == 0 {
                " (disabled)"
            } else {
                ""
            }
        );
    }
    let coolant = match s.coolant & (kerf_proto::COOLANT_MIST | kerf_proto::COOLANT_FLOOD) {
        0 => "off",
        kerf_proto::COOLANT_MIST => "mist",
        kerf_proto::COOLANT_FLOOD => "flood",
        _ => "mist and flood",
    };
    let _ = write!(out, "; coolant: {coolant}; tool: ");
    match s.tool_in_spindle {
        0 => out.push_str("none"),
        t => {
            let _ = write!(out, "T{t} ({:.3} mm)", s.tool_length_mm);
        }
    }
    let on = |bit| if s.switches & bit != 0 { "on" } else { "off" };
    let _ = write!(
        out,
        "\n  switches: optional stop {}, block delete {}, single block {}; outputs on: {}; inputs on: {}",
        on(kerf_proto::SWITCH_OPTIONAL_STOP),
        on(kerf_proto::SWITCH_BLOCK_DELETE),
        on(kerf_proto::SWITCH_SINGLE_BLOCK),
        bit_list(s.digital_outputs),
        bit_list(s.digital_inputs)
    );
    out
}

/// The homing phase's name in `kerf status` (`none` when not homing).
pub fn home_phase_name(phase: u8) -> &'static str {
    match phase {
        kerf_proto::HOME_PHASE_WAITING => "waiting",
        kerf_proto::HOME_PHASE_MOVE_OFF => "move_off",
        kerf_proto::HOME_PHASE_SEARCH => "search",
        kerf_proto::HOME_PHASE_BACK_OFF => "back_off",
        kerf_proto::HOME_PHASE_LATCH => "latch",
        kerf_proto::HOME_PHASE_FINAL => "final",
        _ => "none",
    }
}

/// `kerf status`'s axes line: per axis homed or not (and the homing phase), jogging, and
/// the active home and limit switches.
pub fn axes_text(s: &StatusMsg) -> String {
    let mut out = String::from("  axes:");
    let mut first = true;
    for (i, key) in AXIS_KEYS.iter().enumerate() {
        let bit = 1u32 << i;
        if s.axes_mask & bit == 0 {
            continue;
        }
        out.push_str(if first { " " } else { "; " });
        first = false;
        let _ = write!(
            out,
            "{} {}",
            key.to_ascii_uppercase(),
            if s.homed & bit != 0 {
                "homed"
            } else {
                "not homed"
            }
        );
        if s.homing & bit != 0 {
            let _ = write!(out, ", homing ({})", home_phase_name(s.home_phase[i]));
        }
        if s.jogging & bit != 0 {
            out.push_str(", jogging");
        }
        if s.home_switches & bit != 0 {
            out.push_str(", home switch");
        }
        if s.min_limit_switches & bit != 0 {
            out.push_str(", lower limit switch");
        }
        if s.max_limit_switches & bit != 0 {
            out.push_str(", upper limit switch");
        }
        if s.limit_released & bit != 0 {
            out.push_str(" (jog off it)");
        }
    }
    if s.homing_required != 0 && s.homed & s.axes_mask != s.axes_mask & 0b11_1111 {
        out.push_str("; programs need every axis homed: `kerf home --all`");
    }
    out
}

/// The `axes` object of `kerf status --json` (with its leading comma): per configured
/// axis `homed`, `homing` (the phase's name, or null), `jogging`, `home_switch`,
/// `min_limit_switch`, `max_limit_switch`, `limit_released`; and `homing_required`.
fn axes_json(s: &StatusMsg) -> String {
    let mut out = format!(
        ",\"homing_required\":{},\"axes\":{{",
        s.homing_required != 0
    );
    let mut first = true;
    for (i, key) in AXIS_KEYS.iter().enumerate() {
        let bit = 1u32 << i;
        if s.axes_mask & bit == 0 {
            continue;
        }
        if !first {
            out.push(',');
        }
        first = false;
        let homing = if s.homing & bit != 0 {
            format!("\"{}\"", home_phase_name(s.home_phase[i]))
        } else {
            "null".to_string()
        };
        let _ = write!(
            out,
            "\"{key}\":{{\"homed\":{},\"homing\":{homing},\"jogging\":{},\"home_switch\":{},\"min_limit_switch\":{},\"max_limit_switch\":{},\"limit_released\":{}}}",
            s.homed & bit != 0,
            s.jogging & bit != 0,
            s.home_switches & bit != 0,
            s.min_limit_switches & bit != 0,
            s.max_limit_switches & bit != 0,
            s.limit_released & bit != 0
        );
    }
    out.push('}');
    out
}

/// The machine's objects of `kerf status --json`: `pause`, `switches`, `tool`, `spindle`,
/// `coolant`, `io`, `input_result` (each key with its leading comma).
fn machine_json(s: &StatusMsg, num: &dyn Fn(f64) -> String) -> String {
    let mut out = String::from(",\"pause\":");
    if s.pause_reason == kerf_proto::PAUSE_NONE {
        out.push_str("null");
    } else {
        let _ = write!(
            out,
            "{{\"reason\":\"{}\",\"line\":{},\"value\":{},\"waits_for_operator\":{},\"text\":{}}}",
            pause_name(s.pause_reason),
            s.pause_line,
            s.pause_value,
            pause_waits_for_operator(s.pause_reason),
            json_string(&pause_text(s).unwrap_or_default())
        );
    }
    let on = |bit| s.switches & bit != 0;
    let _ = write!(
        out,
        ",\"switches\":{{\"optional_stop\":{},\"block_delete\":{},\"single_block\":{}}}",
        on(kerf_proto::SWITCH_OPTIONAL_STOP),
        on(kerf_proto::SWITCH_BLOCK_DELETE),
        on(kerf_proto::SWITCH_SINGLE_BLOCK)
    );
    let changer = match s.tool_changer {
        kerf_proto::TOOL_CHANGER_MANUAL => "manual",
        kerf_proto::TOOL_CHANGER_AUTOMATIC => "automatic",
        _ => "none",
    };
    let _ = write!(
        out,
        ",\"tool\":{{\"in_spindle\":{},\"length_mm\":{},\"changer\":\"{changer}\"}}",
        s.tool_in_spindle,
        num(s.tool_length_mm)
    );
    out.push_str(",\"spindle\":");
    if s.spindle_kind == kerf_proto::SPINDLE_NONE {
        out.push_str("null");
    } else {
        let _ = write!(
            out,
            "{{\"kind\":\"{}\",\"dir\":{},\"programmed_rpm\":{},\"commanded_rpm\":{},\"actual_rpm\":{},\"at_speed\":{},\"override_pct\":{},\"override_enabled\":{}}}",
            if s.spindle_kind == kerf_proto::SPINDLE_DRIVE {
                "drive"
            } else {
                "outputs"
            },
            s.spindle_dir,
            num(s.spindle_programmed_rpm),
            num(s.spindle_commanded_rpm),
            num(s.spindle_actual_rpm),
            s.spindle_at_speed != 0,
            num(s.spindle_override_pct),
            s.overrides_enabled & kerf_proto::OVERRIDES_SPINDLE != 0
        );
    }
    let _ = write!(
        out,
        ",\"feed_override_enabled\":{},\"coolant\":{{\"mist\":{},\"flood\":{}}}",
        s.overrides_enabled & kerf_proto::OVERRIDES_FEED != 0,
        s.coolant & kerf_proto::COOLANT_MIST != 0,
        s.coolant & kerf_proto::COOLANT_FLOOD != 0
    );
    let list = |v: &[f64]| v.iter().map(|x| num(*x)).collect::<Vec<_>>().join(",");
    let _ = write!(
        out,
        ",\"io\":{{\"digital_outputs\":{},\"digital_inputs\":{},\"analog_outputs\":[{}],\"analog_inputs\":[{}]}}",
        s.digital_outputs,
        s.digital_inputs,
        list(&s.analog_outputs),
        list(&s.analog_inputs)
    );
    out.push_str(",\"input_result\":");
    if s.input_result_seq == 0 {
        out.push_str("null");
    } else {
        let _ = write!(
            out,
            "{{\"seq\":{},\"program_id\":{},\"line\":{},\"value\":{}}}",
            s.input_result_seq,
            s.input_result_program,
            s.input_result_line,
            num(s.input_result_value)
        );
    }
    out
}

/// The drive side's state by name: `enabling`, `running`, `holding`, `quick_stop`,
/// `stopped`, `resetting` (`none` for a status without one).
pub(crate) fn drives_name(s: &StatusMsg) -> &'static str {
    match s.drives {
        kerf_proto::DRIVES_ENABLING => "enabling",
        kerf_proto::DRIVES_RUNNING => "running",
        kerf_proto::DRIVES_HOLDING => "holding",
        kerf_proto::DRIVES_QUICK_STOP => "quick_stop",
        kerf_proto::DRIVES_STOPPED => "stopped",
        kerf_proto::DRIVES_RESETTING => "resetting",
        _ => "none",
    }
}

/// The names of the EtherCAT subdevices of `config` by ring position ("X drive", "I/O"),
/// as the daemon's messages name them, for [`status_text`] and [`status_json`]; an empty
/// name for a position the configuration does not list, none without `[ethercat]`.
pub fn subdevice_names(config: &kerf_config::Config) -> Vec<String> {
    let Some(ethercat) = config.ethercat() else {
        return Vec::new();
    };
    let expected = kerf_ethercat::bus::expected(ethercat);
    let len = expected
        .iter()
        .map(|e| usize::from(e.position) + 1)
        .max()
        .unwrap_or(0);
    let mut names = vec![String::new(); len];
    for e in expected {
        names[usize::from(e.position)] = e.name;
    }
    names
}

/// The AL state of a subdevice in the status by name ("OP", "SAFE-OP"); "unknown" for 0
/// or any value that is not an AL state.
fn bus_state_name(state: u8) -> &'static str {
    match state {
        kerf_proto::BUS_STATE_INIT
        | kerf_proto::BUS_STATE_PRE_OP
        | kerf_proto::BUS_STATE_BOOT
        | kerf_proto::BUS_STATE_SAFE_OP
        | kerf_proto::BUS_STATE_OP => kerf_ethercat::al::state_name(state),
        _ => "unknown",
    }
}

/// The name of the subdevice at `position`, if the configuration lists it.
fn subdevice_name(names: &[String], position: usize) -> Option<&str> {
    names
        .get(position)
        .map(String::as_str)
        .filter(|n| !n.is_empty())
}

/// The EtherCAT section of `kerf status --json`: `null` without a bus.
fn ethercat_json(names: &[String], s: &StatusMsg) -> String {
    let n = s.bus_positions();
    if n == 0 {
        return "null".to_string();
    }
    let mut out = String::from("{\"subdevices\":[");
    for position in 0..n {
        if position > 0 {
            out.push(',');
        }
        let name = subdevice_name(names, position).map_or("null".to_string(), json_string);
        let code = s.bus_al_codes[position];
        let words = if code == 0 {
            "null".to_string()
        } else {
            json_string(&kerf_ethercat::al::al_code_text(code))
        };
        let _ = write!(
            out,
            "{{\"position\":{position},\"name\":{name},\"state\":\"{}\",\"al_status_code\":{code},\"al_status\":{words}}}",
            bus_state_name(s.bus_states[position])
        );
    }
    let _ = write!(
        out,
        "],\"recovering\":{},\"cycles\":{{\"complete\":{},\"lost\":{},\"short\":{},\"not_op\":{},\"longest_gap\":{}}},\"dc\":",
        s.bus_recovering != 0,
        s.bus_cycles_complete,
        s.bus_cycles_lost,
        s.bus_cycles_short,
        s.bus_cycles_not_op,
        s.bus_longest_gap_cycles
    );
    if s.dc_used == 0 {
        out.push_str("null");
    } else {
        let _ = write!(
            out,
            "{{\"offset_ns\":{},\"offset_abs_ns\":{{\"p50\":{},\"p99\":{},\"p999\":{},\"max\":{}}},\"samples\":{}}}",
            s.dc_offset_ns,
            s.dc_offset_abs_p50_ns,
            s.dc_offset_abs_p99_ns,
            s.dc_offset_abs_p999_ns,
            s.dc_offset_abs_max_ns,
            s.dc_samples
        );
    }
    out.push('}');
    out
}

/// The DRO object of `kerf status --json`: the active system, the machine and work
/// positions and the offsets between them, per axis the machine has.
pub fn dro_json(d: &Dro, axes_mask: u32) -> String {
    let num = |v: f64| {
        let mut b = zmij::Buffer::new();
        if v.is_finite() {
            b.format(v).to_string()
        } else {
            "null".to_string()
        }
    };
    let axes = |v: &[f64; 6]| {
        let keys = AXIS_KEYS.iter().enumerate();
        let pairs: Vec<String> = keys
            .filter(|(i, _)| axes_mask & (1 << i) != 0)
            .map(|(i, k)| format!("\"{k}\":{}", num(v[i])))
            .collect();
        format!("{{{}}}", pairs.join(","))
    };
    format!(
        "{{\"system\":\"{}\",\"machine\":{},\"work\":{},\"work_offset\":{},\"rotation_deg\":{},\"g92\":{},\"tool\":{},\"tool_offset\":{}}}",
        crate::dro::system_name(d.system),
        axes(&d.machine_mm_deg),
        axes(&d.work_mm_deg),
        axes(&d.work_offset.offset_mm_deg),
        num(d.work_offset.rotation_deg),
        axes(&d.g92_mm_deg),
        d.tool,
        axes(&d.tool_offset_mm_deg)
    )
}

/// The DRO line of `kerf status`: `work G54 X 1.000 Y 2.000 Z 3.000`, then the offsets
/// in force (`G54 offset X … Y … Z …`, its rotation and G92 when not zero).
pub fn dro_text(d: &Dro, axes_mask: u32) -> String {
    let axes = |v: &[f64; 6]| {
        let mut out = String::new();
        for (i, key) in AXIS_KEYS.iter().enumerate() {
            if axes_mask & (1 << i) != 0 {
                let _ = write!(out, " {} {:.3}", key.to_ascii_uppercase(), v[i]);
            }
        }
        out
    };
    let name = crate::dro::system_name(d.system);
    let mut out = format!("work {name}{}", axes(&d.work_mm_deg));
    if d.system.is_some() {
        let _ = write!(out, "; {name} offset{}", axes(&d.work_offset.offset_mm_deg));
        if d.work_offset.rotation_deg != 0.0 {
            let _ = write!(out, ", rotation {} deg", d.work_offset.rotation_deg);
        }
    }
    if d.g92_mm_deg.iter().any(|v| *v != 0.0) {
        let _ = write!(out, "; G92{}", axes(&d.g92_mm_deg));
    }
    out
}

/// `kerf status --json`: one JSON object; `names` are the EtherCAT subdevices' names by
/// ring position ([`subdevice_names`]); `dro` the DRO (`null` when it could not be read).
pub fn status_json(machine: &str, names: &[String], s: &StatusMsg, dro: Option<&Dro>) -> String {
    let mut out = String::new();
    let num = |v: f64| {
        if v.is_finite() {
            let mut b = zmij::Buffer::new();
            b.format(v).to_string()
        } else {
            "null".to_string()
        }
    };
    let _ = write!(
        out,
        "{{\"machine\":{},\"state\":\"{}\",\"line\":{},\"position\":{{",
        json_string(machine),
        state_name(s),
        s.line
    );
    let mut first = true;
    for (i, key) in AXIS_KEYS.iter().enumerate() {
        if s.axes_mask & (1 << i) == 0 {
            continue;
        }
        if !first {
            out.push(',');
        }
        first = false;
        let _ = write!(out, "\"{key}\":{}", num(s.position_mm_deg[i]));
    }
    let fault = if s.fault != 0 {
        json_string(s.fault_text())
    } else {
        "null".to_string()
    };
    let _ = write!(
        out,
        "}},\"override_pct\":{},\"queued_moves\":{},\"queued_s\":{},\"cycles\":{},\"overruns\":{},\"rt\":{},\"fault\":{},\"program_id\":{},\"program_done\":{},\"program_end\":\"{}\",\"moves_received\":{},\"window_items\":{},\"rejected\":{},\"period_us\":{}}}",
        num(s.override_pct),
        s.queued_moves,
        num(s.queued_s),
        s.cycles,
        s.overruns,
        s.rt != 0,
        fault,
        s.program_id,
        s.program_done != 0,
        match s.program_end {
            kerf_proto::PROGRAM_END_FINISHED => "finished",
            kerf_proto::PROGRAM_END_ABORTED => "aborted",
            kerf_proto::PROGRAM_END_REFUSED => "refused",
            _ if s.program_id == 0 => "none",
            _ => "running",
        },
        s.moves_received,
        s.window_items,
        s.rejected,
        num(s.period_ns as f64 / 1000.0)
    );
    // The drive side, before the closing brace.
    out.pop();
    let _ = write!(out, ",\"drives\":\"{}\",\"safety\":", drives_name(s));
    match check_name(s.safety_check) {
        None => out.push_str("null"),
        Some(name) => {
            let axis = match AXIS_KEYS.get(s.safety_axis as usize) {
                Some(a) => format!("\"{a}\""),
                None => "null".to_string(),
            };
            let dump = match s.fault_dump() {
                "" => "null".to_string(),
                p => json_string(p),
            };
            let _ = write!(
                out,
                "{{\"check\":\"{name}\",\"axis\":{axis},\"value\":{},\"limit\":{},\"line\":{},\"cycle\":{},\"drive_error_code\":{},\"dump\":{dump}}}",
                num(s.safety_value),
                num(s.safety_limit),
                s.safety_line,
                s.safety_cycle,
                s.drive_error_code
            );
        }
    }
    out.push_str(&machine_json(s, &num));
    out.push_str(&axes_json(s));
    match dro {
        Some(d) => {
            let _ = write!(out, ",\"dro\":{}", dro_json(d, s.axes_mask));
        }
        None => out.push_str(",\"dro\":null"),
    }
    let _ = write!(out, ",\"ethercat\":{}", ethercat_json(names, s));
    out.push('}');
    out
}

/// `count word` with the word in the plural unless `count` is 1: "1 cycle", "2 cycles".
fn counted(count: u64, word: &str) -> String {
    if count == 1 {
        format!("1 {word}")
    } else {
        format!("{count} {word}s")
    }
}

/// A duration of the distributed clocks for a person: ns below 1 µs, else µs to 0.1.
fn dc_time(ns: u64) -> String {
    if ns < 1_000 {
        format!("{ns} ns")
    } else {
        format!("{:.1} µs", ns as f64 / 1_000.0)
    }
}

/// The EtherCAT block of `kerf status`, without a final newline: a summary line, one line
/// per subdevice and one for the distributed clocks; `None` without a bus.
pub fn ethercat_text(names: &[String], s: &StatusMsg) -> Option<String> {
    let n = s.bus_positions();
    if n == 0 {
        return None;
    }
    let states = &s.bus_states[..n];
    let not_op = states
        .iter()
        .filter(|&&st| st != kerf_proto::BUS_STATE_OP)
        .count();
    let mut out = format!("EtherCAT: {}, ", counted(n as u64, "subdevice"));
    match (not_op, n) {
        (0, 1) => out.push_str("in OP"),
        (0, _) => out.push_str("all in OP"),
        (k, _) => {
            let _ = write!(out, "{k} not in OP");
        }
    }
    // A lost bus answers nothing: its states are the last ones it sent.
    if s.safety_check == kerf_proto::SAFETY_FIELDBUS {
        out.push_str(" when last heard");
    }
    if s.bus_recovering != 0 {
        out.push_str(" (recovering)");
    }
    let _ = write!(
        out,
        "; {} exchanged, {} lost, {} short, {} out of OP, at most {} incomplete in a row",
        counted(s.bus_cycles_complete, "cycle"),
        s.bus_cycles_lost,
        s.bus_cycles_short,
        s.bus_cycles_not_op,
        s.bus_longest_gap_cycles
    );
    let position_width = (n - 1).to_string().len();
    let name_of = |p: usize| subdevice_name(names, p).unwrap_or("(not in the configuration)");
    let name_width = (0..n)
        .map(|p| name_of(p).chars().count())
        .max()
        .unwrap_or(0);
    for (position, &state) in states.iter().enumerate() {
        let _ = write!(
            out,
            "\n  {position:>position_width$}  {:<name_width$}  {}",
            name_of(position),
            bus_state_name(state)
        );
        let code = s.bus_al_codes[position];
        if code != 0 {
            let _ = write!(
                out,
                ", AL status code {}",
                kerf_ethercat::al::al_code_text(code)
            );
        }
    }
    out.push_str("\n  distributed clocks: ");
    if s.dc_used == 0 {
        out.push_str("not used");
    } else if s.dc_samples == 0 {
        out.push_str("no offset measured yet");
    } else {
        let sign = match s.dc_offset_ns {
            0 => "",
            o if o < 0 => "-",
            _ => "+",
        };
        let _ = write!(
            out,
            "cycle start vs SYNC0 offset now {sign}{}; |offset| p50 {}, p99 {}, p99.9 {}, max {} over {}",
            dc_time(s.dc_offset_ns.unsigned_abs()),
            dc_time(s.dc_offset_abs_p50_ns),
            dc_time(s.dc_offset_abs_p99_ns),
            dc_time(s.dc_offset_abs_p999_ns),
            dc_time(s.dc_offset_abs_max_ns),
            counted(s.dc_samples, "cycle")
        );
    }
    Some(out)
}

/// `kerf status`: [`status_line`], the DRO's line ([`dro_text`]), then the EtherCAT block
/// ([`ethercat_text`]) when the drives are on a bus; `names` as for [`status_json`].
pub fn status_text(machine: &str, names: &[String], s: &StatusMsg, dro: Option<&Dro>) -> String {
    let mut out = status_line(machine, s);
    if let Some(d) = dro {
        let _ = write!(out, "\n  {}", dro_text(d, s.axes_mask));
    }
    if let Some(pause) = pause_text(s) {
        let _ = write!(out, "\n  {pause}");
    }
    out.push('\n');
    out.push_str(&machine_text(s));
    out.push('\n');
    out.push_str(&axes_text(s));
    if let Some(block) = ethercat_text(names, s) {
        out.push('\n');
        out.push_str(&block);
    }
    out
}

/// `kerf status`: one line for a person (the machine, without the EtherCAT block).
pub fn status_line(machine: &str, s: &StatusMsg) -> String {
    let mut out = format!("{machine}: {}", state_name(s));
    // A pause names its own line on the next line (the setpoint's is the move before).
    if s.line != 0 && s.pause_reason == kerf_proto::PAUSE_NONE {
        let _ = write!(out, " at line {}", s.line);
    }
    out.push(',');
    for (i, key) in AXIS_KEYS.iter().enumerate() {
        if s.axes_mask & (1 << i) != 0 {
            let _ = write!(
                out,
                " {} {:.3}",
                key.to_ascii_uppercase(),
                s.position_mm_deg[i]
            );
        }
    }
    let _ = write!(
        out,
        ", override {} %, {} queued ({:.1} s), {} cycles, {} overruns, rt: {}",
        s.override_pct,
        s.queued_moves,
        s.queued_s,
        s.cycles,
        s.overruns,
        if s.rt != 0 { "yes" } else { "no" }
    );
    let _ = write!(out, ", drives: {}", drives_name(s));
    if s.fault != 0 {
        let _ = write!(out, ", fault: {}", s.fault_text());
    }
    if !s.fault_dump().is_empty() {
        let _ = write!(out, ", black box: {}", s.fault_dump());
    }
    out
}

fn json_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names() -> Vec<String> {
        ["X drive", "Y drive", "Z drive", "I/O"]
            .map(String::from)
            .to_vec()
    }

    /// An idle 3-axis machine whose 4 subdevices are all in OP, with distributed clocks.
    fn on_a_bus() -> StatusMsg {
        let mut s = StatusMsg::zeroed();
        s.state = kerf_proto::STATE_IDLE;
        s.axes_mask = 0b111;
        s.position_mm_deg = [1.0, 2.0, 3.0, 0.0, 0.0, 0.0];
        s.override_pct = 100.0;
        s.cycles = 123_460;
        s.rt = 1;
        s.period_ns = 1_000_000;
        s.drives = kerf_proto::DRIVES_RUNNING;
        s.bus_subdevices = 4;
        s.bus_states[..4].fill(kerf_proto::BUS_STATE_OP);
        s.bus_cycles_complete = 123_456;
        s.dc_used = 1;
        s.dc_offset_ns = 240;
        s.dc_offset_abs_p50_ns = 300;
        s.dc_offset_abs_p99_ns = 1_100;
        s.dc_offset_abs_p999_ns = 2_000;
        s.dc_offset_abs_max_ns = 3_400;
        s.dc_samples = 123_000;
        s
    }

    /// The same bus after the Y drive dropped to SAFE-OP with a sync manager watchdog,
    /// while a reset brings it back.
    fn y_drive_left_op() -> StatusMsg {
        let mut s = on_a_bus();
        s.bus_states[1] = kerf_proto::BUS_STATE_SAFE_OP;
        s.bus_al_codes[1] = 0x001B;
        s.bus_recovering = 1;
        s.bus_cycles_lost = 3;
        s.bus_cycles_short = 2;
        s.bus_cycles_not_op = 17;
        s.bus_longest_gap_cycles = 5;
        s.dc_offset_ns = -1_240;
        s
    }

    #[test]
    fn status_text_shows_the_bus_per_subdevice() {
        let text = status_text("m", &names(), &on_a_bus(), None);
        assert_eq!(
            text,
            "m: idle, X 1.000 Y 2.000 Z 3.000, override 100 %, 0 queued (0.0 s), 123460 cycles, 0 overruns, rt: yes, drives: running\n\
             \x20 spindle: none; coolant: off; tool: none\n\
             \x20 switches: optional stop off, block delete off, single block off; outputs on: none; inputs on: none\n\
             \x20 axes: X not homed; Y not homed; Z not homed\n\
             EtherCAT: 4 subdevices, all in OP; 123456 cycles exchanged, 0 lost, 0 short, 0 out of OP, at most 0 incomplete in a row\n\
             \x20 0  X drive  OP\n\
             \x20 1  Y drive  OP\n\
             \x20 2  Z drive  OP\n\
             \x20 3  I/O      OP\n\
             \x20 distributed clocks: cycle start vs SYNC0 offset now +240 ns; |offset| p50 300 ns, p99 1.1 µs, p99.9 2.0 µs, max 3.4 µs over 123000 cycles"
        );
    }

    #[test]
    fn status_text_names_a_subdevice_out_of_op_and_its_al_status_code() {
        let block = ethercat_text(&names(), &y_drive_left_op()).unwrap();
        assert_eq!(
            block,
            "EtherCAT: 4 subdevices, 1 not in OP (recovering); 123456 cycles exchanged, 3 lost, 2 short, 17 out of OP, at most 5 incomplete in a row\n\
             \x20 0  X drive  OP\n\
             \x20 1  Y drive  SAFE-OP, AL status code 0x001b (sync manager watchdog)\n\
             \x20 2  Z drive  OP\n\
             \x20 3  I/O      OP\n\
             \x20 distributed clocks: cycle start vs SYNC0 offset now -1.2 µs; |offset| p50 300 ns, p99 1.1 µs, p99.9 2.0 µs, max 3.4 µs over 123000 cycles"
        );
    }

    #[test]
    fn status_text_without_dc_with_a_lost_bus_and_an_unlisted_subdevice() {
        let mut s = StatusMsg::zeroed();
        s.bus_subdevices = 2;
        s.bus_states[..2].copy_from_slice(&[kerf_proto::BUS_STATE_OP, 0]);
        s.bus_cycles_complete = 1;
        s.bus_cycles_lost = 3;
        s.bus_longest_gap_cycles = 3;
        s.safety_check = kerf_proto::SAFETY_FIELDBUS;
        let block = ethercat_text(&["X drive".to_string()], &s).unwrap();
        assert_eq!(
            block,
            "EtherCAT: 2 subdevices, 1 not in OP when last heard; 1 cycle exchanged, 3 lost, 0 short, 0 out of OP, at most 3 incomplete in a row\n\
             \x20 0  X drive                     OP\n\
             \x20 1  (not in the configuration)  unknown\n\
             \x20 distributed clocks: not used"
        );
        s.dc_used = 1;
        let block = ethercat_text(&["X drive".to_string()], &s).unwrap();
        assert!(
            block.ends_with("\n  distributed clocks: no offset measured yet"),
            "{block}"
        );
    }

    #[test]
    fn status_text_without_a_bus_is_the_status_line_and_the_machine() {
        let mut s = on_a_bus();
        s.bus_subdevices = 0;
        assert_eq!(ethercat_text(&names(), &s), None);
        assert_eq!(
            status_text("m", &names(), &s, None),
            format!(
                "{}\n{}\n{}",
                status_line("m", &s),
                machine_text(&s),
                axes_text(&s)
            )
        );
    }

    #[test]
    fn the_axes_line_and_object_tell_homing_jogging_and_the_switches() {
        let mut s = StatusMsg::zeroed();
        s.axes_mask = 0b111;
        s.homing_required = 1;
        s.homed = 0b100;
        s.homing = 0b001;
        s.home_phase[0] = kerf_proto::HOME_PHASE_LATCH;
        s.jogging = 0b010;
        s.home_switches = 0b001;
        s.max_limit_switches = 0b010;
        s.limit_released = 0b010;
        assert_eq!(
            axes_text(&s),
            "  axes: X not homed, homing (latch), home switch; Y not homed, jogging, upper limit switch (jog off it); Z homed; programs need every axis homed: `kerf home --all`"
        );
        let v: serde_json::Value =
            serde_json::from_str(&format!("{{{}}}", &axes_json(&s)[1..])).unwrap();
        assert_eq!(v["homing_required"], true);
        assert_eq!(v["axes"]["x"]["homing"], "latch");
        assert_eq!(v["axes"]["x"]["home_switch"], true);
        assert_eq!(v["axes"]["y"]["jogging"], true);
        assert_eq!(v["axes"]["y"]["max_limit_switch"], true);
        assert_eq!(v["axes"]["y"]["limit_released"], true);
        assert_eq!(v["axes"]["z"]["homed"], true);
        assert_eq!(v["axes"]["z"]["homing"], serde_json::Value::Null);
        assert!(v["axes"].get("a").is_none(), "only the configured axes");
    }

    /// A machine paused at a manual tool change with the spindle stopped, flood on,
    /// outputs 1 and 4 and input 0 on.
    fn at_a_tool_change() -> StatusMsg {
        let mut s = on_a_bus();
        s.bus_subdevices = 0;
        s.state = kerf_proto::STATE_PAUSED;
        s.pause_reason = kerf_proto::PAUSE_TOOL_CHANGE;
        s.pause_line = 30;
        s.pause_value = 3;
        s.set_pause_text("insert tool T3 (length 45.200 mm)");
        s.switches = kerf_proto::SWITCH_OPTIONAL_STOP | kerf_proto::SWITCH_BLOCK_DELETE;
        s.tool_in_spindle = 1;
        s.tool_length_mm = 12.5;
        s.tool_changer = kerf_proto::TOOL_CHANGER_MANUAL;
        s.spindle_kind = kerf_proto::SPINDLE_DRIVE;
        s.spindle_programmed_rpm = 12000.0;
        s.spindle_override_pct = 100.0;
        s.overrides_enabled = kerf_proto::OVERRIDES_FEED | kerf_proto::OVERRIDES_SPINDLE;
        s.coolant = kerf_proto::COOLANT_FLOOD;
        s.digital_outputs = 0b1_0010;
        s.digital_inputs = 0b1;
        s
    }

    #[test]
    fn a_pause_is_told_in_words_with_what_ends_it() {
        let s = at_a_tool_change();
        assert_eq!(state_name(&s), "paused");
        assert_eq!(
            pause_text(&s).unwrap(),
            "paused at line 30 (M6): insert tool T3 (length 45.200 mm), then `kerf resume`"
        );
        let text = status_text("m", &names(), &s, None);
        assert_eq!(
            text.lines().collect::<Vec<_>>()[1..],
            [
                "  paused at line 30 (M6): insert tool T3 (length 45.200 mm), then `kerf resume`",
                "  spindle: stopped, S12000 → 0 rpm commanded, 0 rpm actual, override 100 %; coolant: flood; tool: T1 (12.500 mm)",
                "  switches: optional stop on, block delete on, single block off; outputs on: 1,4; inputs on: 0",
                "  axes: X not homed; Y not homed; Z not homed",
            ]
        );
        let mut m0 = s;
        m0.pause_reason = kerf_proto::PAUSE_PROGRAM_STOP;
        m0.pause_line = 12;
        assert_eq!(
            pause_text(&m0).unwrap(),
            "paused at line 12 (M0, program stop): `kerf resume` to continue"
        );
        m0.pause_reason = kerf_proto::PAUSE_NONE;
        assert_eq!(pause_text(&m0), None);
    }

    #[test]
    fn status_json_has_the_machine() {
        let s = at_a_tool_change();
        let json = status_json("m", &names(), &s, None);
        let v: serde_json::Value = serde_json::from_str(&json).expect("JSON");
        assert_eq!(v["state"], "paused");
        assert_eq!(v["pause"]["reason"], "tool_change");
        assert_eq!(v["pause"]["line"], 30);
        assert_eq!(v["pause"]["value"], 3);
        assert_eq!(v["pause"]["waits_for_operator"], true);
        assert_eq!(
            v["pause"]["text"],
            "paused at line 30 (M6): insert tool T3 (length 45.200 mm), then `kerf resume`"
        );
        assert_eq!(v["switches"]["optional_stop"], true);
        assert_eq!(v["switches"]["single_block"], false);
        assert_eq!(v["tool"]["in_spindle"], 1);
        assert_eq!(v["tool"]["length_mm"], 12.5);
        assert_eq!(v["tool"]["changer"], "manual");
        assert_eq!(v["spindle"]["kind"], "drive");
        assert_eq!(v["spindle"]["programmed_rpm"], 12000.0);
        assert_eq!(v["spindle"]["at_speed"], false);
        assert_eq!(v["spindle"]["override_enabled"], true);
        assert_eq!(v["feed_override_enabled"], true);
        assert_eq!(v["coolant"]["flood"], true);
        assert_eq!(v["coolant"]["mist"], false);
        assert_eq!(v["io"]["digital_outputs"], 18);
        assert_eq!(v["io"]["analog_inputs"].as_array().unwrap().len(), 16);
        assert_eq!(v["input_result"], serde_json::Value::Null);
        let mut none = s;
        none.spindle_kind = kerf_proto::SPINDLE_NONE;
        none.pause_reason = kerf_proto::PAUSE_NONE;
        let v: serde_json::Value =
            serde_json::from_str(&status_json("m", &names(), &none, None)).expect("JSON");
        assert_eq!(v["spindle"], serde_json::Value::Null);
        assert_eq!(v["pause"], serde_json::Value::Null);
    }

    #[test]
    fn status_json_has_the_ethercat_object() {
        let json = status_json("m", &names(), &y_drive_left_op(), None);
        let parsed: serde_json::Value = serde_json::from_str(&json).expect("JSON");
        assert_eq!(parsed["ethercat"]["dc"]["offset_ns"], -1240);
        let ethercat = json
            .split_once(",\"ethercat\":")
            .map(|(_, e)| e)
            .expect("an ethercat key");
        assert_eq!(
            ethercat,
            concat!(
                "{\"subdevices\":[",
                "{\"position\":0,\"name\":\"X drive\",\"state\":\"OP\",\"al_status_code\":0,\"al_status\":null},",
                "{\"position\":1,\"name\":\"Y drive\",\"state\":\"SAFE-OP\",\"al_status_code\":27,\"al_status\":\"0x001b (sync manager watchdog)\"},",
                "{\"position\":2,\"name\":\"Z drive\",\"state\":\"OP\",\"al_status_code\":0,\"al_status\":null},",
                "{\"position\":3,\"name\":\"I/O\",\"state\":\"OP\",\"al_status_code\":0,\"al_status\":null}",
                "],\"recovering\":true,",
                "\"cycles\":{\"complete\":123456,\"lost\":3,\"short\":2,\"not_op\":17,\"longest_gap\":5},",
                "\"dc\":{\"offset_ns\":-1240,\"offset_abs_ns\":{\"p50\":300,\"p99\":1100,\"p999\":2000,\"max\":3400},\"samples\":123000}",
                "}}"
            )
        );
        // Without distributed clocks, and a position the configuration does not name.
        let mut s = y_drive_left_op();
        s.dc_used = 0;
        let json = status_json("m", &names()[..1], &s, None);
        assert!(json.ends_with(",\"dc\":null}}"), "{json}");
        assert!(
            json.contains("{\"position\":1,\"name\":null,\"state\":\"SAFE-OP\""),
            "{json}"
        );
    }

    #[test]
    fn the_dro_shows_the_work_position_and_the_offsets() {
        let dro = Dro {
            system: Some(1),
            work_offset: crate::dro::WorkOffset {
                offset_mm_deg: [10.0, 20.0, -5.0, 0.0, 0.0, 0.0],
                rotation_deg: 0.0,
            },
            g92_mm_deg: [0.0, 0.0, 1.5, 0.0, 0.0, 0.0],
            tool: 2,
            tool_offset_mm_deg: [0.0; 6],
            machine_mm_deg: [11.0, 22.0, -3.0, 0.0, 0.0, 0.0],
            work_mm_deg: [1.0, 2.0, 0.5, 0.0, 0.0, 0.0],
        };
        assert_eq!(
            dro_text(&dro, 0b111),
            "work G55 X 1.000 Y 2.000 Z 0.500; G55 offset X 10.000 Y 20.000 Z -5.000; G92 X 0.000 Y 0.000 Z 1.500"
        );
        let json = status_json("m", &names(), &on_a_bus(), Some(&dro));
        let v: serde_json::Value = serde_json::from_str(&json).expect("JSON");
        assert_eq!(v["dro"]["system"], "G55");
        assert_eq!(v["dro"]["work"]["z"], 0.5);
        assert_eq!(v["dro"]["machine"]["x"], 11.0);
        assert_eq!(v["dro"]["g92"]["z"], 1.5);
        assert_eq!(v["dro"]["tool"], 2);
        assert!(v["dro"]["work"].get("a").is_none(), "{json}");
        let text = status_text("m", &names(), &on_a_bus(), Some(&dro));
        assert!(text.contains("\n  work G55 X 1.000"), "{text}");
    }

    #[test]
    fn status_json_without_a_bus_has_ethercat_null() {
        let mut s = on_a_bus();
        s.bus_subdevices = 0;
        let json = status_json("m", &names(), &s, None);
        assert!(json.contains(",\"safety\":null,\"pause\":null,"), "{json}");
        assert!(json.ends_with(",\"ethercat\":null}"), "{json}");
    }

    #[test]
    fn subdevices_are_named_by_position_from_the_configuration() {
        let axis = "velocity_mm_s = 100.0\nacceleration_mm_s2 = 1000.0\njerk_mm_s3 = 10000.0\nmin_mm = -10.0\nmax_mm = 10.0\n";
        // The I/O coupler first on the ring, then Y and X drives, Z at position 3.
        let text = format!(
            "period_us = 1000\n[axes.x]\n{axis}[axes.y]\n{axis}[axes.z]\n{axis}\
             [ethercat]\ninterface = \"eth0\"\n\
             [[ethercat.drives]]\naxis = \"x\"\nposition = 2\nvendor_id = 0x2\nproduct_code = 0x402\n\
             [[ethercat.drives]]\naxis = \"y\"\nposition = 1\nvendor_id = 0x2\nproduct_code = 0x402\n\
             [[ethercat.drives]]\naxis = \"z\"\nposition = 3\nvendor_id = 0x2\nproduct_code = 0x402\n\
             [[ethercat.io]]\nposition = 0\nvendor_id = 0x2\nproduct_code = 0x07433052\n"
        );
        let config = kerf_config::Config::from_toml_str(&text, "m.toml").unwrap();
        assert_eq!(
            subdevice_names(&config),
            ["I/O", "Y drive", "X drive", "Z drive"]
        );
        let simulated = kerf_config::Config::from_toml_str(
            &format!("period_us = 1000\n[axes.x]\n{axis}[axes.y]\n{axis}[axes.z]\n{axis}"),
            "m.toml",
        )
        .unwrap();
        assert!(subdevice_names(&simulated).is_empty());
    }

    #[test]
    fn a_hostile_subdevice_count_is_cut_to_the_arrays() {
        let mut s = on_a_bus();
        s.bus_subdevices = u32::MAX;
        let block = ethercat_text(&names(), &s).unwrap();
        assert!(
            block.starts_with("EtherCAT: 32 subdevices, 28 not in OP;"),
            "{block}"
        );
        assert_eq!(block.lines().count(), 1 + 32 + 1);
    }
}
