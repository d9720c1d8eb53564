//! The machine's functions' tests: `[io]`, `[spindle]`, `[coolant]`, `[tool_changer]`,
//! `[operator]` and `daemon.state_file`, simulated and on EtherCAT; the bundled files;
//! [`MachineCaps`]. Expected values are the files' numbers written out by hand.

use std::path::Path;

use crate::tests_ethercat::{AXES, at, at_nth, bus, load, refused, spindle_drive};
use crate::*;

/// The three axes with `[io]` of two digital outputs, two digital inputs, an analog
/// output and an analog input, then `rest`.
fn machine(rest: &str) -> String {
    format!(
        "{AXES}[io]\n\
         digital_outputs = [ {{ number = 0, name = \"mist\" }}, {{ number = 5, name = \"flood\" }} ]\n\
         digital_inputs = [ {{ number = 3, name = \"door\", sim = true }}, {{ number = 1, name = \"ready\" }} ]\n\
         analog_outputs = [ {{ number = 2, name = \"speed\" }} ]\n\
         analog_inputs = [ {{ number = 15, name = \"force\", sim = -2.5 }} ]\n\
         {rest}"
    )
}

fn config(text: &str) -> Config {
    load(text).unwrap_or_else(|e| panic!("refused: {e}\n{text}"))
}

/// The error prefix for the value of the first `line` (`key = value`) in `text`.
pub(crate) fn at_value(text: &str, line: &str) -> String {
    let offset = text
        .find(line)
        .unwrap_or_else(|| panic!("`{line}` not in the text"))
        + line.find("= ").expect("a key = value line")
        + 2;
    let before = &text[..offset];
    let line_no = before.matches('\n').count() + 1;
    let col = offset - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    format!("m.toml:{line_no}:{col}: error: ")
}

fn io_ref(name: &str, number: u8) -> IoRef {
    IoRef {
        name: name.to_string(),
        number,
    }
}

#[test]
fn io_lists_are_read_in_number_order_with_their_sim_values() {
    let c = config(&machine(""));
    let outs: Vec<(u8, &str)> =
        c.io.digital_outputs
            .iter()
            .map(|o| (o.number, o.name.as_str()))
            .collect();
    assert_eq!(outs, [(0, "mist"), (5, "flood")]);
    let ins: Vec<(u8, &str, bool)> =
        c.io.digital_inputs
            .iter()
            .map(|i| (i.number, i.name.as_str(), i.sim))
            .collect();
    // Sorted by number; `ready` without `sim` starts false.
    assert_eq!(ins, [(1, "ready", false), (3, "door", true)]);
    assert!(c.io.digital_outputs.iter().all(|o| o.bus_bit.is_none()));
    assert_eq!(
        c.io.analog_outputs,
        [AnalogOutput {
            number: 2,
            name: "speed".into()
        }]
    );
    assert_eq!(
        c.io.analog_inputs,
        [AnalogInput {
            number: 15,
            name: "force".into(),
            sim: -2.5
        }]
    );
    assert_eq!(c.io.digital_input("door").map(|d| d.number), Some(3));
    assert_eq!(c.io.digital_output("door"), None);
    assert_eq!(c.io.analog_output("speed").map(|d| d.number), Some(2));
    assert_eq!(c.io.analog_input("force").map(|d| d.number), Some(15));
    // The same tables as arrays of tables.
    let c2 = config(&format!(
        "{AXES}[[io.digital_outputs]]\nnumber = 5\nname = \"flood\"\n[[io.digital_outputs]]\nnumber = 0\nname = \"mist\"\n"
    ));
    assert_eq!(c2.io.digital_outputs, c.io.digital_outputs);
}

#[test]
fn without_the_tables_the_machine_is_a_simulated_drive_spindle_and_a_manual_changer() {
    let c = config(AXES);
    assert_eq!(c.io, IoConfig::default());
    let s = &c.spindle;
    assert_eq!(
        s.kind,
        SpindleKind::Drive(SpindleDrive {
            counts_per_rev: 10_000.0,
            on_bus: false
        })
    );
    assert!(s.exists());
    assert_eq!(
        (
            s.max_rpm,
            s.min_rpm,
            s.acceleration_rpm_s,
            s.at_speed_tolerance,
            s.at_speed_timeout_s,
            s.orient_timeout_s
        ),
        (24_000.0, 0.0, 8000.0, 0.02, 10.0, 5.0)
    );
    assert!(s.fault_out_of_band && s.off_at_end && s.off_at_abort && s.off_at_fault);
    assert_eq!(
        c.coolant,
        CoolantConfig {
            mist: None,
            flood: None,
            off_at_end: true,
            off_at_abort: true,
            off_at_fault: true
        }
    );
    assert_eq!(c.tool_changer, ToolChanger::Manual);
    assert_eq!(
        c.operator,
        OperatorConfig {
            optional_stop: true,
            single_block: false
        }
    );
    // M3 runs, M7/M8 and every I/O number are refused, M6 pauses.
    assert_eq!(
        c.machine_check(),
        MachineCaps {
            spindle_max_rpm: Some(24_000.0),
            spindle_orients: true,
            mist: false,
            flood: false,
            digital_outputs: 0,
            digital_inputs: 0,
            analog_outputs: 0,
            analog_inputs: 0,
            tool_changer: ToolChangerKind::Manual,
        }
    );
}

#[test]
fn every_key_of_an_outputs_spindle_coolant_and_an_automatic_changer_is_read() {
    let text = machine(
        "[spindle]\nkind = \"outputs\"\nmax_rpm = 12000\nmin_rpm = 500\nacceleration_rpm_s = 4000\n\
         at_speed_tolerance = 0.05\nat_speed_timeout_s = 4.5\nfault_out_of_band = false\norient_timeout_s = 2\n\
         enable_output = \"mist\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.0008\n\
         at_speed_input = \"ready\"\nspin_up_s = 7\noff_at_end = false\noff_at_abort = false\noff_at_fault = false\n\
         [coolant]\nflood = \"flood\"\noff_at_end = false\noff_at_abort = false\noff_at_fault = false\n\
         [operator]\noptional_stop = false\nsingle_block = true\n",
    );
    let c = config(&text);
    let s = &c.spindle;
    assert_eq!(
        s.kind,
        SpindleKind::Outputs(SpindleOutputs {
            enable_output: io_ref("mist", 0),
            reverse_output: None,
            speed_output: io_ref("speed", 2),
            speed_output_scale: 0.0008,
            at_speed_input: Some(io_ref("ready", 1)),
            // With an at-speed input the spin-up time is not checked against the timeout.
            spin_up_s: 7.0,
        })
    );
    assert_eq!(
        (
            s.max_rpm,
            s.min_rpm,
            s.acceleration_rpm_s,
            s.at_speed_tolerance,
            s.at_speed_timeout_s,
            s.orient_timeout_s
        ),
        (12_000.0, 500.0, 4000.0, 0.05, 4.5, 2.0)
    );
    assert!(!s.fault_out_of_band && !s.off_at_end && !s.off_at_abort && !s.off_at_fault);
    assert_eq!(
        c.coolant,
        CoolantConfig {
            mist: None,
            flood: Some(io_ref("flood", 5)),
            off_at_end: false,
            off_at_abort: false,
            off_at_fault: false
        }
    );
    assert_eq!(
        c.operator,
        OperatorConfig {
            optional_stop: false,
            single_block: true
        }
    );

    let text = machine(
        "[spindle]\nkind = \"none\"\n[coolant]\nmist = \"mist\"\n\
         [tool_changer]\nkind = \"automatic\"\nnumber_output = \"speed\"\nchange_output = \"flood\"\nchanged_input = \"door\"\ntimeout_s = 12.5\n",
    );
    let c = config(&text);
    assert_eq!(c.spindle.kind, SpindleKind::None);
    assert!(!c.spindle.exists());
    assert_eq!(
        c.tool_changer,
        ToolChanger::Automatic(AutomaticToolChanger {
            number_output: io_ref("speed", 2),
            change_output: io_ref("flood", 5),
            changed_input: io_ref("door", 3),
            timeout_s: 12.5,
        })
    );
    // Outputs 0 and 5 (bits 0 and 5: 1 + 32), inputs 1 and 3 (2 + 8), analog output 2
    // (4), analog input 15 (32768).
    assert_eq!(
        c.machine_check(),
        MachineCaps {
            spindle_max_rpm: None,
            spindle_orients: false,
            mist: true,
            flood: false,
            digital_outputs: 33,
            digital_inputs: 10,
            analog_outputs: 4,
            analog_inputs: 32768,
            tool_changer: ToolChangerKind::Automatic,
        }
    );
    let caps = c.machine_check();
    assert!(caps.has_digital_output(5) && !caps.has_digital_output(1));
    assert!(caps.has_digital_input(3) && !caps.has_digital_input(0));
    assert!(caps.has_analog_output(2) && !caps.has_analog_output(64));
    assert!(caps.has_analog_input(15) && !caps.has_analog_input(16));
    assert!(!caps.has_digital_output(64) && !caps.has_digital_input(1000));
    let automatic_default = config(&machine(
        "[tool_changer]\nkind = \"automatic\"\nnumber_output = \"speed\"\nchange_output = \"flood\"\nchanged_input = \"door\"\n",
    ));
    assert!(
        matches!(automatic_default.tool_changer, ToolChanger::Automatic(a) if a.timeout_s == 30.0)
    );
    let none = config(&machine("[tool_changer]\nkind = \"none\"\n"));
    assert_eq!(none.tool_changer, ToolChanger::None);
    assert_eq!(none.machine_check().tool_changer, ToolChangerKind::None);
    // The extreme numbers: digital output 63 is the top bit.
    let c = config(&format!(
        "{AXES}[io]\ndigital_outputs = [ {{ number = 63, name = \"top\" }} ]\n"
    ));
    assert_eq!(c.machine_check().digital_outputs, 1 << 63);
    assert!(c.machine_check().has_digital_output(63));
}

#[test]
fn io_numbers_and_names_are_checked_where_they_are_written() {
    let out = |entries: &str| format!("{AXES}[io]\ndigital_outputs = [ {entries} ]\n");
    let cases: Vec<(String, &str, String)> = vec![
        (
            out("{ number = 64, name = \"a\" }"),
            "64",
            "`io.digital_outputs[0].number` must be a digital output number from 0 to 63, found 64".into(),
        ),
        (
            out("{ number = -1, name = \"a\" }"),
            "-1, name",
            "`io.digital_outputs[0].number` must be a digital output number from 0 to 63, found -1".into(),
        ),
        (
            format!("{AXES}[io]\nanalog_inputs = [ {{ number = 16, name = \"a\" }} ]\n"),
            "16",
            "`io.analog_inputs[0].number` must be an analog input number from 0 to 15, found 16".into(),
        ),
        (
            format!("{AXES}[io]\nanalog_outputs = [ {{ number = 16, name = \"a\" }} ]\n"),
            "16",
            "`io.analog_outputs[0].number` must be an analog output number from 0 to 15, found 16".into(),
        ),
        (
            format!("{AXES}[io]\ndigital_inputs = [ {{ number = 99, name = \"a\" }} ]\n"),
            "99",
            "`io.digital_inputs[0].number` must be a digital input number from 0 to 63, found 99".into(),
        ),
        (
            out("{ number = 1, name = \"a\" }, { number = 2, name = \"b\" }, { number = 1, name = \"c\" }"),
            "1, name = \"c\"",
            "`io.digital_outputs[2].number` = 1 is also the number of `io.digital_outputs[0]`; each of io.digital_outputs has its own".into(),
        ),
        (
            out("{ number = 1, name = \"9lives\" }"),
            "\"9lives\"",
            "`io.digital_outputs[0].name` must be 1 to 64 ASCII letters, digits, `_` or `-`, starting with a letter, found `9lives`".into(),
        ),
        (
            out("{ number = 1, name = \"\" }"),
            "\"\"",
            "`io.digital_outputs[0].name` must be 1 to 64 ASCII letters, digits, `_` or `-`, starting with a letter, found ``".into(),
        ),
        (
            format!(
                "{AXES}[io]\ndigital_outputs = [ {{ number = 1, name = \"clamp\" }} ]\nanalog_inputs = [ {{ number = 1, name = \"clamp\" }} ]\n"
            ),
            "\"clamp\" }] \n",
            "the name `clamp` is used twice in [io]: `io.digital_outputs[0]` and `io.analog_inputs[0]`".into(),
        ),
        (
            format!("{AXES}[io]\nanalog_inputs = [ {{ number = 1, name = \"f\", sim = 2e9 }} ]\n"),
            "2e9",
            "`io.analog_inputs[0].sim` must be between -1e9 and 1e9 (the input's units), found 2e9".into(),
        ),
        (
            out("{ number = 1, name = \"a\", sim = true }"),
            "sim",
            "unknown key `io.digital_outputs[0].sim` (known here: `number` or `name`)".into(),
        ),
        (
            format!("{AXES}[io]\ndigital_output = []\n"),
            "digital_output ",
            "unknown key `io.digital_output` (known here: `digital_outputs`, `digital_inputs`, `analog_outputs`, `analog_inputs`)".into(),
        ),
        (
            out("{ number = 1 }"),
            "{ number = 1 }",
            "missing key `io.digital_outputs[0].name`".into(),
        ),
    ];
    for (text, needle, message) in cases {
        // The duplicate name's place is its second occurrence.
        let place = if needle.starts_with("\"clamp\"") {
            at_nth(&text, "\"clamp\"", 1)
        } else {
            at(&text, needle)
        };
        assert_eq!(refused(&text), format!("{place}{message}"), "{text}");
    }
}

#[test]
fn spindle_values_are_range_checked_at_their_place() {
    let cases: &[(&str, &str, &str)] = &[
        (
            "max_rpm = 0",
            "0",
            "`spindle.max_rpm` must be between 0.001 and 1000000 rpm, found 0",
        ),
        (
            "max_rpm = 2e6",
            "2e6",
            "`spindle.max_rpm` must be between 0.001 and 1000000 rpm, found 2000000",
        ),
        (
            "min_rpm = -1",
            "-1",
            "`spindle.min_rpm` must be between 0 and 1000000 rpm, found -1",
        ),
        (
            "min_rpm = 24000",
            "24000",
            "`spindle.min_rpm` (24000) must be below `spindle.max_rpm` (24000)",
        ),
        (
            "acceleration_rpm_s = 0",
            "0",
            "`spindle.acceleration_rpm_s` must be between 0.1 and 1e7 rpm/s, found 0",
        ),
        (
            "at_speed_tolerance = 0.6",
            "0.6",
            "`spindle.at_speed_tolerance` must be between 0.001 and 0.5 (fraction of the commanded speed), found 0.6",
        ),
        (
            "at_speed_timeout_s = 0",
            "0",
            "`spindle.at_speed_timeout_s` must be between 0.01 and 3600 s, found 0",
        ),
        (
            "orient_timeout_s = 4000",
            "4000",
            "`spindle.orient_timeout_s` must be between 0.01 and 3600 s, found 4000",
        ),
        (
            "counts_per_rev = 0",
            "0",
            "`spindle.counts_per_rev` must be between 0.001 and 1e9 counts, found 0",
        ),
        (
            "kind = \"belt\"",
            "\"belt\"",
            "`spindle.kind` must be \"drive\", \"outputs\" or \"none\", found `belt`",
        ),
        (
            "max_speed = 1",
            "max_speed",
            "unknown key `spindle.max_speed`",
        ),
    ];
    for (line, needle, message) in cases {
        let text = format!("{AXES}[spindle]\n{line}\n");
        let e = refused(&text);
        // The place is the value's (the key's for an unknown key).
        let offset = text.find(line).unwrap();
        let line_no = text[..offset].matches('\n').count() + 1;
        let col = line.find(needle).unwrap() + 1;
        assert!(
            e.starts_with(&format!("m.toml:{line_no}:{col}: error: {message}")),
            "{line}: {e}"
        );
    }
}

#[test]
fn the_at_speed_timeout_must_leave_time_to_reach_full_speed() {
    // 24000 rpm at 8000 rpm/s takes 3 s: 3 s is not enough, 3.01 s is.
    let text = format!("{AXES}[spindle]\nat_speed_timeout_s = 3\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}`spindle.at_speed_timeout_s` (3 s) must exceed the time the spindle takes from 0 to `max_rpm` (24000 rpm) at `acceleration_rpm_s` (8000 rpm/s), 3 s: every start to full speed would fault",
            at_value(&text, "at_speed_timeout_s = 3")
        )
    );
    config(&format!("{AXES}[spindle]\nat_speed_timeout_s = 3.01\n"));
    // With the default 10 s timeout, a slow ramp is refused at `max_rpm` when given.
    let text = format!("{AXES}[spindle]\nmax_rpm = 60000\nacceleration_rpm_s = 5000\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}`spindle.at_speed_timeout_s` (10 s) must exceed the time the spindle takes from 0 to `max_rpm` (60000 rpm) at `acceleration_rpm_s` (5000 rpm/s), 12 s: every start to full speed would fault",
            at_value(&text, "max_rpm = 60000")
        )
    );
    let text = format!("{AXES}[spindle]\nacceleration_rpm_s = 1000\n");
    assert!(
        refused(&text).starts_with(&format!(
            "{}`spindle.at_speed_timeout_s` (10 s)",
            at_value(&text, "acceleration_rpm_s = 1000")
        )),
        "{}",
        refused(&text)
    );
    // An outputs spindle without an at-speed input is at speed after `spin_up_s`.
    let outputs = "[spindle]\nkind = \"outputs\"\nenable_output = \"mist\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.001\n";
    let text = machine(&format!("{outputs}spin_up_s = 10\n"));
    assert_eq!(
        refused(&text),
        format!(
            "{}`spindle.at_speed_timeout_s` (10 s) must exceed `spindle.spin_up_s` (10 s): without `at_speed_input` the spindle counts as at speed only after `spin_up_s`, so every start would fault",
            at_value(&text, "spin_up_s = 10")
        )
    );
    let c = config(&machine(&format!("{outputs}spin_up_s = 9.5\n")));
    assert!(matches!(c.spindle.kind, SpindleKind::Outputs(o) if o.spin_up_s == 9.5));
    // The default spin-up (3 s) within the default timeout.
    let c = config(&machine(outputs));
    assert!(
        matches!(c.spindle.kind, SpindleKind::Outputs(o) if o.spin_up_s == 3.0 && o.at_speed_input.is_none())
    );
}

#[test]
fn the_keys_of_one_kind_are_refused_for_the_others() {
    let outputs =
        "enable_output = \"mist\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.001\n";
    let cases: Vec<(String, &str, String)> = vec![
        (
            machine("[spindle]\nenable_output = \"mist\"\n"),
            "\"mist\"\n",
            "`spindle.enable_output` is a key of kind \"outputs\", but `spindle.kind` is \"drive\" by default; remove it".into(),
        ),
        (
            machine("[spindle]\nkind = \"none\"\nspin_up_s = 1.25\n"),
            "1.25",
            "`spindle.spin_up_s` is a key of kind \"outputs\", but `spindle.kind` is \"none\"; remove it".into(),
        ),
        (
            machine(&format!("[spindle]\nkind = \"outputs\"\n{outputs}counts_per_rev = 4096\n")),
            "4096",
            "`spindle.counts_per_rev` is a key of kind \"drive\", but `spindle.kind` is \"outputs\"; remove it".into(),
        ),
        (
            machine("[tool_changer]\ntimeout_s = 5.5\n"),
            "5.5",
            "`tool_changer.timeout_s` is a key of kind \"automatic\", but `tool_changer.kind` is \"manual\" by default; remove it".into(),
        ),
        (
            machine("[tool_changer]\nkind = \"none\"\nchange_output = \"flood\"\n"),
            "\"flood\"\n",
            "`tool_changer.change_output` is a key of kind \"automatic\", but `tool_changer.kind` is \"none\"; remove it".into(),
        ),
        (
            machine("[tool_changer]\nkind = \"robot\"\n"),
            "\"robot\"",
            "`tool_changer.kind` must be \"manual\", \"automatic\" or \"none\", found `robot`".into(),
        ),
        // A kind's required keys, missing: the error is at the kind.
        (
            machine("[spindle]\nkind = \"outputs\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.001\n"),
            "\"outputs\"",
            "`spindle.kind` is \"outputs\" needs `spindle.enable_output`, the digital output that switches the spindle on".into(),
        ),
        (
            machine("[spindle]\nkind = \"outputs\"\nenable_output = \"mist\"\nspeed_output_scale = 0.001\n"),
            "\"outputs\"",
            "`spindle.kind` is \"outputs\" needs `spindle.speed_output`, the analog output that sets its speed".into(),
        ),
        (
            machine("[spindle]\nkind = \"outputs\"\nenable_output = \"mist\"\nspeed_output = \"speed\"\n"),
            "\"outputs\"",
            "`spindle.kind` is \"outputs\" needs `spindle.speed_output_scale`, the analog output's units per rpm (10 V at 24000 rpm: 0.0004167)".into(),
        ),
        (
            machine("[tool_changer]\nkind = \"automatic\"\nnumber_output = \"speed\"\nchange_output = \"flood\"\n"),
            "\"automatic\"",
            "`tool_changer.kind` is \"automatic\" needs `tool_changer.changed_input`, the digital input that says the change is done".into(),
        ),
    ];
    for (text, needle, message) in cases {
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{text}"
        );
    }
    let e = refused(&machine(&format!(
        "[spindle]\nkind = \"outputs\"\n{}",
        outputs.replace("0.001", "0")
    )));
    assert!(
        e.ends_with("`spindle.speed_output_scale` must be between 1e-12 and 1000000 (output units per rpm), found 0"),
        "{e}"
    );
}

#[test]
fn a_name_a_function_uses_must_be_in_io_with_the_right_type() {
    let outputs = |enable: &str, speed: &str| {
        machine(&format!(
            "[spindle]\nkind = \"outputs\"\nenable_output = \"{enable}\"\nspeed_output = \"{speed}\"\nspeed_output_scale = 0.001\n"
        ))
    };
    let cases: Vec<(String, &str, &str)> = vec![
        (
            outputs("spindle_on", "speed"),
            "\"spindle_on\"",
            "`spindle.enable_output` names `spindle_on`, which is not in [io]; it must be a digital output (`io.digital_outputs`)",
        ),
        (
            outputs("door", "speed"),
            "\"door\"\nspeed_output",
            "`spindle.enable_output` names `door`, which is a digital input (`io.digital_inputs`); it must be a digital output (`io.digital_outputs`)",
        ),
        (
            outputs("mist", "flood"),
            "\"flood\"\nspeed_output_scale",
            "`spindle.speed_output` names `flood`, which is a digital output (`io.digital_outputs`); it must be an analog output (`io.analog_outputs`)",
        ),
        (
            machine(
                "[spindle]\nkind = \"outputs\"\nenable_output = \"mist\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.001\nreverse_output = \"force\"\n",
            ),
            "\"force\"\n",
            "`spindle.reverse_output` names `force`, which is an analog input (`io.analog_inputs`); it must be a digital output (`io.digital_outputs`)",
        ),
        (
            machine(
                "[spindle]\nkind = \"outputs\"\nenable_output = \"mist\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.001\nat_speed_input = \"flood\"\n",
            ),
            "\"flood\"\n",
            "`spindle.at_speed_input` names `flood`, which is a digital output (`io.digital_outputs`); it must be a digital input (`io.digital_inputs`)",
        ),
        (
            machine("[coolant]\nmist = \"fog\"\n"),
            "\"fog\"",
            "`coolant.mist` names `fog`, which is not in [io]; it must be a digital output (`io.digital_outputs`)",
        ),
        (
            machine("[coolant]\nflood = \"speed\"\n"),
            "\"speed\"\n",
            "`coolant.flood` names `speed`, which is an analog output (`io.analog_outputs`); it must be a digital output (`io.digital_outputs`)",
        ),
        (
            machine(
                "[tool_changer]\nkind = \"automatic\"\nnumber_output = \"flood\"\nchange_output = \"mist\"\nchanged_input = \"door\"\n",
            ),
            "\"flood\"\nchange",
            "`tool_changer.number_output` names `flood`, which is a digital output (`io.digital_outputs`); it must be an analog output (`io.analog_outputs`)",
        ),
        (
            machine(
                "[tool_changer]\nkind = \"automatic\"\nnumber_output = \"speed\"\nchange_output = \"mist\"\nchanged_input = \"mist\"\n",
            ),
            "\"mist\"\n",
            "`tool_changer.changed_input` names `mist`, which is a digital output (`io.digital_outputs`); it must be a digital input (`io.digital_inputs`)",
        ),
        // One output, two functions.
        (
            machine("[coolant]\nmist = \"mist\"\nflood = \"mist\"\n"),
            "\"mist\"\n",
            "`coolant.mist` and `coolant.flood` both name the output `mist`; each machine function has its own output",
        ),
        (
            machine(
                "[spindle]\nkind = \"outputs\"\nenable_output = \"flood\"\nspeed_output = \"speed\"\nspeed_output_scale = 0.001\n[coolant]\nflood = \"flood\"\n",
            ),
            "\"flood\"\n",
            "`spindle.enable_output` and `coolant.flood` both name the output `flood`; each machine function has its own output",
        ),
    ];
    for (text, needle, message) in cases {
        // The error is at the last occurrence of the needle that the message is about:
        // the second `"mist"` in the changed_input case, the second function's name for
        // outputs used twice.
        let nth = match message {
            m if m.starts_with("`tool_changer.changed_input`") => 1,
            m if m.contains("both name") => 1,
            _ => 0,
        };
        assert_eq!(
            refused(&text),
            format!("{}{message}", at_nth(&text, needle, nth)),
            "{text}"
        );
    }
}

#[test]
fn on_ethercat_io_names_are_bits_of_the_bus_and_analog_io_is_refused() {
    let io_bits = "inputs = { part = 4, door = 1 }\noutputs = { clamp = 7 }\n";
    let on_bus = |rest: &str| format!("{}{rest}", bus("", "", io_bits));
    let c = config(&on_bus(
        "[io]\ndigital_outputs = [ { number = 2, name = \"clamp\" } ]\n\
         digital_inputs = [ { number = 0, name = \"part\" }, { number = 9, name = \"door\" } ]\n\
         [coolant]\nflood = \"clamp\"\n",
    ));
    assert_eq!(
        c.io.digital_outputs,
        [DigitalOutput {
            number: 2,
            name: "clamp".into(),
            bus_bit: Some(BusBit {
                position: 3,
                bit: 7
            })
        }]
    );
    let ins: Vec<(u8, Option<BusBit>, bool)> =
        c.io.digital_inputs
            .iter()
            .map(|i| (i.number, i.bus_bit, i.sim))
            .collect();
    assert_eq!(
        ins,
        [
            (
                0,
                Some(BusBit {
                    position: 3,
                    bit: 4
                }),
                false
            ),
            (
                9,
                Some(BusBit {
                    position: 3,
                    bit: 1
                }),
                false
            )
        ]
    );
    assert_eq!(c.coolant.flood, Some(io_ref("clamp", 2)));
    // Without a spindle drive on the bus the machine has no spindle.
    assert_eq!(c.spindle.kind, SpindleKind::None);
    assert_eq!(c.machine_check().spindle_max_rpm, None);

    let cases: Vec<(String, &str, String)> = vec![
        (
            on_bus("[io]\ndigital_outputs = [ { number = 0, name = \"blast\" } ]\n"),
            "\"blast\"",
            "`io.digital_outputs[0].name` is `blast`, which is not an output bit of any [[ethercat.io]]: with [ethercat], every digital output of [io] is a bit named in an I/O subdevice's `outputs`".into(),
        ),
        (
            on_bus("[io]\ndigital_outputs = [ { number = 0, name = \"door\" } ]\n"),
            "\"door\" }",
            "`io.digital_outputs[0].name` is `door`, which is not an output bit of any [[ethercat.io]] (it is an input bit of the subdevice at position 3): with [ethercat], every digital output of [io] is a bit named in an I/O subdevice's `outputs`".into(),
        ),
        (
            on_bus("[io]\ndigital_inputs = [ { number = 0, name = \"clamp\" } ]\n"),
            "\"clamp\" }",
            "`io.digital_inputs[0].name` is `clamp`, which is not an input bit of any [[ethercat.io]] (it is an output bit of the subdevice at position 3): with [ethercat], every digital input of [io] is a bit named in an I/O subdevice's `inputs`".into(),
        ),
        (
            on_bus("[io]\ndigital_inputs = [ { number = 0, name = \"part\", sim = true } ]\n"),
            "true",
            "`io.digital_inputs[0].sim` sets a simulated input, but with [ethercat] `part` is input bit 4 of the I/O subdevice at position 3; remove it".into(),
        ),
        (
            on_bus("[io]\nanalog_outputs = [ { number = 0, name = \"laser\" } ]\n"),
            "\"laser\"",
            "`io.analog_outputs[0]` (`laser`): analog inputs and outputs on EtherCAT are not supported yet; with [ethercat], [io] has digital inputs and outputs only".into(),
        ),
        (
            on_bus("[io]\nanalog_inputs = [ { number = 0, name = \"force\" } ]\n"),
            "\"force\"",
            "`io.analog_inputs[0]` (`force`): analog inputs and outputs on EtherCAT are not supported yet; with [ethercat], [io] has digital inputs and outputs only".into(),
        ),
    ];
    for (text, needle, message) in cases {
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{text}"
        );
    }
}

#[test]
fn on_ethercat_the_spindle_is_the_bus_drive_or_none() {
    let with_drive = |rest: &str| format!("{}{}{rest}", bus("", "", ""), spindle_drive(""));
    // The spindle drive alone makes a drive spindle with the defaults.
    let c = config(&with_drive(""));
    assert_eq!(
        c.spindle.kind,
        SpindleKind::Drive(SpindleDrive {
            counts_per_rev: 10_000.0,
            on_bus: true
        })
    );
    assert_eq!(c.machine_check().spindle_max_rpm, Some(24_000.0));
    let c = config(&with_drive(
        "[spindle]\nkind = \"drive\"\ncounts_per_rev = 4096\nmax_rpm = 6000\n",
    ));
    assert_eq!(
        c.spindle.kind,
        SpindleKind::Drive(SpindleDrive {
            counts_per_rev: 4096.0,
            on_bus: true
        })
    );
    assert_eq!(c.spindle.max_rpm, 6000.0);
    // A drive spindle beside a bus without a spindle drive.
    let text = format!("{}[spindle]\nkind = \"drive\"\n", bus("", "", ""));
    assert_eq!(
        refused(&text),
        format!(
            "{}`spindle.kind` is \"drive\" but [ethercat] lists no spindle drive, and with [ethercat] the spindle is not simulated: add a [[ethercat.drives]] with `axis = \"s\"` (mode \"csv\"), or make the kind \"outputs\" or \"none\"",
            at(&text, "\"drive\"")
        )
    );
    // A spindle drive on the bus with another kind.
    for kind in ["none", "outputs"] {
        let text = with_drive(&format!("[spindle]\nkind = \"{kind}\"\n"));
        assert_eq!(
            refused(&text),
            format!(
                "{}`spindle.kind` is \"{kind}\" but the EtherCAT drive at position 4 is the spindle's (`axis = \"s\"`): a spindle on the bus is a \"drive\"",
                at(&text, &format!("\"{kind}\""))
            )
        );
    }
    // Keys of another kind name the default kind on the bus.
    let text = format!("{}[spindle]\nspin_up_s = 1.25\n", bus("", "", ""));
    assert_eq!(
        refused(&text),
        format!(
            "{}`spindle.spin_up_s` is a key of kind \"outputs\", but `spindle.kind` is \"none\" by default; remove it",
            at(&text, "1.25")
        )
    );
}

#[test]
fn unknown_keys_of_the_machine_tables_are_named() {
    let cases = [
        (
            "[coolant]\nair = \"x\"\n",
            "air",
            "unknown key `coolant.air` (known here: `mist`, `flood`, `off_at_end`, `off_at_abort`, `off_at_fault`)",
        ),
        (
            "[tool_changer]\ncarousel = 12\n",
            "carousel",
            "unknown key `tool_changer.carousel` (known here: `kind`, `number_output`, `change_output`, `changed_input`, `timeout_s`)",
        ),
        (
            "[operator]\nfeed_hold = true\n",
            "feed_hold",
            "unknown key `operator.feed_hold` (known here: `optional_stop` or `single_block`)",
        ),
        (
            "[operator]\nblock_delete = true\n",
            "block_delete",
            "unknown key `operator.block_delete` (known here: `optional_stop` or `single_block`)",
        ),
    ];
    for (rest, needle, message) in cases {
        let text = format!("{AXES}{rest}");
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{rest}"
        );
    }
    let text = format!("{AXES}[operator]\nsingle_block = 1\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}`operator.single_block` must be true or false, found 1",
            at_value(&text, "single_block = 1")
        )
    );
    let text = format!("{AXES}[spindle]\nat_speed_timeout_s = \"ten\"\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}`spindle.at_speed_timeout_s` must be a number in seconds, found \"ten\"",
            at(&text, "\"ten\"")
        )
    );
    let text = format!("{AXES}[spindle]\nmax_rpm = \"fast\"\n");
    assert!(
        refused(&text).ends_with("`spindle.max_rpm` must be a number in rpm, found \"fast\""),
        "{}",
        refused(&text)
    );
}

#[test]
fn the_bundled_mill_is_a_simulated_machine_with_coolant_and_io() {
    let c = Config::builtin();
    let outs: Vec<(u8, &str)> =
        c.io.digital_outputs
            .iter()
            .map(|o| (o.number, o.name.as_str()))
            .collect();
    assert_eq!(
        outs,
        [
            (0, "mist"),
            (1, "flood"),
            (2, "clamp"),
            (3, "blast"),
            (4, "tool_change")
        ]
    );
    let ins: Vec<(u8, &str, bool)> =
        c.io.digital_inputs
            .iter()
            .map(|i| (i.number, i.name.as_str(), i.sim))
            .collect();
    // Inputs 3 to 11 are the home and limit switches (tests_homing.rs).
    assert_eq!(
        ins[..3],
        [
            (0, "part_present", true),
            (1, "door_closed", true),
            (2, "tool_changed", false)
        ]
    );
    assert_eq!(ins.len(), 12);
    assert_eq!(c.io.analog_output("laser_power").map(|a| a.number), Some(0));
    assert_eq!(c.io.analog_input("probe_force").map(|a| a.sim), Some(0.0));
    assert_eq!(c.coolant.mist, Some(io_ref("mist", 0)));
    assert_eq!(c.coolant.flood, Some(io_ref("flood", 1)));
    // An automatic changer on the simulated I/O (the kind's default is manual).
    assert_eq!(
        c.tool_changer,
        ToolChanger::Automatic(AutomaticToolChanger {
            number_output: io_ref("tool_number", 1),
            change_output: io_ref("tool_change", 4),
            changed_input: io_ref("tool_changed", 2),
            timeout_s: 30.0,
        })
    );
    assert_eq!(c.spindle, SpindleConfig::default());
    assert_eq!(c.operator, OperatorConfig::default());
    // Not set: the default, named after the machine, in the state directory.
    assert_eq!(c.daemon.state_file, None);
    assert_eq!(
        c.state_file().file_name(),
        Some(std::ffi::OsStr::new("default.state.toml"))
    );
    assert_eq!(
        c.machine_check(),
        MachineCaps {
            spindle_max_rpm: Some(24_000.0),
            spindle_orients: true,
            mist: true,
            flood: true,
            digital_outputs: 0b1_1111,
            digital_inputs: 0b1111_1111_1111,
            analog_outputs: 0b11,
            analog_inputs: 1,
            tool_changer: ToolChangerKind::Automatic,
        }
    );
}

/// The M-codes and S words a program uses, from its text: (code, the number after it).
fn words(program: &str, letter: char) -> Vec<f64> {
    let mut out = Vec::new();
    for line in program.lines() {
        // Comments: LinuxCNC `( )` and `;`, Heidenhain `;`, Sinumerik `;`.
        let code: String = {
            let mut depth = 0;
            line.split(';')
                .next()
                .unwrap_or("")
                .chars()
                .filter(|c| {
                    match c {
                        '(' => depth += 1,
                        ')' => depth -= 1,
                        _ => return depth == 0,
                    }
                    false
                })
                .collect()
        };
        let upper = code.to_ascii_uppercase();
        let b = upper.as_bytes();
        for (i, &ch) in b.iter().enumerate() {
            let starts_word = i == 0 || !b[i - 1].is_ascii_alphabetic();
            if ch == letter as u8 && starts_word {
                let digits: String = upper[i + 1..]
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.')
                    .collect();
                if let Ok(v) = digits.parse() {
                    out.push(v);
                }
            }
        }
    }
    out
}

/// Every bundled example program runs on the bundled machine: its spindle speeds within
/// `max_rpm`, its coolant codes with outputs, its tool changes with a changer, no I/O
/// code it does not have.
#[test]
fn the_bundled_examples_fit_the_bundled_machine() {
    let caps = Config::builtin().machine_check();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/examples");
    let mut programs = 0;
    let mut seen = std::collections::BTreeSet::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        programs += 1;
        for m in words(&text, 'M') {
            seen.insert(m as u32);
            match m as u32 {
                3 | 4 | 5 | 19 => assert!(caps.spindle_max_rpm.is_some(), "{path:?}"),
                6 => assert_ne!(caps.tool_changer, ToolChangerKind::None, "{path:?}"),
                7 => assert!(caps.mist, "{path:?}"),
                8 => assert!(caps.flood, "{path:?}"),
                62..=68 => panic!("{path:?}: M{m} needs its P/E word checked here"),
                _ => {}
            }
        }
        for s in words(&text, 'S') {
            assert!(s <= caps.spindle_max_rpm.unwrap_or(0.0), "{path:?}: S{s}");
        }
    }
    assert!(programs >= 6, "{programs} programs in {dir:?}");
    // The examples do use the spindle, flood coolant and tool changes.
    for m in [3, 5, 6, 8, 9] {
        assert!(seen.contains(&m), "M{m} in no example: {seen:?}");
    }
}

#[test]
fn the_ethercat_example_names_bus_bits_and_its_spindle_drive() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/ethercat-example.toml");
    let c = Config::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let bit = |position, bit| Some(BusBit { position, bit });
    let outs: Vec<(u8, &str, Option<BusBit>)> =
        c.io.digital_outputs
            .iter()
            .map(|o| (o.number, o.name.as_str(), o.bus_bit))
            .collect();
    assert_eq!(
        outs,
        [(0, "coolant", bit(4, 0)), (1, "spindle_enable", bit(4, 1))]
    );
    let ins: Vec<(u8, &str, Option<BusBit>)> =
        c.io.digital_inputs
            .iter()
            .map(|o| (o.number, o.name.as_str(), o.bus_bit))
            .collect();
    assert_eq!(
        ins,
        [
            (0, "estop_ok", bit(4, 0)),
            (1, "door_closed", bit(4, 1)),
            (2, "probe", bit(4, 2))
        ]
    );
    assert_eq!(
        c.spindle.kind,
        SpindleKind::Drive(SpindleDrive {
            counts_per_rev: 10_000.0,
            on_bus: true
        })
    );
    assert_eq!(
        (
            c.spindle.max_rpm,
            c.spindle.acceleration_rpm_s,
            c.spindle.at_speed_timeout_s
        ),
        (18_000.0, 6000.0, 8.0)
    );
    let drive = c
        .ethercat()
        .and_then(|b| b.spindle_drive())
        .expect("spindle drive");
    assert_eq!(drive.position, 3);
    assert_eq!(c.coolant.flood, Some(io_ref("coolant", 0)));
    assert_eq!(c.coolant.mist, None);
    assert_eq!(
        c.machine_check(),
        MachineCaps {
            spindle_max_rpm: Some(18_000.0),
            spindle_orients: false,
            mist: false,
            flood: true,
            digital_outputs: 0b11,
            digital_inputs: 0b111,
            analog_outputs: 0,
            analog_inputs: 0,
            tool_changer: ToolChangerKind::Manual,
        }
    );
}

#[test]
fn events_the_machine_cannot_do_are_refused_with_the_key_to_look_at() {
    use kerf_geom::{Event, EventCode as C};
    let caps = MachineCaps {
        spindle_max_rpm: Some(12000.0),
        spindle_orients: true,
        mist: false,
        flood: true,
        digital_outputs: 0b101,
        digital_inputs: 0b10,
        analog_outputs: 0b1,
        analog_inputs: 0,
        tool_changer: ToolChangerKind::Manual,
    };
    let ev = |code, value| Event::new(9, code, value);
    for ok in [
        ev(C::M3, None),
        ev(C::S, Some(12000.0)),
        ev(C::M8, None),
        ev(C::M9, None),
        ev(C::M6, None),
        ev(C::M62, Some(0.0)),
        ev(C::M65, Some(2.0)),
        ev(C::M66, Some(1.0)),
        ev(C::M68, Some(0.0)),
    ] {
        assert_eq!(caps.check_event(&ok), Ok(()), "{ok:?}");
    }
    let refused = |e: Event| caps.check_event(&e).unwrap_err();
    assert_eq!(
        refused(ev(C::S, Some(12000.5))),
        "S12000.5 is above the spindle's top speed, 12000 rpm (spindle.max_rpm)"
    );
    assert_eq!(
        refused(ev(C::M7, None)),
        "M7: this machine has no mist coolant output (coolant.mist)"
    );
    assert_eq!(
        refused(ev(C::M63, Some(1.0))),
        "M63 P1: this machine has no digital output 1 ([io] digital_outputs)"
    );
    assert_eq!(
        refused(ev(C::M66, Some(0.0))),
        "M66 P0: this machine has no digital input 0 ([io] digital_inputs)"
    );
    assert_eq!(
        refused(ev(C::M66Analog, Some(0.0))),
        "M66 E0: this machine has no analog input 0 ([io] analog_inputs)"
    );
    assert_eq!(
        refused(ev(C::M67, Some(3.0))),
        "M67 E3: this machine has no analog output 3 ([io] analog_outputs)"
    );
    let bare = MachineCaps {
        spindle_max_rpm: None,
        spindle_orients: false,
        tool_changer: ToolChangerKind::None,
        ..caps
    };
    assert_eq!(
        bare.check_event(&ev(C::M4, None)).unwrap_err(),
        "M4: this machine has no spindle (spindle.kind = \"none\")"
    );
    assert_eq!(
        bare.check_event(&ev(C::M6, None)).unwrap_err(),
        "M6: this machine has no tool changer (tool_changer.kind = \"none\")"
    );
    assert_eq!(caps.check_event(&ev(C::M19, None)), Ok(()));
    let no_orient = MachineCaps {
        spindle_orients: false,
        ..caps
    };
    assert!(
        no_orient
            .check_event(&ev(C::M19, None))
            .unwrap_err()
            .starts_with("M19: this machine's spindle cannot orient")
    );
    // Without a spindle any S passes: it commands nothing until M3 or M4.
    assert_eq!(bare.check_event(&ev(C::S, Some(1e9))), Ok(()));
}
