//! The reference rows of `[io]`, `[spindle]`, `[coolant]`, `[tool_changer]` and
//! `[operator]`, from the constants and defaults the checker uses.

use crate::*;

use super::{KeyDoc, f, k, rf, ri};

/// The rows, in the order of docs/CONFIG.md.
pub(super) fn keys() -> Vec<KeyDoc> {
    let req = || "required".to_string();
    let none = || "none".to_string();
    let flag = || "true or false".to_string();
    let name = || "1 to 64 ASCII letters, digits, `_`, `-`, from a letter".to_string();
    let spindle = SpindleConfig::default();
    let coolant = CoolantConfig::default();
    let operator = OperatorConfig::default();
    vec![
        k(
            "io",
            "no inputs or outputs".into(),
            "table".into(),
            "The inputs and outputs programs use by number (LinuxCNC `M62`-`M65 P<n>`, `M66 P<n>`/`E<n>`, `M67`/`M68 E<n>`) and the machine's functions by name; each list an array of `{ number, name }` tables, names unique over all four lists. Without [ethercat] they are simulated; with [ethercat] every digital input and output is the bit of that name of an `[[ethercat.io]]` (inputs from its `inputs`, outputs from its `outputs`), and analog entries are refused (not supported on EtherCAT yet).",
        ),
        k(
            "io.digital_outputs",
            "[]".into(),
            "array of tables".into(),
            "Digital outputs (`M62`-`M65`).",
        ),
        k(
            "io.digital_outputs.number",
            req(),
            ri(DIGITAL_IO_NUMBER_RANGE),
            "The output's number, `P` of `M62`-`M65`; unique among the digital outputs.",
        ),
        k(
            "io.digital_outputs.name",
            req(),
            name(),
            "The output's name, as the machine's functions (`[spindle]`, `[coolant]`, `[tool_changer]`) and the bus name it.",
        ),
        k(
            "io.digital_inputs",
            "[]".into(),
            "array of tables".into(),
            "Digital inputs (`M66 P`).",
        ),
        k(
            "io.digital_inputs.number",
            req(),
            ri(DIGITAL_IO_NUMBER_RANGE),
            "The input's number, `P` of `M66`; unique among the digital inputs.",
        ),
        k(
            "io.digital_inputs.name",
            req(),
            name(),
            "The input's name.",
        ),
        k(
            "io.digital_inputs.sim",
            "false".into(),
            flag(),
            "The simulated input's value at start; refused with [ethercat].",
        ),
        k(
            "io.analog_outputs",
            "[]".into(),
            "array of tables".into(),
            "Analog outputs (`M67`/`M68`), simulated only.",
        ),
        k(
            "io.analog_outputs.number",
            req(),
            ri(ANALOG_IO_NUMBER_RANGE),
            "The output's number, `E` of `M67`/`M68`; unique among the analog outputs.",
        ),
        k(
            "io.analog_outputs.name",
            req(),
            name(),
            "The output's name.",
        ),
        k(
            "io.analog_inputs",
            "[]".into(),
            "array of tables".into(),
            "Analog inputs (`M66 E`), simulated only.",
        ),
        k(
            "io.analog_inputs.number",
            req(),
            ri(ANALOG_IO_NUMBER_RANGE),
            "The input's number, `E` of `M66`; unique among the analog inputs.",
        ),
        k(
            "io.analog_inputs.name",
            req(),
            name(),
            "The input's name.",
        ),
        k(
            "io.analog_inputs.sim",
            "0".into(),
            rf(ANALOG_VALUE_RANGE),
            "The simulated input's value at start.",
        ),
        k(
            "spindle",
            "a simulated drive with the defaults below; with [ethercat], the bus's spindle drive, else none".into(),
            "table".into(),
            "The spindle (`S`, `M3`/`M4`/`M5`, `M19`). The keys of one kind are refused for the others.",
        ),
        k(
            "spindle.kind",
            "\"drive\"; with [ethercat] \"drive\" when a [[ethercat.drives]] has `axis = \"s\"`, else \"none\"".into(),
            "\"drive\", \"outputs\" or \"none\"".into(),
            "\"drive\": a drive in velocity mode, simulated, or with [ethercat] the `[[ethercat.drives]]` with `axis = \"s\"` (required then; the spindle is not simulated beside a bus). \"outputs\": enable and reverse digital outputs and a speed analog output of [io]. \"none\": no spindle, a program that starts one is refused before motion.",
        ),
        k(
            "spindle.max_rpm",
            f(spindle.max_rpm),
            rf(SPINDLE_RPM_RANGE),
            "The fastest speed; a program asking more is refused before motion.",
        ),
        k(
            "spindle.min_rpm",
            f(spindle.min_rpm),
            format!("0 to {}, below `max_rpm`", f(*SPINDLE_RPM_RANGE.end())),
            "The slowest speed: a commanded speed above 0 and below it runs at it.",
        ),
        k(
            "spindle.acceleration_rpm_s",
            f(spindle.acceleration_rpm_s),
            rf(SPINDLE_ACCELERATION_RANGE_RPM_S),
            "The spindle's ramp: the simulated drive's, and the one `at_speed_timeout_s` must leave time for.",
        ),
        k(
            "spindle.at_speed_tolerance",
            f(spindle.at_speed_tolerance),
            rf(AT_SPEED_TOLERANCE_RANGE),
            "The at-speed band, a fraction of the commanded speed (LinuxCNC's `spindle.at-speed`).",
        ),
        k(
            "spindle.at_speed_timeout_s",
            f(spindle.at_speed_timeout_s),
            format!(
                "{}, above `max_rpm` / `acceleration_rpm_s` (and above `spin_up_s` without `at_speed_input`)",
                rf(MACHINE_TIMEOUT_RANGE_S)
            ),
            "A feed move after a start or speed change waits at most this long for at-speed, then faults (rapids do not wait).",
        ),
        k(
            "spindle.fault_out_of_band",
            spindle.fault_out_of_band.to_string(),
            flag(),
            "Leaving the at-speed band while feeding is a fault (a broken belt).",
        ),
        k(
            "spindle.orient_timeout_s",
            f(spindle.orient_timeout_s),
            rf(MACHINE_TIMEOUT_RANGE_S),
            "The wait of an `M19` without `Q`.",
        ),
        k(
            "spindle.enable_output",
            "required for \"outputs\"".into(),
            "a digital output of [io]".into(),
            "Kind \"outputs\": on while the spindle turns.",
        ),
        k(
            "spindle.reverse_output",
            none(),
            "a digital output of [io]".into(),
            "Kind \"outputs\": on while the spindle turns counter-clockwise (`M4`); without it `M4` is refused.",
        ),
        k(
            "spindle.speed_output",
            "required for \"outputs\"".into(),
            "an analog output of [io]".into(),
            "Kind \"outputs\": the speed, written as rpm × `speed_output_scale`.",
        ),
        k(
            "spindle.speed_output_scale",
            "required for \"outputs\"".into(),
            rf(SPEED_OUTPUT_SCALE_RANGE),
            "Kind \"outputs\": analog output units per rpm (10 V at 24000 rpm: 0.0004167).",
        ),
        k(
            "spindle.at_speed_input",
            none(),
            "a digital input of [io]".into(),
            "Kind \"outputs\": on when the spindle is at speed; without it the spindle counts as at speed `spin_up_s` after a change.",
        ),
        k(
            "spindle.spin_up_s",
            f(DEFAULT_SPIN_UP_S),
            rf(SPIN_UP_RANGE_S),
            "Kind \"outputs\" without `at_speed_input`: the time after a change at which the spindle counts as at speed.",
        ),
        k(
            "spindle.counts_per_rev",
            f(DEFAULT_SPINDLE_COUNTS_PER_REV),
            rf(SPINDLE_COUNTS_PER_REV_RANGE),
            "Kind \"drive\": the drive's velocity counts per revolution (its target velocity 0x60FF in counts/s is rpm × `counts_per_rev` / 60).",
        ),
        k(
            "spindle.off_at_end",
            spindle.off_at_end.to_string(),
            flag(),
            "`M2`/`M30` stop the spindle.",
        ),
        k(
            "spindle.off_at_abort",
            spindle.off_at_abort.to_string(),
            flag(),
            "An abort stops the spindle.",
        ),
        k(
            "spindle.off_at_fault",
            spindle.off_at_fault.to_string(),
            flag(),
            "A fault sets the spindle command to 0.",
        ),
        k(
            "coolant",
            "no coolant outputs".into(),
            "table".into(),
            "Coolant (`M7`, `M8`, `M9`).",
        ),
        k(
            "coolant.mist",
            none(),
            "a digital output of [io]".into(),
            "The output `M7` switches on; without it `M7` is refused before motion.",
        ),
        k(
            "coolant.flood",
            none(),
            "a digital output of [io]".into(),
            "The output `M8` switches on; without it `M8` is refused before motion.",
        ),
        k(
            "coolant.off_at_end",
            coolant.off_at_end.to_string(),
            flag(),
            "`M2`/`M30` switch the coolant off.",
        ),
        k(
            "coolant.off_at_abort",
            coolant.off_at_abort.to_string(),
            flag(),
            "An abort switches the coolant off.",
        ),
        k(
            "coolant.off_at_fault",
            coolant.off_at_fault.to_string(),
            flag(),
            "A fault switches the coolant off.",
        ),
        k(
            "tool_changer",
            "manual".into(),
            "table".into(),
            "The tool change `M6`. The keys of \"automatic\" are refused for the other kinds.",
        ),
        k(
            "tool_changer.kind",
            "\"manual\"".into(),
            "\"manual\", \"automatic\" or \"none\"".into(),
            "\"manual\": `M6` pauses with \"insert tool T…\", cycle start (`kerf resume`) confirms. \"automatic\": the handshake below (LinuxCNC iocontrol's tool-prep-number, tool-change, tool-changed). \"none\": `M6` is refused before motion.",
        ),
        k(
            "tool_changer.number_output",
            "required for \"automatic\"".into(),
            "an analog output of [io]".into(),
            "Carries the tool number.",
        ),
        k(
            "tool_changer.change_output",
            "required for \"automatic\"".into(),
            "a digital output of [io]".into(),
            "The change request.",
        ),
        k(
            "tool_changer.changed_input",
            "required for \"automatic\"".into(),
            "a digital input of [io]".into(),
            "The change done.",
        ),
        k(
            "tool_changer.timeout_s",
            f(DEFAULT_TOOL_CHANGE_TIMEOUT_S),
            rf(MACHINE_TIMEOUT_RANGE_S),
            "The change faults when `changed_input` has not come on after this.",
        ),
        k(
            "operator",
            "all defaults".into(),
            "table".into(),
            "The runtime switches' values when the daemon starts (`kerf optional-stop`, `kerf single-block` change them; the block delete switch's is `gcode.block_delete`).",
        ),
        k(
            "operator.optional_stop",
            operator.optional_stop.to_string(),
            flag(),
            "`M1` pauses (LinuxCNC's default).",
        ),
        k(
            "operator.single_block",
            operator.single_block.to_string(),
            flag(),
            "The program pauses after each block.",
        ),
    ]
}
