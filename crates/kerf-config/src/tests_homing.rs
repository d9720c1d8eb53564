//! Homing, jogging and the axes' switches: `[homing]`, `[jog]`, `[axes.*.homing]`,
//! `[axes.*.limit_switches]`, `[axes.*.sim]`; every key's range edges, every refusal
//! with its place, the defaults, and the bundled mill. Expected values are the files'
//! numbers written out by hand.

use std::path::Path;

use crate::ethercat::PdoEntry;

use crate::tests_ethercat::{AXES, at, at_nth, bus, load, refused};
use crate::tests_machine::at_value;
use crate::*;

/// [`AXES`] (X, Y, Z at ±10 mm, 100 mm/s) with `[io]`: digital inputs `xh` 0, `yh` 1,
/// `xmin` 2, `xmax` 3, `door` 4 (`sim = true`), `done` 5; digital output `lamp` 0;
/// analog output `num` 0; analog input `force` 0; then `rest`.
pub(crate) fn machine(rest: &str) -> String {
    format!(
        "{AXES}[io]\n\
         digital_inputs = [ {{ number = 0, name = \"xh\" }}, {{ number = 1, name = \"yh\" }}, \
         {{ number = 2, name = \"xmin\" }}, {{ number = 3, name = \"xmax\" }}, \
         {{ number = 4, name = \"door\", sim = true }}, {{ number = 5, name = \"done\" }} ]\n\
         digital_outputs = [ {{ number = 0, name = \"lamp\" }} ]\n\
         analog_outputs = [ {{ number = 0, name = \"num\" }} ]\n\
         analog_inputs = [ {{ number = 0, name = \"force\" }} ]\n\
         {rest}"
    )
}

/// `[axes.x.homing]` of kind "switch" on `xh` with these velocities, then `extra`.
fn x_switch(search: &str, latch: &str, extra: &str) -> String {
    format!(
        "[axes.x.homing]\nkind = \"switch\"\nswitch = \"xh\"\nsearch_velocity_mm_s = {search}\nlatch_velocity_mm_s = {latch}\n{extra}"
    )
}

fn config(text: &str) -> Config {
    load(text).unwrap_or_else(|e| panic!("refused: {e}\n{text}"))
}

/// Axis `i`'s setup.
fn setup(c: &Config, i: usize) -> AxisSetup {
    c.axis_setups()[i].unwrap_or_else(|| panic!("axis {i}"))
}

/// A rotary A axis, ±180 deg at 360 deg/s, with `rest` after it.
fn with_a(rest: &str) -> String {
    machine(&format!(
        "[axes.a]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -180.0\nmax_deg = 180.0\n{rest}"
    ))
}

#[test]
fn without_the_tables_every_axis_is_homed_at_start_and_homing_is_required() {
    let c = config(AXES);
    assert_eq!(
        c.homing,
        HomingConfig {
            required: true,
            unhomed_jog_pct: 10.0
        }
    );
    assert_eq!(
        c.jog,
        JogConfig {
            deadman_ms: 100,
            default_speed_pct: 25.0
        }
    );
    let none = AxisSetup {
        homing: AxisHoming {
            kind: HomingKind::None,
            switch_input: None,
            drive_method: 0,
            search_velocity_units_s: 0.0,
            latch_velocity_units_s: 0.0,
            acceleration_units_s2: 0.0,
            search_distance_units: 0.0,
            home_offset_units: 0.0,
            home_units: 0.0,
            final_speed_units_s: 0.0,
            sequence: 0,
        },
        limit_switches: LimitSwitches {
            min_input: None,
            max_input: None,
        },
        sim: SimAxis {
            start_units: 0.0,
            home_switch_units: None,
            min_limit_units: None,
            max_limit_units: None,
        },
    };
    assert_eq!(
        c.axis_setups(),
        [Some(none), Some(none), Some(none), None, None, None]
    );
    assert!(HomingKind::None.homed_at_start());
    assert!(HomingKind::Absolute.homed_at_start());
    assert!(!HomingKind::Switch.homed_at_start());
    // A rotary axis without the tables is the same; kind "none" written out too.
    let c = config(&with_a("[axes.y.homing]\nkind = \"none\"\n"));
    assert_eq!(c.axis_setups()[3], Some(none));
    assert_eq!(c.axis_setups()[1], Some(none));
}

#[test]
fn every_key_is_read_into_the_axis_setups() {
    let text = machine(&format!(
        "{}[axes.x.limit_switches]\nmin = \"xmin\"\nmax = \"xmax\"\n\
         [axes.x.sim]\nstart_mm = 3.5\nhome_switch_mm = -8.0\nmin_limit_mm = -12.0\nmax_limit_mm = 12.5\n\
         [axes.y.homing]\nkind = \"absolute\"\nhome_offset_mm = -123.25\n\
         [homing]\nrequired = false\nunhomed_jog_pct = 50\n\
         [jog]\ndeadman_ms = 250\ndefault_speed_pct = 5.5\n",
        x_switch(
            "-20.0",
            "1.5",
            "search_distance_mm = 40.0\nhome_offset_mm = -7.5\nhome_mm = 2.0\nfinal_speed_mm_s = 60.0\nsequence = 3\n"
        )
    ));
    let c = config(&text);
    assert_eq!(
        c.homing,
        HomingConfig {
            required: false,
            unhomed_jog_pct: 50.0
        }
    );
    assert_eq!(
        c.jog,
        JogConfig {
            deadman_ms: 250,
            default_speed_pct: 5.5
        }
    );
    assert_eq!(
        setup(&c, 0),
        AxisSetup {
            homing: AxisHoming {
                kind: HomingKind::Switch,
                switch_input: Some(0),
                drive_method: 0,
                search_velocity_units_s: -20.0,
                latch_velocity_units_s: 1.5,
                acceleration_units_s2: 0.0,
                search_distance_units: 40.0,
                home_offset_units: -7.5,
                home_units: 2.0,
                final_speed_units_s: 60.0,
                sequence: 3,
            },
            limit_switches: LimitSwitches {
                min_input: Some(2),
                max_input: Some(3),
            },
            sim: SimAxis {
                start_units: 3.5,
                home_switch_units: Some(-8.0),
                min_limit_units: Some(-12.0),
                max_limit_units: Some(12.5),
            },
        }
    );
    assert_eq!(
        setup(&c, 1).homing,
        AxisHoming {
            kind: HomingKind::Absolute,
            home_offset_units: -123.25,
            ..AxisHoming::default()
        }
    );
    assert_eq!(setup(&c, 2), AxisSetup::default());
}

#[test]
fn a_switch_homing_takes_its_defaults_from_the_axis() {
    let c = config(&machine(&x_switch("15.0", "-15.0", "")));
    // 1.5 × the travel of 20 mm; home at 0; back to it at the search's speed; sequence 0;
    // the latch point at machine 0.
    assert_eq!(
        setup(&c, 0).homing,
        AxisHoming {
            kind: HomingKind::Switch,
            switch_input: Some(0),
            drive_method: 0,
            search_velocity_units_s: 15.0,
            latch_velocity_units_s: -15.0,
            acceleration_units_s2: 0.0,
            search_distance_units: 30.0,
            home_offset_units: 0.0,
            home_units: 0.0,
            final_speed_units_s: 15.0,
            sequence: 0,
        }
    );
    // Without [axes.x.sim] the simulated machine is all defaults: the operator sets the
    // switch with `kerf input`.
    assert_eq!(setup(&c, 0).sim, SimAxis::default());
}

#[test]
fn rotary_axes_take_the_same_keys_in_degrees() {
    let text = with_a(
        "[axes.a.homing]\nkind = \"switch\"\nswitch = \"yh\"\nsearch_velocity_deg_s = 360.0\n\
         latch_velocity_deg_s = -2.0\nsearch_distance_deg = 400.0\nhome_offset_deg = 90.0\n\
         home_deg = -180.0\nfinal_speed_deg_s = 30.0\nsequence = 9\n\
         [axes.a.limit_switches]\nmax = \"xmax\"\n\
         [axes.a.sim]\nstart_deg = 10.0\nhome_switch_deg = 170.0\nmax_limit_deg = 185.0\n",
    );
    let c = config(&text);
    assert_eq!(
        setup(&c, 3),
        AxisSetup {
            homing: AxisHoming {
                kind: HomingKind::Switch,
                switch_input: Some(1),
                drive_method: 0,
                search_velocity_units_s: 360.0,
                latch_velocity_units_s: -2.0,
                acceleration_units_s2: 0.0,
                search_distance_units: 400.0,
                home_offset_units: 90.0,
                home_units: -180.0,
                final_speed_units_s: 30.0,
                sequence: 9,
            },
            limit_switches: LimitSwitches {
                min_input: None,
                max_input: Some(3),
            },
            sim: SimAxis {
                start_units: 10.0,
                home_switch_units: Some(170.0),
                min_limit_units: None,
                max_limit_units: Some(185.0),
            },
        }
    );
    // The default search distance is 1.5 × 360 deg.
    let c = config(&with_a(
        "[axes.a.homing]\nkind = \"switch\"\nswitch = \"yh\"\nsearch_velocity_deg_s = 10\nlatch_velocity_deg_s = 1\n",
    ));
    assert_eq!(setup(&c, 3).homing.search_distance_units, 540.0);
    // The linear keys are unknown on a rotary axis, and the other way round.
    let text = with_a("[axes.a.homing]\nkind = \"absolute\"\nhome_offset_mm = 1.0\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}unknown key `axes.a.homing.home_offset_mm` (known here: `kind`, `switch`, `method`, `search_velocity_deg_s`, `latch_velocity_deg_s`, `acceleration_deg_s2`, `search_distance_deg`, `home_offset_deg`, `home_deg`, `final_speed_deg_s`, `sequence`)",
            at(&text, "home_offset_mm")
        )
    );
    let text = with_a("[axes.a.sim]\nstart_mm = 1.0\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}unknown key `axes.a.sim.start_mm` (known here: `start_deg`, `home_switch_deg`, `min_limit_deg`, `max_limit_deg`)",
            at(&text, "start_mm")
        )
    );
    let text = machine("[axes.x.sim]\nstart_deg = 1.0\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}unknown key `axes.x.sim.start_deg` (known here: `start_mm`, `home_switch_mm`, `min_limit_mm`, `max_limit_mm`)",
            at(&text, "start_deg")
        )
    );
    // A rotary axis's messages speak degrees.
    let text = with_a(
        "[axes.a.homing]\nkind = \"switch\"\nswitch = \"yh\"\nsearch_velocity_deg_s = 361\nlatch_velocity_deg_s = 1\n",
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.a.homing.search_velocity_deg_s` must be non-zero and at most the axis's `velocity_deg_s`, 360 deg/s, in magnitude (its sign is the direction of the search), found 361",
            at(&text, "361")
        )
    );
    let text = with_a(
        "[axes.a.homing]\nkind = \"switch\"\nswitch = \"yh\"\nsearch_velocity_deg_s = 10\nlatch_velocity_deg_s = 1\nhome_deg = 180.5\n",
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.a.homing.home_deg` (180.5 deg) must lie within the travel of axis a, -180 to 180 deg (`min_deg`, `max_deg`)",
            at(&text, "180.5")
        )
    );
}

/// One range case: the text, whether it loads, and for a refusal the `key = value` line
/// at whose value the error is, and the message.
type Case = (String, Result<(), (String, String)>);

fn check_cases(cases: Vec<Case>) {
    for (text, want) in cases {
        match want {
            Ok(()) => {
                config(&text);
            }
            Err((line, message)) => assert_eq!(
                refused(&text),
                format!("{}{message}", at_value(&text, &line)),
                "{text}"
            ),
        }
    }
}

#[test]
fn homing_and_jog_values_are_accepted_to_their_range_edges_and_refused_beyond() {
    let homing = |v: &str| machine(&format!("[homing]\nunhomed_jog_pct = {v}\n"));
    let deadman = |v: &str| machine(&format!("[jog]\ndeadman_ms = {v}\n"));
    let speed = |v: &str| machine(&format!("[jog]\ndefault_speed_pct = {v}\n"));
    let pct = |key: &str, lo: &str, hi: &str, v: &str| {
        let last = key.rsplit('.').next().unwrap_or(key);
        Err((
            format!("{last} = {v}"),
            format!("`{key}` must be between {lo} and {hi} % (of the axis's velocity), found {v}"),
        ))
    };
    let ms = |v: &str| {
        Err((
            format!("deadman_ms = {v}"),
            format!("`jog.deadman_ms` must be a time in ms from 20 to 2000, found {v}"),
        ))
    };
    check_cases(vec![
        (homing("1"), Ok(())),
        (homing("100"), Ok(())),
        (
            homing("0.99"),
            pct("homing.unhomed_jog_pct", "1", "100", "0.99"),
        ),
        (
            homing("100.01"),
            pct("homing.unhomed_jog_pct", "1", "100", "100.01"),
        ),
        (deadman("20"), Ok(())),
        (deadman("2000"), Ok(())),
        (deadman("19"), ms("19")),
        (deadman("2001"), ms("2001")),
        (deadman("-5"), ms("-5")),
        (speed("0.1"), Ok(())),
        (speed("100"), Ok(())),
        (
            speed("0.09"),
            pct("jog.default_speed_pct", "0.1", "100", "0.09"),
        ),
        (
            speed("101"),
            pct("jog.default_speed_pct", "0.1", "100", "101"),
        ),
    ]);
    let c = config(&machine("[homing]\nrequired = false\n"));
    assert!(!c.homing.required);
    assert_eq!(config(&homing("1")).homing.unhomed_jog_pct, 1.0);
    assert_eq!(config(&deadman("2000")).jog.deadman_ms, 2000);
    assert_eq!(config(&speed("0.1")).jog.default_speed_pct, 0.1);
}

#[test]
fn axis_homing_values_are_accepted_to_their_range_edges_and_refused_beyond() {
    // The axis: velocity 100 mm/s, travel -10 to 10 mm.
    let sw = |search: &str, latch: &str, extra: &str| machine(&x_switch(search, latch, extra));
    let k = |key: &str| format!("axes.x.homing.{key}");
    // `written` in the file, `v` as the message prints it.
    let search_err_as = |written: &str, v: &str| {
        Err((
            format!("search_velocity_mm_s = {written}"),
            format!(
                "`{}` must be non-zero and at most the axis's `velocity_mm_s`, 100 mm/s, in magnitude (its sign is the direction of the search), found {v}",
                k("search_velocity_mm_s")
            ),
        ))
    };
    let search_err = |v: &str| search_err_as(v, v);
    let latch_err = |v: &str, max: &str| {
        Err((
            format!("latch_velocity_mm_s = {v}"),
            format!(
                "`{}` must be non-zero and at most the search's speed, {max} mm/s (`{}`), in magnitude, found {v}",
                k("latch_velocity_mm_s"),
                k("search_velocity_mm_s")
            ),
        ))
    };
    let above_zero = |key: &str, max: &str, unit: &str, why: &str, v: &str| {
        Err((
            format!("{key} = {v}"),
            format!(
                "`{}` must be above 0 and at most {max} {unit}{why}, found {v}",
                k(key)
            ),
        ))
    };
    let distance = |v: &str| above_zero("search_distance_mm", "1e7", "mm", "", v);
    let speed_why = " (the axis's `velocity_mm_s`)";
    let speed = |v: &str| above_zero("final_speed_mm_s", "100", "mm/s", speed_why, v);
    let coordinate = |v: &str| {
        Err((
            format!("home_offset_mm = {v}"),
            format!(
                "`{}` must be between -1000000 and 1000000 mm, found {v}",
                k("home_offset_mm")
            ),
        ))
    };
    let travel = |v: &str| {
        Err((
            format!("home_mm = {v}"),
            format!(
                "`{}` ({v} mm) must lie within the travel of axis x, -10 to 10 mm (`min_mm`, `max_mm`)",
                k("home_mm")
            ),
        ))
    };
    let sequence = |v: &str| {
        Err((
            format!("sequence = {v}"),
            format!(
                "`{}` must be a homing sequence number from 0 to 9, found {v}",
                k("sequence")
            ),
        ))
    };
    let absolute = |offset: &str| {
        machine(&format!(
            "[axes.x.homing]\nkind = \"absolute\"\nhome_offset_mm = {offset}\n"
        ))
    };
    check_cases(vec![
        // search_velocity_mm_s: non-zero, |v| at most the axis's 100 mm/s.
        (sw("100", "1", ""), Ok(())),
        (sw("-100", "1", ""), Ok(())),
        (sw("1e-9", "1e-9", ""), Ok(())),
        (sw("0", "1", ""), search_err("0")),
        (sw("100.001", "1", ""), search_err("100.001")),
        (sw("-100.5", "1", ""), search_err("-100.5")),
        (sw("nan", "1", ""), search_err_as("nan", "NaN")),
        // latch_velocity_mm_s: non-zero, |v| at most |search|, either sign.
        (sw("-20", "-20", ""), Ok(())),
        (sw("-20", "20", ""), Ok(())),
        (sw("-20", "20.5", ""), latch_err("20.5", "20")),
        (sw("-20", "-21", ""), latch_err("-21", "20")),
        (sw("-20", "0", ""), latch_err("0", "20")),
        // search_distance_mm: above 0, at most 1e7.
        (sw("-20", "1", "search_distance_mm = 1e-9\n"), Ok(())),
        (sw("-20", "1", "search_distance_mm = 1e7\n"), Ok(())),
        (sw("-20", "1", "search_distance_mm = 0\n"), distance("0")),
        (sw("-20", "1", "search_distance_mm = -5\n"), distance("-5")),
        (
            sw("-20", "1", "search_distance_mm = 1.1e7\n"),
            distance("1.1e7"),
        ),
        // home_offset_mm: ±1e6.
        (sw("-20", "1", "home_offset_mm = 1e6\n"), Ok(())),
        (sw("-20", "1", "home_offset_mm = -1e6\n"), Ok(())),
        (
            sw("-20", "1", "home_offset_mm = 1500000\n"),
            coordinate("1500000"),
        ),
        (absolute("-1e6"), Ok(())),
        (absolute("-2000000"), coordinate("-2000000")),
        // home_mm: within the travel, its ends included.
        (sw("-20", "1", "home_mm = -10\n"), Ok(())),
        (sw("-20", "1", "home_mm = 10\n"), Ok(())),
        (sw("-20", "1", "home_mm = 10.001\n"), travel("10.001")),
        (sw("-20", "1", "home_mm = -10.5\n"), travel("-10.5")),
        // final_speed_mm_s: above 0, at most the axis's velocity.
        (sw("-20", "1", "final_speed_mm_s = 100\n"), Ok(())),
        (sw("-20", "1", "final_speed_mm_s = 1e-9\n"), Ok(())),
        (sw("-20", "1", "final_speed_mm_s = 0\n"), speed("0")),
        (sw("-20", "1", "final_speed_mm_s = 100.5\n"), speed("100.5")),
        (sw("-20", "1", "final_speed_mm_s = -5\n"), speed("-5")),
        // sequence: 0 to 9.
        (sw("-20", "1", "sequence = 0\n"), Ok(())),
        (sw("-20", "1", "sequence = 9\n"), Ok(())),
        (sw("-20", "1", "sequence = 10\n"), sequence("10")),
        (sw("-20", "1", "sequence = -1\n"), sequence("-1")),
    ]);
    // The values at the edges are the values read.
    let h = setup(&config(&sw("-100", "100", "search_distance_mm = 1e7\nhome_offset_mm = -1e6\nhome_mm = 10\nfinal_speed_mm_s = 100\nsequence = 9\n")), 0).homing;
    assert_eq!(
        (
            h.search_velocity_units_s,
            h.latch_velocity_units_s,
            h.search_distance_units,
            h.home_offset_units,
            h.home_units,
            h.final_speed_units_s,
            h.sequence
        ),
        (-100.0, 100.0, 1e7, -1e6, 10.0, 100.0, 9)
    );
}

#[test]
fn home_mm_defaults_to_zero_only_when_zero_is_in_the_travel() {
    // X travels 20 to 30 mm here: without home_mm the default 0 is outside.
    let text = machine(&x_switch("-20", "1", "")).replacen(
        "min_mm = -10.0\nmax_mm = 10.0",
        "min_mm = 20.0\nmax_mm = 30.0",
        1,
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.homing.home_mm` is not given, and its default, 0 mm, is outside the travel of axis x, 20 to 30 mm (`min_mm`, `max_mm`): give the position the axis goes to after homing",
            at(&text, "\"switch\"")
        )
    );
    let c = config(&format!("{text}home_mm = 25.0\n"));
    assert_eq!(setup(&c, 0).homing.home_units, 25.0);
    // The search distance follows the travel: 1.5 × 10 mm.
    assert_eq!(setup(&c, 0).homing.search_distance_units, 15.0);
    // Kinds that do not move need no home position.
    let c = config(&text.replace(
        &x_switch("-20", "1", ""),
        "[axes.x.homing]\nkind = \"absolute\"\n",
    ));
    assert_eq!(setup(&c, 0).homing.kind, HomingKind::Absolute);
}

#[test]
fn simulated_positions_are_accepted_to_their_range_edges_and_refused_beyond() {
    let sim = |keys: &str| {
        machine(&format!(
            "{}[axes.x.limit_switches]\nmin = \"xmin\"\nmax = \"xmax\"\n[axes.x.sim]\n{keys}",
            x_switch("-20", "1", "")
        ))
    };
    let coord = |key: &str, v: &str| {
        Err((
            format!("{key} = {v}"),
            format!("`axes.x.sim.{key}` must be between -1000000 and 1000000 mm, found {v}"),
        ))
    };
    check_cases(vec![
        (sim("start_mm = -1e6\n"), Ok(())),
        (sim("start_mm = 1e6\n"), Ok(())),
        (
            sim("start_mm = 1000000.5\n"),
            coord("start_mm", "1000000.5"),
        ),
        (sim("home_switch_mm = 1e6\n"), Ok(())),
        (
            sim("home_switch_mm = -1010000\n"),
            coord("home_switch_mm", "-1010000"),
        ),
        (sim("min_limit_mm = -1e6\nmax_limit_mm = 1e6\n"), Ok(())),
        (
            sim("min_limit_mm = -2000000\n"),
            coord("min_limit_mm", "-2000000"),
        ),
        (sim("max_limit_mm = inf\n"), coord("max_limit_mm", "inf")),
        // The limits, when both are placed, in order.
        (sim("min_limit_mm = 4.0\nmax_limit_mm = 4.001\n"), Ok(())),
        (
            sim("min_limit_mm = 4.0\nmax_limit_mm = 4.0\n"),
            Err((
                "max_limit_mm = 4.0".into(),
                "`axes.x.sim.max_limit_mm` (4) must be greater than `axes.x.sim.min_limit_mm` (4)"
                    .into(),
            )),
        ),
        (
            sim("min_limit_mm = 5\nmax_limit_mm = -5\n"),
            Err((
                "max_limit_mm = -5".into(),
                "`axes.x.sim.max_limit_mm` (-5) must be greater than `axes.x.sim.min_limit_mm` (5)"
                    .into(),
            )),
        ),
        // A machine that starts beyond its home switch or on a limit switch is a case
        // to simulate, not a mistake.
        (
            sim("start_mm = -15.0\nhome_switch_mm = -8.0\nmin_limit_mm = -12.0\n"),
            Ok(()),
        ),
    ]);
    let s = setup(
        &config(&sim(
            "start_mm = -1e6\nhome_switch_mm = 1e6\nmin_limit_mm = -1e6\nmax_limit_mm = 1e6\n",
        )),
        0,
    )
    .sim;
    assert_eq!(
        s,
        SimAxis {
            start_units: -1e6,
            home_switch_units: Some(1e6),
            min_limit_units: Some(-1e6),
            max_limit_units: Some(1e6),
        }
    );
}

#[test]
fn the_kind_and_the_keys_of_its_kind_are_checked() {
    let cases: Vec<(String, &str, String)> = vec![
        (
            machine("[axes.x.homing]\nsequence = 1\n"),
            "[axes.x.homing]",
            "missing key `axes.x.homing.kind`".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"index\"\n"),
            "\"index\"",
            "`axes.x.homing.kind` must be \"none\", \"switch\", \"absolute\" or \"drive\", found `index`".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"drive\"\n"),
            "\"drive\"",
            "`axes.x.homing.kind` is \"drive\" needs `axes.x.homing.method`, the CiA 402 homing method (0x6098) the drive homes with".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nswitch = \"xh\"\n"),
            "switch = \"xh\"",
            "`axes.x.homing.switch` is a key of kind \"switch\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"none\"\nsearch_velocity_mm_s = 5\n"),
            "5\n",
            "`axes.x.homing.search_velocity_mm_s` is a key of kinds \"switch\" and \"drive\", but `axes.x.homing.kind` is \"none\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nlatch_velocity_mm_s = 5\n"),
            "5\n",
            "`axes.x.homing.latch_velocity_mm_s` is a key of kinds \"switch\" and \"drive\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nsearch_distance_mm = 5\n"),
            "5\n",
            "`axes.x.homing.search_distance_mm` is a key of kinds \"switch\" and \"drive\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nhome_mm = 5\n"),
            "5\n",
            "`axes.x.homing.home_mm` is a key of kinds \"switch\" and \"drive\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nfinal_speed_mm_s = 5\n"),
            "5\n",
            "`axes.x.homing.final_speed_mm_s` is a key of kinds \"switch\" and \"drive\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nsequence = 5\n"),
            "5\n",
            "`axes.x.homing.sequence` is a key of kinds \"switch\" and \"drive\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"none\"\nhome_offset_mm = 5\n"),
            "5\n",
            "`axes.x.homing.home_offset_mm` is a key of kinds \"switch\", \"absolute\" and \"drive\", but `axes.x.homing.kind` is \"none\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"switch\"\nsearch_velocity_mm_s = 5\nlatch_velocity_mm_s = 1\n"),
            "\"switch\"",
            "`axes.x.homing.kind` is \"switch\" needs `axes.x.homing.switch`, the digital input of [io] the home switch is wired to".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"switch\"\nswitch = \"xh\"\nlatch_velocity_mm_s = 1\n"),
            "\"switch\"",
            "`axes.x.homing.kind` is \"switch\" needs `axes.x.homing.search_velocity_mm_s`, the speed of the search for the switch, signed: its sign is the direction".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"switch\"\nswitch = \"xh\"\nsearch_velocity_mm_s = 5\n"),
            "\"switch\"",
            "`axes.x.homing.kind` is \"switch\" needs `axes.x.homing.latch_velocity_mm_s`, the speed of the move that latches the switch's edge, signed: the search's sign approaches the edge again after a back-off, the opposite sign leaves the switch".into(),
        ),
    ];
    for (text, needle, message) in cases {
        let place = if needle.contains(" = ") {
            at_value(&text, needle)
        } else {
            at(&text, needle)
        };
        assert_eq!(refused(&text), format!("{place}{message}"), "{text}");
    }
}

#[test]
fn switch_names_must_be_digital_inputs_of_io() {
    let cases: Vec<(String, &str, String)> = vec![
        (
            machine(&x_switch("-20", "1", "").replace("\"xh\"", "\"nowhere\"")),
            "\"nowhere\"",
            "`axes.x.homing.switch` names `nowhere`, which is not in [io]; it must be a digital input (`io.digital_inputs`)".into(),
        ),
        (
            machine(&x_switch("-20", "1", "").replace("\"xh\"", "\"lamp\"")),
            "\"lamp\"\n",
            "`axes.x.homing.switch` names `lamp`, which is a digital output (`io.digital_outputs`); it must be a digital input (`io.digital_inputs`)".into(),
        ),
        (
            machine(&x_switch("-20", "1", "").replace("\"xh\"", "\"force\"")),
            "\"force\"\n",
            "`axes.x.homing.switch` names `force`, which is an analog input (`io.analog_inputs`); it must be a digital input (`io.digital_inputs`)".into(),
        ),
        (
            machine("[axes.y.limit_switches]\nmin = \"ymin\"\n"),
            "\"ymin\"",
            "`axes.y.limit_switches.min` names `ymin`, which is not in [io]; it must be a digital input (`io.digital_inputs`)".into(),
        ),
        (
            machine("[axes.z.limit_switches]\nmax = \"lamp\"\n"),
            "\"lamp\"\n",
            "`axes.z.limit_switches.max` names `lamp`, which is a digital output (`io.digital_outputs`); it must be a digital input (`io.digital_inputs`)".into(),
        ),
        (
            AXES.to_string() + "[axes.x.limit_switches]\nmin = \"xmin\"\n",
            "\"xmin\"",
            "`axes.x.limit_switches.min` names `xmin`, which is not in [io]; it must be a digital input (`io.digital_inputs`)".into(),
        ),
    ];
    for (text, needle, message) in cases {
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{text}"
        );
    }
    // An empty limit switch table is no switch at all.
    let c = config(&machine("[axes.x.limit_switches]\n"));
    assert_eq!(setup(&c, 0).limit_switches, LimitSwitches::default());
}

#[test]
fn no_input_serves_two_functions() {
    let y_switch = |input: &str| {
        format!(
            "[axes.y.homing]\nkind = \"switch\"\nswitch = \"{input}\"\nsearch_velocity_mm_s = 5\nlatch_velocity_mm_s = 1\n"
        )
    };
    let changer = "[tool_changer]\nkind = \"automatic\"\nnumber_output = \"num\"\nchange_output = \"lamp\"\nchanged_input = \"done\"\n";
    let spindle = "[spindle]\nkind = \"outputs\"\nenable_output = \"lamp\"\nspeed_output = \"num\"\nspeed_output_scale = 0.001\nat_speed_input = \"done\"\n";
    // The needle's occurrence the error is at: the second function to name the input
    // (occurrence 0 is the input's entry in [io]).
    let cases: Vec<(String, &str, usize, String)> = vec![
        // Two axes' home switches, even homing in the same sequence.
        (
            machine(&format!("{}{}", x_switch("-20", "1", ""), y_switch("xh"))),
            "\"xh\"",
            2,
            "`axes.x.homing.switch` and `axes.y.homing.switch` both name the input `xh`; each machine function has its own input".into(),
        ),
        // A home switch that is also a limit switch (of its own axis or another).
        (
            machine(&format!(
                "{}[axes.x.limit_switches]\nmin = \"xh\"\n",
                x_switch("-20", "1", "")
            )),
            "\"xh\"",
            2,
            "`axes.x.homing.switch` and `axes.x.limit_switches.min` both name the input `xh`; each machine function has its own input".into(),
        ),
        (
            machine(&format!(
                "{}[axes.z.limit_switches]\nmax = \"xh\"\n",
                x_switch("-20", "1", "")
            )),
            "\"xh\"",
            2,
            "`axes.x.homing.switch` and `axes.z.limit_switches.max` both name the input `xh`; each machine function has its own input".into(),
        ),
        // Both ends of one axis on one input.
        (
            machine("[axes.y.limit_switches]\nmin = \"xmin\"\nmax = \"xmin\"\n"),
            "\"xmin\"",
            2,
            "`axes.y.limit_switches.min` and `axes.y.limit_switches.max` both name the input `xmin`; each machine function has its own input".into(),
        ),
        // The tool changer's and the spindle's inputs.
        (
            machine(&format!("{changer}[axes.x.limit_switches]\nmax = \"done\"\n")),
            "\"done\"",
            2,
            "`tool_changer.changed_input` and `axes.x.limit_switches.max` both name the input `done`; each machine function has its own input".into(),
        ),
        (
            machine(&format!("{}{spindle}", y_switch("done"))),
            "\"done\"",
            1,
            "`spindle.at_speed_input` and `axes.y.homing.switch` both name the input `done`; each machine function has its own input".into(),
        ),
    ];
    for (text, needle, nth, message) in cases {
        assert_eq!(
            refused(&text),
            format!("{}{message}", at_nth(&text, needle, nth)),
            "{text}"
        );
    }
    // Each on an input of its own, they load.
    let c = config(&machine(&format!(
        "{}{}[axes.x.limit_switches]\nmin = \"xmin\"\nmax = \"xmax\"\n{changer}",
        x_switch("-20", "1", ""),
        y_switch("yh")
    )));
    assert_eq!(
        c.axis_setups()
            .map(|s| s.and_then(|s| s.homing.switch_input)),
        [Some(0), Some(1), None, None, None, None]
    );
}

#[test]
fn the_simulated_machine_drives_only_switches_it_has_inputs_for() {
    let cases: Vec<(String, &str, String)> = vec![
        // A simulated home switch without a switch homing.
        (
            machine("[axes.x.sim]\nhome_switch_mm = -8.0\n"),
            "-8.0",
            "`axes.x.sim.home_switch_mm` places a simulated home switch, but axis x has no [axes.x.homing]: it needs kind \"switch\" or \"drive\"; remove it or home the axis on a switch".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\n[axes.x.sim]\nhome_switch_mm = -8.0\n"),
            "-8.0",
            "`axes.x.sim.home_switch_mm` places a simulated home switch, but `axes.x.homing.kind` is \"absolute\": it needs kind \"switch\" or \"drive\"; remove it or home the axis on a switch".into(),
        ),
        // A simulated limit switch without its input.
        (
            machine("[axes.x.sim]\nmin_limit_mm = -12.0\n"),
            "-12.0",
            "`axes.x.sim.min_limit_mm` places the simulated min limit switch, but `axes.x.limit_switches.min` names no input for it; add it or remove this key".into(),
        ),
        (
            machine("[axes.x.limit_switches]\nmin = \"xmin\"\n[axes.x.sim]\nmax_limit_mm = 12.0\n"),
            "12.0",
            "`axes.x.sim.max_limit_mm` places the simulated max limit switch, but `axes.x.limit_switches.max` names no input for it; add it or remove this key".into(),
        ),
        // A driven input with a start value of its own.
        (
            machine(&format!(
                "{}[axes.x.sim]\nhome_switch_mm = -8.0\n",
                x_switch("-20", "1", "")
            ))
            .replace("name = \"xh\" }", "name = \"xh\", sim = false }"),
            "false",
            "`io.digital_inputs[0].sim` sets the start value of `xh`, but the simulation sets that input from the axis's position (`axes.x.sim.home_switch_mm`); remove it".into(),
        ),
        (
            machine("[axes.y.limit_switches]\nmax = \"door\"\n[axes.y.sim]\nmax_limit_mm = 9.0\n"),
            "true",
            "`io.digital_inputs[4].sim` sets the start value of `door`, but the simulation sets that input from the axis's position (`axes.y.sim.max_limit_mm`); remove it".into(),
        ),
        (
            machine("[axes.x.sim]\nfriction = 1.0\n"),
            "friction",
            "unknown key `axes.x.sim.friction` (known here: `start_mm`, `home_switch_mm`, `min_limit_mm`, `max_limit_mm`)".into(),
        ),
    ];
    for (text, needle, message) in cases {
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{text}"
        );
    }
    // Switches the simulation does not place are the operator's: their inputs may keep a
    // start value (`door` starts on), and a switch homing needs no simulated switch.
    let c = config(&machine(&format!(
        "{}[axes.y.limit_switches]\nmax = \"door\"\n[axes.y.sim]\nstart_mm = 2.0\n",
        x_switch("-20", "1", "")
    )));
    assert_eq!(setup(&c, 1).limit_switches.max_input, Some(4));
    assert_eq!(
        setup(&c, 1).sim,
        SimAxis {
            start_units: 2.0,
            ..SimAxis::default()
        }
    );
    assert_eq!(setup(&c, 0).sim.home_switch_units, None);
    assert!(c.io.digital_input("door").is_some_and(|d| d.sim));
}

#[test]
fn on_ethercat_switches_are_bus_bits_and_the_simulated_machine_is_refused() {
    let io_bits = "inputs = { xh = 0, xmin = 5, xmax = 6 }\n";
    let on_bus = |rest: &str| {
        format!(
            "{}[io]\ndigital_inputs = [ {{ number = 7, name = \"xh\" }}, {{ number = 8, name = \"xmin\" }}, {{ number = 9, name = \"xmax\" }} ]\n{rest}",
            bus("", "", io_bits)
        )
    };
    let c = config(&on_bus(&format!(
        "{}[axes.x.limit_switches]\nmin = \"xmin\"\nmax = \"xmax\"\n",
        x_switch("-20", "1", "")
    )));
    let x = setup(&c, 0);
    assert_eq!(x.homing.switch_input, Some(7));
    assert_eq!(
        x.limit_switches,
        LimitSwitches {
            min_input: Some(8),
            max_input: Some(9)
        }
    );
    // The inputs are the bus's bits of those names.
    assert_eq!(
        c.io.digital_input("xmin").and_then(|i| i.bus_bit),
        Some(BusBit {
            position: 3,
            bit: 5
        })
    );
    assert_eq!(x.sim, SimAxis::default());
    // The simulated machine has no place beside real drives.
    let text = on_bus("[axes.z.sim]\nstart_mm = 1.0\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}[axes.z.sim] describes the simulated machine behind a simulated drive, but with [ethercat] the drives and their switches are real; remove it",
            at(&text, "[axes.z.sim]")
        )
    );
    // A switch that is no input bit of the bus is refused where [io] names it.
    let text = format!(
        "{}[io]\ndigital_inputs = [ {{ number = 7, name = \"yh\" }} ]\n",
        bus("", "", io_bits)
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`io.digital_inputs[0].name` is `yh`, which is not an input bit of any [[ethercat.io]]: with [ethercat], every digital input of [io] is a bit named in an I/O subdevice's `inputs`",
            at(&text, "\"yh\"")
        )
    );
}

#[test]
fn unknown_keys_and_wrong_types_are_named() {
    let cases = [
        (
            "[homing]\nrequird = true\n",
            "requird",
            "unknown key `homing.requird` (known here: `required` or `unhomed_jog_pct`)",
        ),
        (
            "[jog]\ndeadman_s = 0.1\n",
            "deadman_s",
            "unknown key `jog.deadman_s` (known here: `deadman_ms` or `default_speed_pct`)",
        ),
        (
            "[axes.x.homing]\nkind = \"none\"\nhome_velocity_mm_s = 1\n",
            "home_velocity_mm_s",
            "unknown key `axes.x.homing.home_velocity_mm_s` (known here: `kind`, `switch`, `method`, `search_velocity_mm_s`, `latch_velocity_mm_s`, `acceleration_mm_s2`, `search_distance_mm`, `home_offset_mm`, `home_mm`, `final_speed_mm_s`, `sequence`)",
        ),
        (
            "[axes.z.limit_switches]\nhome = \"zh\"\n",
            "home",
            "unknown key `axes.z.limit_switches.home` (known here: `min` or `max`)",
        ),
        (
            "[homing]\nrequired = \"yes\"\n",
            "\"yes\"",
            "`homing.required` must be true or false, found \"yes\"",
        ),
        (
            "[homing]\nunhomed_jog_pct = \"ten\"\n",
            "\"ten\"",
            "`homing.unhomed_jog_pct` must be a number in percent, found \"ten\"",
        ),
        (
            "[jog]\ndeadman_ms = 100.5\n",
            "100.5",
            "`jog.deadman_ms` must be a whole number of milliseconds, found 100.5",
        ),
        (
            "[axes.x.homing]\nkind = \"switch\"\nsearch_velocity_mm_s = \"fast\"\n",
            "\"fast\"",
            "`axes.x.homing.search_velocity_mm_s` must be a number in mm/s, found \"fast\"",
        ),
        (
            "[axes.x.homing]\nkind = 1\n",
            "1\n",
            "`axes.x.homing.kind` must be a string in double quotes, found 1",
        ),
    ];
    for (rest, needle, message) in cases {
        let text = machine(rest);
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{rest}"
        );
    }
}

/// The bundled mill homes on simulated switches: Z first, then X and Y together, every
/// switch an input of its own, every search finding its switch from power-up.
#[test]
fn the_bundled_mill_homes_on_simulated_switches() {
    let c = Config::builtin();
    assert_eq!(
        c.homing,
        HomingConfig {
            required: true,
            unhomed_jog_pct: 10.0
        }
    );
    assert_eq!(
        c.jog,
        JogConfig {
            deadman_ms: 100,
            default_speed_pct: 25.0
        }
    );
    let input = |name: &str| c.io.digital_input(name).map(|i| u32::from(i.number));
    let xy = |home: &str, min: &str, max: &str| AxisSetup {
        homing: AxisHoming {
            kind: HomingKind::Switch,
            switch_input: input(home),
            drive_method: 0,
            search_velocity_units_s: -100.0,
            latch_velocity_units_s: 2.0,
            acceleration_units_s2: 0.0,
            search_distance_units: 3000.0,
            home_offset_units: -100.0,
            home_units: 0.0,
            final_speed_units_s: 200.0,
            sequence: 1,
        },
        limit_switches: LimitSwitches {
            min_input: input(min),
            max_input: input(max),
        },
        sim: SimAxis {
            start_units: -80.0,
            home_switch_units: Some(-100.0),
            min_limit_units: Some(-1005.0),
            max_limit_units: Some(1005.0),
        },
    };
    let z = AxisSetup {
        homing: AxisHoming {
            kind: HomingKind::Switch,
            switch_input: input("z_home"),
            drive_method: 0,
            search_velocity_units_s: 50.0,
            latch_velocity_units_s: -2.0,
            acceleration_units_s2: 0.0,
            search_distance_units: 1500.0,
            home_offset_units: 50.0,
            home_units: 0.0,
            final_speed_units_s: 100.0,
            sequence: 0,
        },
        limit_switches: LimitSwitches {
            min_input: input("z_min"),
            max_input: input("z_max"),
        },
        sim: SimAxis {
            start_units: 40.0,
            home_switch_units: Some(50.0),
            min_limit_units: Some(-505.0),
            max_limit_units: Some(505.0),
        },
    };
    assert_eq!(
        c.axis_setups(),
        [
            Some(xy("x_home", "x_min", "x_max")),
            Some(xy("y_home", "y_min", "y_max")),
            Some(z),
            None,
            None,
            None
        ]
    );
    // The switches are inputs 3 to 11, after the inputs the example had; the ones before
    // keep their numbers and start values.
    let ins: Vec<(u8, &str, bool)> =
        c.io.digital_inputs
            .iter()
            .map(|i| (i.number, i.name.as_str(), i.sim))
            .collect();
    assert_eq!(
        ins,
        [
            (0, "part_present", true),
            (1, "door_closed", true),
            (2, "tool_changed", false),
            (3, "x_home", false),
            (4, "y_home", false),
            (5, "z_home", false),
            (6, "x_min", false),
            (7, "x_max", false),
            (8, "y_min", false),
            (9, "y_max", false),
            (10, "z_min", false),
            (11, "z_max", false),
        ]
    );
    // What the numbers mean on this machine, per axis: from start_mm each search reaches
    // its switch (in the search direction, within the search distance) before the limit
    // switch behind it; the switch lies within the travel, the limit switches just beyond
    // it; the latch point keeps the machine coordinate the drive counted; home within the
    // travel.
    let travel = [(-1000.0, 1000.0), (-1000.0, 1000.0), (-500.0, 500.0)];
    for (i, (min, max)) in travel.into_iter().enumerate() {
        let s = setup(&c, i);
        let h = s.homing;
        let home_switch = s.sim.home_switch_units.expect("a simulated home switch");
        let (lo, hi) = (
            s.sim.min_limit_units.expect("min limit"),
            s.sim.max_limit_units.expect("max limit"),
        );
        let to_switch = home_switch - s.sim.start_units;
        assert!(to_switch * h.search_velocity_units_s > 0.0, "axis {i}");
        assert!(to_switch.abs() < h.search_distance_units / 2.0, "axis {i}");
        assert!(min < home_switch && home_switch < max, "axis {i}");
        assert!(
            lo < min && max < hi && hi - max <= 10.0 && min - lo <= 10.0,
            "axis {i}"
        );
        // The limit switch behind the home switch in the search direction.
        let behind = if h.search_velocity_units_s < 0.0 {
            lo
        } else {
            hi
        };
        assert!((behind - home_switch).abs() >= 10.0, "axis {i}");
        assert_eq!(h.home_offset_units, home_switch, "axis {i}");
        assert!(min <= h.home_units && h.home_units <= max, "axis {i}");
        // The latch leaves the switch: the opposite sign, slower.
        assert!(h.latch_velocity_units_s * h.search_velocity_units_s < 0.0);
    }
}

/// The quick-start program runs within the bundled mill's travel from where homing
/// leaves the machine.
#[test]
fn the_quickstart_program_fits_the_homed_bundled_mill() {
    let c = Config::builtin();
    let setups = c.axis_setups();
    let mut settings = c.settings();
    for (i, s) in setups.iter().enumerate() {
        if let Some(s) = s {
            settings.start_mm_deg[i] = s.homing.home_units;
        }
    }
    assert_eq!(settings.start_mm_deg[..3], [0.0, 0.0, 0.0]);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/examples/quickstart.ngc");
    let text = std::fs::read(&path).expect("quickstart.ngc");
    let moves: Vec<kerf_gcode::Move> =
        kerf_gcode::Interpreter::new(&text[..], kerf_gcode::Dialect::LinuxCnc, settings)
            .filter_map(|item| match item.expect("a valid program") {
                kerf_gcode::Item::Move(m) => Some(m),
                _ => None,
            })
            .collect();
    assert!(moves.len() > 40, "{} moves", moves.len());
    assert_eq!(travel::check_moves(&moves, &c.axes), Ok(()));
}

/// [`machine`] with `[axes.x.homing]` of kind "drive" and `keys`, then `extra`.
fn x_drive(keys: &str, extra: &str) -> String {
    machine(&format!("[axes.x.homing]\nkind = \"drive\"\n{keys}{extra}"))
}

#[test]
fn a_drive_homing_reads_every_key_and_gives_its_objects_in_the_drives_counts() {
    let c = config(&x_drive(
        "method = 20\nsearch_velocity_mm_s = 20.0\nlatch_velocity_mm_s = 2.5\n\
         acceleration_mm_s2 = 500.0\nsearch_distance_mm = 15.0\nhome_offset_mm = -7.5\n\
         home_mm = 2.0\nfinal_speed_mm_s = 30.0\nsequence = 2\n",
        "[axes.x.drive]\ncounts_per_mm = 400.0\ndirection = -1\n\
         [axes.x.sim]\nstart_mm = 1.0\nhome_switch_mm = 4.25\n",
    ));
    assert_eq!(
        setup(&c, 0).homing,
        AxisHoming {
            kind: HomingKind::Drive,
            switch_input: None,
            drive_method: 20,
            search_velocity_units_s: 20.0,
            latch_velocity_units_s: 2.5,
            acceleration_units_s2: 500.0,
            search_distance_units: 15.0,
            home_offset_units: -7.5,
            home_units: 2.0,
            final_speed_units_s: 30.0,
            sequence: 2,
        }
    );
    assert_eq!(
        setup(&c, 0).sim,
        SimAxis {
            start_units: 1.0,
            home_switch_units: Some(4.25),
            ..SimAxis::default()
        }
    );
    assert!(!HomingKind::Drive.homed_at_start());
    // 400 counts/mm: 8000 and 1000 counts/s, 200 000 counts/s²; the offset with the
    // direction: -1 × 400 × -7.5 = 3000 counts.
    assert_eq!(
        c.drive_homing_objects(0),
        Some(DriveHomingObjects {
            method: 20,
            search_speed_counts_s: 8000,
            zero_speed_counts_s: 1000,
            acceleration_counts_s2: 200_000,
            home_offset_counts: 3000,
        })
    );
    // The switch at 4.25 mm of the drive's frame is at -1700 counts; 15 mm are 6000.
    assert_eq!(
        c.sim_homing(0),
        Some(kerf_drive::sim::SimHomingConfig {
            method: 20,
            search_speed_counts_s: 8000,
            zero_speed_counts_s: 1000,
            acceleration_counts_s2: 200_000,
            home_offset_counts: 3000,
            home_switch_counts: Some(-1700.0),
            search_limit_counts: 6000.0,
        })
    );
    // The other axes are not homed by their drives.
    for axis in [1, 2, 3, 6] {
        assert_eq!(c.drive_homing_objects(axis), None);
        assert_eq!(c.sim_homing(axis), None);
    }
}

#[test]
fn a_drive_homing_takes_its_defaults_from_the_axis() {
    // Method 37 moves nothing: no speeds needed, none written (0); the axis's
    // acceleration; 1.5 × the travel of 20 mm; home and offset 0; the final move at 10 %
    // of 100 mm/s.
    let c = config(&x_drive("method = 37\n", ""));
    assert_eq!(
        setup(&c, 0).homing,
        AxisHoming {
            kind: HomingKind::Drive,
            switch_input: None,
            drive_method: 37,
            search_velocity_units_s: 0.0,
            latch_velocity_units_s: 0.0,
            acceleration_units_s2: 1000.0,
            search_distance_units: 30.0,
            home_offset_units: 0.0,
            home_units: 0.0,
            final_speed_units_s: 10.0,
            sequence: 0,
        }
    );
    assert_eq!(
        c.drive_homing_objects(0),
        Some(DriveHomingObjects {
            method: 37,
            search_speed_counts_s: 0,
            zero_speed_counts_s: 0,
            acceleration_counts_s2: 1_000_000,
            home_offset_counts: 0,
        })
    );
    assert_eq!(
        c.sim_homing(0),
        Some(kerf_drive::sim::SimHomingConfig {
            method: 37,
            search_speed_counts_s: 0,
            zero_speed_counts_s: 0,
            acceleration_counts_s2: 1_000_000,
            home_offset_counts: 0,
            home_switch_counts: None,
            search_limit_counts: 30_000.0,
        })
    );
    // A method that moves: the final move at the search's speed; speeds of a fraction of
    // a count per second round to the nearest count, and never to 0.
    let c = config(&x_drive(
        "method = 21\nsearch_velocity_mm_s = 12.5\nlatch_velocity_mm_s = 0.0001\n",
        "",
    ));
    let h = setup(&c, 0).homing;
    assert_eq!(
        (
            h.drive_method,
            h.final_speed_units_s,
            h.acceleration_units_s2
        ),
        (21, 12.5, 1000.0)
    );
    let o = c.drive_homing_objects(0).unwrap();
    assert_eq!(
        (o.search_speed_counts_s, o.zero_speed_counts_s),
        (12_500, 1)
    );
    // Method 35 is 37's older number.
    assert_eq!(
        setup(&config(&x_drive("method = 35\n", "")), 0)
            .homing
            .drive_method,
        35
    );
}

#[test]
fn a_rotary_axis_homed_by_its_drive_takes_degrees() {
    let c = config(&with_a(
        "[axes.a.homing]\nkind = \"drive\"\nmethod = 22\nsearch_velocity_deg_s = 90\n\
         latch_velocity_deg_s = 9\nacceleration_deg_s2 = 3600\nhome_offset_deg = 45\nhome_deg = -90\n\
         [axes.a.drive]\ncounts_per_deg = 100\n[axes.a.sim]\nhome_switch_deg = -170\n",
    ));
    let h = setup(&c, 3).homing;
    assert_eq!(
        (
            h.kind,
            h.drive_method,
            h.search_velocity_units_s,
            h.latch_velocity_units_s,
            h.acceleration_units_s2,
            h.search_distance_units,
            h.home_offset_units,
            h.home_units,
            h.final_speed_units_s,
        ),
        (
            HomingKind::Drive,
            22,
            90.0,
            9.0,
            3600.0,
            540.0,
            45.0,
            -90.0,
            90.0
        )
    );
    assert_eq!(
        c.sim_homing(3),
        Some(kerf_drive::sim::SimHomingConfig {
            method: 22,
            search_speed_counts_s: 9000,
            zero_speed_counts_s: 900,
            acceleration_counts_s2: 360_000,
            home_offset_counts: 4500,
            home_switch_counts: Some(-17_000.0),
            search_limit_counts: 54_000.0,
        })
    );
    // Its messages speak degrees.
    let text =
        with_a("[axes.a.homing]\nkind = \"drive\"\nmethod = 37\nacceleration_deg_s2 = 3601\n");
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.a.homing.acceleration_deg_s2` must be above 0 and at most 3600 deg/s² (the axis's `acceleration_deg_s2`), found 3601",
            at_value(&text, "acceleration_deg_s2 = 3601")
        )
    );
}

#[test]
fn drive_homing_values_are_accepted_to_their_range_edges_and_refused_beyond() {
    let moving = |extra: &str| {
        x_drive(
            &format!("method = 19\nsearch_velocity_mm_s = 20\nlatch_velocity_mm_s = 2\n{extra}"),
            "",
        )
    };
    let speed = "(the axis's `velocity_mm_s`; kind \"drive\" takes a speed: the method gives the direction)";
    let err = |line: &str, message: String| Err((line.to_string(), message));
    let mut cases: Vec<Case> = vec![
        // The search's speed: above 0, at most the axis's 100 mm/s.
        (
            x_drive("method = 20\nsearch_velocity_mm_s = 100\nlatch_velocity_mm_s = 100\n", ""),
            Ok(()),
        ),
        (
            x_drive("method = 20\nsearch_velocity_mm_s = 100.01\nlatch_velocity_mm_s = 1\n", ""),
            err(
                "search_velocity_mm_s = 100.01",
                format!("`axes.x.homing.search_velocity_mm_s` must be above 0 and at most 100 mm/s {speed}, found 100.01"),
            ),
        ),
        (
            x_drive("method = 20\nsearch_velocity_mm_s = -5\nlatch_velocity_mm_s = 1\n", ""),
            err(
                "search_velocity_mm_s = -5",
                format!("`axes.x.homing.search_velocity_mm_s` must be above 0 and at most 100 mm/s {speed}, found -5"),
            ),
        ),
        (
            x_drive("method = 20\nsearch_velocity_mm_s = 0\nlatch_velocity_mm_s = 1\n", ""),
            err(
                "search_velocity_mm_s = 0",
                format!("`axes.x.homing.search_velocity_mm_s` must be above 0 and at most 100 mm/s {speed}, found 0"),
            ),
        ),
        // The zero speed: above 0, at most the search's.
        (
            x_drive("method = 20\nsearch_velocity_mm_s = 20\nlatch_velocity_mm_s = 20.5\n", ""),
            err(
                "latch_velocity_mm_s = 20.5",
                "`axes.x.homing.latch_velocity_mm_s` must be above 0 and at most 20 mm/s (`axes.x.homing.search_velocity_mm_s`), found 20.5".into(),
            ),
        ),
        (
            x_drive("method = 20\nsearch_velocity_mm_s = 20\nlatch_velocity_mm_s = -1\n", ""),
            err(
                "latch_velocity_mm_s = -1",
                "`axes.x.homing.latch_velocity_mm_s` must be above 0 and at most 20 mm/s (`axes.x.homing.search_velocity_mm_s`), found -1".into(),
            ),
        ),
        // Without a search speed (method 37) the zero speed is bounded by the axis's.
        (x_drive("method = 37\nlatch_velocity_mm_s = 100\n", ""), Ok(())),
        (
            x_drive("method = 37\nlatch_velocity_mm_s = 101\n", ""),
            err(
                "latch_velocity_mm_s = 101",
                format!("`axes.x.homing.latch_velocity_mm_s` must be above 0 and at most 100 mm/s {speed}, found 101"),
            ),
        ),
        // The acceleration: above 0, at most the axis's 1000 mm/s².
        (moving("acceleration_mm_s2 = 1000\n"), Ok(())),
        (moving("acceleration_mm_s2 = 0.001\n"), Ok(())),
        (
            moving("acceleration_mm_s2 = 1000.5\n"),
            err(
                "acceleration_mm_s2 = 1000.5",
                "`axes.x.homing.acceleration_mm_s2` must be above 0 and at most 1000 mm/s² (the axis's `acceleration_mm_s2`), found 1000.5".into(),
            ),
        ),
        (
            moving("acceleration_mm_s2 = 0\n"),
            err(
                "acceleration_mm_s2 = 0",
                "`axes.x.homing.acceleration_mm_s2` must be above 0 and at most 1000 mm/s² (the axis's `acceleration_mm_s2`), found 0".into(),
            ),
        ),
        // The simulated drive's search limit, as kind "switch"'s search distance.
        (moving("search_distance_mm = 1e7\n"), Ok(())),
        (
            moving("search_distance_mm = 0\n"),
            err(
                "search_distance_mm = 0",
                "`axes.x.homing.search_distance_mm` must be above 0 and at most 1e7 mm, found 0".into(),
            ),
        ),
        // The home offset: a coordinate, within 32-bit counts (1e6 mm at 1000 counts/mm
        // is 1e9 counts).
        (moving("home_offset_mm = -1e6\n"), Ok(())),
        (
            moving("home_offset_mm = 1000000.5\n"),
            err(
                "home_offset_mm = 1000000.5",
                "`axes.x.homing.home_offset_mm` must be between -1000000 and 1000000 mm, found 1000000.5".into(),
            ),
        ),
        // Home within the travel, the final speed within the axis's velocity, the
        // sequence 0 to 9: as for kind "switch".
        (moving("home_mm = 10\nfinal_speed_mm_s = 100\nsequence = 9\n"), Ok(())),
        (
            moving("home_mm = 10.5\n"),
            err(
                "home_mm = 10.5",
                "`axes.x.homing.home_mm` (10.5 mm) must lie within the travel of axis x, -10 to 10 mm (`min_mm`, `max_mm`)".into(),
            ),
        ),
        (
            moving("final_speed_mm_s = 100.5\n"),
            err(
                "final_speed_mm_s = 100.5",
                "`axes.x.homing.final_speed_mm_s` must be above 0 and at most 100 mm/s (the axis's `velocity_mm_s`), found 100.5".into(),
            ),
        ),
        (
            moving("sequence = 10\n"),
            err(
                "sequence = 10",
                "`axes.x.homing.sequence` must be a homing sequence number from 0 to 9, found 10".into(),
            ),
        ),
    ];
    // The methods of the simulated drive, and no other.
    for m in [19, 20, 21, 22] {
        cases.push((
            x_drive(
                &format!("method = {m}\nsearch_velocity_mm_s = 20\nlatch_velocity_mm_s = 2\n"),
                "",
            ),
            Ok(()),
        ));
    }
    for m in [35, 37] {
        cases.push((x_drive(&format!("method = {m}\n"), ""), Ok(())));
    }
    for m in ["0", "1", "17", "18", "23", "34", "36", "38", "-1", "300"] {
        cases.push((
            x_drive(&format!("method = {m}\n"), ""),
            err(
                &format!("method = {m}"),
                format!("`axes.x.homing.method` must be a homing method the simulated drive supports (19, 20, 21, 22, 35, 37), found {m}"),
            ),
        ));
    }
    check_cases(cases);
}

#[test]
fn a_drive_homing_refuses_what_its_drive_cannot_hold_in_counts() {
    // 3000 counts/mm: 1e6 mm is 3e9 counts, beyond 0x607C's i32 (the travel of 10 mm
    // fits).
    let text = x_drive(
        "method = 37\nhome_offset_mm = 1e6\n",
        "[axes.x.drive]\ncounts_per_mm = 3000\n",
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.homing.home_offset_mm` is 3e9 counts at the drive's 3000 counts/mm, beyond the 32-bit home offset 0x607C (2147483647)",
            at_value(&text, "home_offset_mm = 1e6")
        )
    );
    // 1e8 counts/mm: 50 mm/s is 5e9 counts/s, beyond 0x6099's u32.
    let text = x_drive(
        "method = 20\nsearch_velocity_mm_s = 50\nlatch_velocity_mm_s = 1\nacceleration_mm_s2 = 0.01\n",
        "[axes.x.drive]\ncounts_per_mm = 1e8\n",
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.homing.search_velocity_mm_s` is 5e9 counts/s at the drive's 1e8 counts/mm, beyond the 32-bit 0x6099:01 (4294967295)",
            at_value(&text, "search_velocity_mm_s = 50")
        )
    );
    // The default acceleration, the axis's 1000 mm/s², is 1e11 counts/s² there: refused
    // at the kind, naming the key to give.
    let text = x_drive(
        "method = 20\nsearch_velocity_mm_s = 1\nlatch_velocity_mm_s = 1\n",
        "[axes.x.drive]\ncounts_per_mm = 1e8\n",
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.homing.acceleration_mm_s2` is 1e11 counts/s² at the drive's 1e8 counts/mm, beyond the 32-bit 0x609A (4294967295)",
            at(&text, "\"drive\"")
        )
    );
}

#[test]
fn the_keys_of_a_drive_homing_are_its_own() {
    let cases: Vec<(String, &str, String)> = vec![
        (
            x_drive("search_velocity_mm_s = 5\nlatch_velocity_mm_s = 1\n", ""),
            "\"drive\"",
            "`axes.x.homing.kind` is \"drive\" needs `axes.x.homing.method`, the CiA 402 homing method (0x6098) the drive homes with".into(),
        ),
        (
            x_drive("method = 19\nlatch_velocity_mm_s = 1\n", ""),
            "\"drive\"",
            "`axes.x.homing.kind` is \"drive\" needs `axes.x.homing.search_velocity_mm_s`, the drive's speed during the search for the switch (0x6099:01), which method 19 needs".into(),
        ),
        (
            x_drive("method = 22\nsearch_velocity_mm_s = 5\n", ""),
            "\"drive\"",
            "`axes.x.homing.kind` is \"drive\" needs `axes.x.homing.latch_velocity_mm_s`, the drive's speed during the search for zero (0x6099:02), which method 22 needs".into(),
        ),
        (
            x_drive("method = 37\nswitch = \"xh\"\n", ""),
            "switch = \"xh\"",
            "`axes.x.homing.switch` is a key of kind \"switch\", but `axes.x.homing.kind` is \"drive\"; remove it".into(),
        ),
        (
            machine(&x_switch("-20", "1", "method = 20\n")),
            "method = 20",
            "`axes.x.homing.method` is a key of kind \"drive\", but `axes.x.homing.kind` is \"switch\"; remove it".into(),
        ),
        (
            machine(&x_switch("-20", "1", "acceleration_mm_s2 = 20\n")),
            "acceleration_mm_s2 = 20",
            "`axes.x.homing.acceleration_mm_s2` is a key of kind \"drive\", but `axes.x.homing.kind` is \"switch\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"absolute\"\nmethod = 37\n"),
            "method = 37",
            "`axes.x.homing.method` is a key of kind \"drive\", but `axes.x.homing.kind` is \"absolute\"; remove it".into(),
        ),
        (
            machine("[axes.x.homing]\nkind = \"none\"\nacceleration_mm_s2 = 5\n"),
            "acceleration_mm_s2 = 5",
            "`axes.x.homing.acceleration_mm_s2` is a key of kind \"drive\", but `axes.x.homing.kind` is \"none\"; remove it".into(),
        ),
        (
            x_drive("method = 37\n", "[axes.x.sim]\nhome_switch_mm = 3\n"),
            "home_switch_mm = 3",
            "`axes.x.sim.home_switch_mm` places a simulated home switch, but `axes.x.homing.method` 37 homes where the axis stands, without a switch; remove it".into(),
        ),
        (
            x_drive("method = 1.5\n", ""),
            "1.5",
            "`axes.x.homing.method` must be a whole number, found 1.5".into(),
        ),
    ];
    for (text, needle, message) in cases {
        let place = if needle.contains(" = ") {
            at_value(&text, needle)
        } else {
            at(&text, needle)
        };
        assert_eq!(refused(&text), format!("{place}{message}"), "{text}");
    }
    // A method with a switch may have none on the simulated machine: its search then
    // ends in a homing error.
    let c = config(&x_drive(
        "method = 21\nsearch_velocity_mm_s = 5\nlatch_velocity_mm_s = 1\n",
        "",
    ));
    assert_eq!(c.sim_homing(0).map(|s| s.home_switch_counts), Some(None));
}

#[test]
fn on_ethercat_a_drive_homing_takes_any_cia_402_method_and_no_simulated_limit() {
    let on_bus = |homing: &str| {
        format!(
            "{}[axes.x.homing]\nkind = \"drive\"\n{homing}",
            bus("", "", "")
        )
    };
    for m in [1, 17, 34, 35, 37] {
        let c = config(&on_bus(&format!(
            "method = {m}\nsearch_velocity_mm_s = 10\nlatch_velocity_mm_s = 1\nhome_offset_mm = 2.5\n"
        )));
        assert_eq!(
            c.drive_homing_objects(0),
            Some(DriveHomingObjects {
                method: m,
                search_speed_counts_s: 10_000,
                zero_speed_counts_s: 1000,
                acceleration_counts_s2: 1_000_000,
                home_offset_counts: 2500,
            })
        );
        // Not a simulated drive.
        assert_eq!(c.sim_homing(0), None);
    }
    for m in ["0", "38", "-3", "128"] {
        let text = on_bus(&format!(
            "method = {m}\nsearch_velocity_mm_s = 10\nlatch_velocity_mm_s = 1\n"
        ));
        assert_eq!(
            refused(&text),
            format!(
                "{}`axes.x.homing.method` must be a CiA 402 homing method from 1 to 37, found {m}",
                at_value(&text, &format!("method = {m}"))
            )
        );
    }
    let text = on_bus(
        "method = 20\nsearch_velocity_mm_s = 10\nlatch_velocity_mm_s = 1\nsearch_distance_mm = 30\n",
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.homing.search_distance_mm` is the simulated drive's search limit for kind \"drive\"; with [ethercat] the drive searches within its own limits; remove it",
            at_value(&text, "search_distance_mm = 30")
        )
    );
}

#[test]
fn on_ethercat_a_drive_homing_maps_the_mode_and_writes_its_objects_at_bring_up() {
    let homing = "[axes.x.homing]\nkind = \"drive\"\nmethod = 19\nsearch_velocity_mm_s = 10\n\
                  latch_velocity_mm_s = 1\nhome_offset_mm = 2.5\n";
    let c = config(&format!("{}{homing}", bus("", "", "")));
    let bus_side = c.ethercat.as_ref().expect("[ethercat]");
    let x = &bus_side.drives[0];
    let entry = |index, bits| PdoEntry {
        index,
        subindex: 0,
        bits,
    };
    // The CSP default with the mode of operation out and its display in, 8 bits each,
    // at the end: controlword, target position, 0x6060; and the six inputs, 0x6061.
    assert_eq!(
        x.rx_pdo.entries,
        vec![entry(0x6040, 16), entry(0x607A, 32), entry(0x6060, 8)]
    );
    assert_eq!(x.tx_pdo.entries.last(), Some(&entry(0x6061, 8)));
    assert_eq!(x.tx_pdo.entries.len(), 7);
    // 1000 counts/mm (the bench's default scale): 10 000 and 1000 counts/s, the axis's
    // 1000 mm/s², 2500 counts of offset.
    assert_eq!(
        x.homing,
        Some(DriveHomingObjects {
            method: 19,
            search_speed_counts_s: 10_000,
            zero_speed_counts_s: 1000,
            acceleration_counts_s2: 1_000_000,
            home_offset_counts: 2500,
        })
    );
    // The axes not homed by their drives keep the default mapping and write nothing.
    for d in &bus_side.drives[1..] {
        assert_eq!(d.homing, None);
        assert_eq!(d.rx_pdo.entries.len(), 2);
        assert_eq!(d.tx_pdo.entries.len(), 6);
    }
    // A mapping of the file's must carry the mode: the homing switches it cyclically.
    let rx = "rx_pdo = [\n    { index = 0x6040, subindex = 0, bits = 16 },\n    \
              { index = 0x607A, subindex = 0, bits = 32 },\n]\n";
    let text = format!("{}{homing}", bus("", rx, ""));
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].rx_pdo` must map the modes of operation 0x6060:00 (8 bits): axis x homes by its drive (`axes.x.homing.kind = \"drive\"`), which the daemon switches to homing mode (6) and back in the cyclic data",
            at(&text, "[\n    { index = 0x6040")
        )
    );
    let with_mode = "rx_pdo = [\n    { index = 0x6040, subindex = 0, bits = 16 },\n    \
                     { index = 0x607A, subindex = 0, bits = 32 },\n    \
                     { index = 0x6060, subindex = 0, bits = 8 },\n]\n";
    let c = config(&format!("{}{homing}", bus("", with_mode, "")));
    assert_eq!(
        c.ethercat.as_ref().unwrap().drives[0].rx_pdo.entries[2],
        entry(0x6060, 8)
    );
    // Its objects are the homing table's, not the start-up list's.
    let sdo = "sdo = [{ index = 0x6098, subindex = 0, type = \"i8\", value = 19 }]\n";
    let text = format!("{}{homing}", bus("", sdo, ""));
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].sdo[0]` writes 0x6098, which the bring-up sets from [axes.x.homing]; set it there",
            at(&text, "0x6098")
        )
    );
    // Without the homing, the start-up list may write them (a drive homed otherwise).
    let c = config(&bus("", sdo, ""));
    assert_eq!(c.ethercat.as_ref().unwrap().drives[0].sdo.len(), 1);
}
