//! The reference rows of `[homing]`, `[jog]` and each axis's `[axes.*.homing]`,
//! `[axes.*.limit_switches]` and `[axes.*.sim]`, from the constants the checker uses.

use crate::*;

use super::{KeyDoc, f, k, rf, ri};

/// The rows of the axes' tables, in the order of docs/CONFIG.md (after `axes.*.drive`).
pub(super) fn axis_keys() -> Vec<KeyDoc> {
    let none = || "none".to_string();
    let coord = || format!("±{}", f(MAX_COORDINATE_MM));
    let for_switch = || "required for \"switch\"".to_string();
    let input = || "a digital input of [io]".to_string();
    let moving =
        || "required for \"switch\"; for \"drive\" unless `method` is 35 or 37".to_string();
    let methods: Vec<String> = kerf_drive::sim::SUPPORTED_METHODS
        .iter()
        .map(|m| m.to_string())
        .collect();
    vec![
        k(
            "axes.*.homing",
            "kind \"none\"".into(),
            "table".into(),
            "How the axis finds its machine coordinates (`[axes.x.homing]`, ...), keys below: lengths in mm, on A, B, C in degrees (`_deg`, `_deg_s`, `_deg_s2`). Each key is refused for the kinds that do not take it. `kerf home` homes the axes; until all are homed, programs and MDI are refused (`homing.required`).",
        ),
        k(
            "axes.*.homing.kind",
            "required".into(),
            "\"none\", \"switch\", \"absolute\" or \"drive\"".into(),
            "\"none\": homed at start, the machine coordinates are the drive's from power-up (as before homing existed). \"switch\": Kerf searches the home switch at `search_velocity`, latches its edge at `latch_velocity`, sets the latch point's machine coordinate to `home_offset` and moves to `home`. \"absolute\": an absolute encoder, homed at start without motion, machine coordinate = encoder position + `home_offset`. \"drive\": the drive homes itself in CiA 402 homing mode (6) with `method` (0x6098), `search_velocity` and `latch_velocity` (0x6099:01, :02), `acceleration` (0x609A) and `home_offset` (0x607C); its home position then reads `home_offset`, and Kerf moves the axis to `home` (docs/DRIVES.md, \"Homing by the drive\").",
        ),
        k(
            "axes.*.homing.switch",
            for_switch(),
            input(),
            "Kind \"switch\": the home switch's input (with [ethercat] a bit of the bus, as every input of [io]); no other function may use it.",
        ),
        k(
            "axes.*.homing.method",
            "required for \"drive\"".into(),
            format!(
                "on simulated drives {}; on EtherCAT {}",
                methods.join(", "),
                ri(DRIVE_HOMING_METHOD_RANGE)
            ),
            "Kind \"drive\": the CiA 402 homing method (0x6098). The simulated drive's: 19, 20 (home switch on the positive side; the home position where it falls moving negative, or rises moving positive), 21, 22 (on the negative side; where it falls moving positive, or rises moving negative), 35 and 37 (the current position is home, no motion). On EtherCAT any method of CiA 402 the drive supports.",
        ),
        k(
            "axes.*.homing.search_velocity_mm_s",
            moving(),
            "\"switch\": non-zero, magnitude at most `velocity_mm_s`; \"drive\": above 0, at most `velocity_mm_s`".into(),
            "Kind \"switch\": speed of the search for the switch, signed: its sign is the direction. Kind \"drive\": the drive's speed during the search for the switch (0x6099:01, in counts/s through the axis's scale); the method gives the direction.",
        ),
        k(
            "axes.*.homing.search_velocity_deg_s",
            moving(),
            "as `search_velocity_mm_s`, with `velocity_deg_s`".into(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.latch_velocity_mm_s",
            moving(),
            "\"switch\": non-zero, magnitude at most that of `search_velocity_mm_s`; \"drive\": above 0, at most `search_velocity_mm_s`".into(),
            "Kind \"switch\": speed of the latch move, signed: the search's sign backs off and approaches the switch's edge again, the opposite sign leaves the switch and latches where it releases. Kind \"drive\": the drive's speed during the search for zero (0x6099:02), its slow approach of the edge.",
        ),
        k(
            "axes.*.homing.latch_velocity_deg_s",
            moving(),
            "as `latch_velocity_mm_s`".into(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.acceleration_mm_s2",
            "`acceleration_mm_s2` of the axis".into(),
            "above 0, at most the axis's `acceleration_mm_s2`".into(),
            "Kind \"drive\": the homing acceleration (0x609A), also the drive's deceleration in its stops.",
        ),
        k(
            "axes.*.homing.acceleration_deg_s2",
            "`acceleration_deg_s2` of the axis".into(),
            "above 0, at most the axis's `acceleration_deg_s2`".into(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.search_distance_mm",
            format!(
                "{} × (`max_mm` - `min_mm`)",
                f(DEFAULT_SEARCH_DISTANCE_TRAVELS)
            ),
            format!("above 0, at most {}", f(MAX_SEARCH_DISTANCE_MM)),
            "Kind \"switch\": the longest search; a switch not found within it is a fault naming the axis. Kind \"drive\" on a simulated drive: the simulated drive's search limit, after which it reports a homing error (refused with [ethercat]: a real drive has its own).",
        ),
        k(
            "axes.*.homing.search_distance_deg",
            format!(
                "{} × (`max_deg` - `min_deg`)",
                f(DEFAULT_SEARCH_DISTANCE_TRAVELS)
            ),
            format!("above 0, at most {}", f(MAX_SEARCH_DISTANCE_MM)),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.home_offset_mm",
            f(DEFAULT_HOME_OFFSET_MM),
            format!("{}; kind \"drive\": within the drive's 32-bit counts", coord()),
            "Kind \"switch\": the machine coordinate of the switch's latch point; kind \"absolute\": the machine coordinate of encoder position 0; kind \"drive\": the machine coordinate of the drive's home position, written to the drive as its home offset (0x607C, in counts through the axis's scale).",
        ),
        k(
            "axes.*.homing.home_offset_deg",
            f(DEFAULT_HOME_OFFSET_MM),
            format!("{}; kind \"drive\": within the drive's 32-bit counts", coord()),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.home_mm",
            format!(
                "{} (required when that is outside the travel)",
                f(DEFAULT_HOME_MM)
            ),
            "within `min_mm` to `max_mm`".into(),
            "Kinds \"switch\" and \"drive\": where the axis goes after homing, machine coordinates.",
        ),
        k(
            "axes.*.homing.home_deg",
            format!(
                "{} (required when that is outside the travel)",
                f(DEFAULT_HOME_MM)
            ),
            "within `min_deg` to `max_deg`".into(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.final_speed_mm_s",
            format!(
                "the magnitude of `search_velocity_mm_s` (kind \"drive\" without it: {} % of `velocity_mm_s`)",
                f(DEFAULT_DRIVE_FINAL_SPEED_PCT)
            ),
            "above 0, at most `velocity_mm_s`".into(),
            "Kinds \"switch\" and \"drive\": the speed of the move to `home_mm`.",
        ),
        k(
            "axes.*.homing.final_speed_deg_s",
            format!(
                "the magnitude of `search_velocity_deg_s` (kind \"drive\" without it: {} % of `velocity_deg_s`)",
                f(DEFAULT_DRIVE_FINAL_SPEED_PCT)
            ),
            "above 0, at most `velocity_deg_s`".into(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.homing.sequence",
            DEFAULT_HOMING_SEQUENCE.to_string(),
            ri(HOMING_SEQUENCE_RANGE),
            "Kinds \"switch\" and \"drive\" (LinuxCNC `HOME_SEQUENCE`): `kerf home --all` homes sequence 0 first, then 1, ...; axes with the same number home together.",
        ),
        k(
            "axes.*.limit_switches",
            none(),
            "table".into(),
            "The axis's hard limit switches (`[axes.x.limit_switches]`, ...): hitting one is a fault that stops all axes; after the reset the axis jogs only away from it. No other function may use their inputs.",
        ),
        k(
            "axes.*.limit_switches.min",
            none(),
            input(),
            "The switch at the lower end of the travel.",
        ),
        k(
            "axes.*.limit_switches.max",
            none(),
            input(),
            "The switch at the upper end of the travel.",
        ),
        k(
            "axes.*.sim",
            none(),
            "table".into(),
            "The simulated machine behind a simulated drive (`[axes.x.sim]`, ...), refused with [ethercat]. Positions are in the drive's own frame: the position it counts from power-up, the machine coordinate before homing. A switch it places is a simulated input (one of [io], which without [ethercat] are all simulated) whose value the simulation sets from the position, so its `sim` in [io] is refused; a switch input it does not place the operator sets with `kerf input`.",
        ),
        k(
            "axes.*.sim.start_mm",
            f(DEFAULT_SIM_START_MM),
            coord(),
            "The motor's position at power-up.",
        ),
        k(
            "axes.*.sim.start_deg",
            f(DEFAULT_SIM_START_MM),
            coord(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.sim.home_switch_mm",
            none(),
            coord(),
            "The simulated home switch. Kind \"switch\": the input `homing.switch`, active at and beyond this point in the search direction. Kind \"drive\" (methods 19 to 22): the switch wired to the simulated drive, active beyond this point in the method's search direction in the drive's counts (increasing for 19 and 20, decreasing for 21 and 22: with `direction = -1` toward smaller mm); without it the drive's search ends in a homing error.",
        ),
        k(
            "axes.*.sim.home_switch_deg",
            none(),
            coord(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.sim.min_limit_mm",
            none(),
            coord(),
            "The simulated min limit switch (needs `limit_switches.min`): active at and below this point.",
        ),
        k(
            "axes.*.sim.min_limit_deg",
            none(),
            coord(),
            "The same on a rotary axis.",
        ),
        k(
            "axes.*.sim.max_limit_mm",
            none(),
            format!("{}, above `min_limit_mm`", coord()),
            "The simulated max limit switch (needs `limit_switches.max`): active at and above this point.",
        ),
        k(
            "axes.*.sim.max_limit_deg",
            none(),
            format!("{}, above `min_limit_deg`", coord()),
            "The same on a rotary axis.",
        ),
    ]
}

/// The rows of `[homing]` and `[jog]`, in the order of docs/CONFIG.md.
pub(super) fn keys() -> Vec<KeyDoc> {
    let homing = HomingConfig::default();
    let jog = JogConfig::default();
    vec![
        k(
            "homing",
            "all defaults".into(),
            "table".into(),
            "Homing for the machine as a whole; each axis's is `[axes.*.homing]`.",
        ),
        k(
            "homing.required",
            homing.required.to_string(),
            "true or false".into(),
            "Programs and MDI are refused until every axis is homed (axes of kind \"none\" and \"absolute\" are homed at start).",
        ),
        k(
            "homing.unhomed_jog_pct",
            f(homing.unhomed_jog_pct),
            rf(UNHOMED_JOG_PCT_RANGE),
            "The jog speed cap of an axis that is not homed (whose soft limits do not apply yet), percent of its velocity.",
        ),
        k(
            "jog",
            "all defaults".into(),
            "table".into(),
            "Jogging (`kerf jog`).",
        ),
        k(
            "jog.deadman_ms",
            jog.deadman_ms.to_string(),
            ri(DEADMAN_RANGE_MS),
            "A continuous jog stops on a jerk-limited ramp when its request is not renewed within this (a client that vanished never leaves an axis running).",
        ),
        k(
            "jog.default_speed_pct",
            f(jog.default_speed_pct),
            rf(JOG_SPEED_PCT_RANGE),
            "The speed of a jog without `--speed`, percent of the axis's velocity.",
        ),
    ]
}

/// The rows of `[serve]`.
pub(super) fn serve_keys() -> Vec<KeyDoc> {
    vec![
        k(
            "serve",
            "all defaults".into(),
            "table".into(),
            "`kerf serve`: the web page and the JSON API beside the daemon (docs/API.md).",
        ),
        k(
            "serve.http",
            format!("\"{DEFAULT_SERVE_HTTP}\""),
            "an IP address and a port".into(),
            "Where the web page and the JSON API listen (`kerf serve --http` overrides it). Loopback by default; for remote access put a TLS reverse proxy in front (docs/API.md).",
        ),
        k(
            "serve.opcua",
            format!("\"{DEFAULT_SERVE_OPCUA}\""),
            "an IP address and a port".into(),
            "Where the OPC UA server listens (`kerf serve --opcua` overrides it), `opc.tcp://ADDRESS/`. Loopback by default (docs/API.md, \"OPC UA\").",
        ),
        k(
            "serve.manufacturer",
            format!("\"{DEFAULT_MANUFACTURER}\""),
            "1 to 100 characters".into(),
            "The machine's manufacturer in OPC UA (Identification/Manufacturer).",
        ),
        k(
            "serve.model",
            format!("\"{DEFAULT_MODEL}\""),
            "1 to 100 characters".into(),
            "The machine's model in OPC UA (Identification/Model).",
        ),
        k(
            "serve.serial_number",
            "the machine's name".into(),
            "1 to 100 characters".into(),
            "The machine's serial number in OPC UA (Identification/SerialNumber).",
        ),
        k(
            "serve.control_token_sha256",
            "none: nobody controls the machine through `kerf serve`".into(),
            "64 hex digits".into(),
            "The SHA-256 of the token a client presents (`Authorization: Bearer TOKEN`) to control the machine (`kerf serve --hash-token` prints it from the token on standard input); the token itself is never stored. Without it every control request is refused; watching needs no token.",
        ),
        k(
            "serve.opcua_certificate",
            "none: only the None endpoint, anonymous".into(),
            "a .der or .pem file".into(),
            "The OPC UA server's application instance certificate, relative to the configuration's directory. With it (and its key) the server also offers the Basic256Sha256, Aes128Sha256RsaOaep and Aes256Sha256RsaPss endpoints, where `serve.opcua_users` log in (docs/API.md, \"Security: certificates, users and roles\").",
        ),
        k(
            "serve.opcua_private_key",
            "none".into(),
            "a PEM file".into(),
            "The certificate's private key; given with `serve.opcua_certificate` or not at all.",
        ),
        k(
            "serve.opcua_pki_dir",
            "`MACHINE-opcua-pki` in the state directory".into(),
            "a directory".into(),
            "The OPC UA certificate store: a client's certificate lands in `rejected/` at its first secure connection and is trusted once an administrator moves it to `trusted/`.",
        ),
        k(
            "serve.opcua_users",
            "none: anonymous reading only".into(),
            "a list of { name, password_hash, role }".into(),
            "Who may log in to the OPC UA server (on the secure endpoints only; needs `serve.opcua_certificate`): `name`, `password_hash` (`pbkdf2-sha256$…`, printed by `kerf serve --hash-password` from the password on standard input; the password is never stored) and `role`: \"viewer\" reads, \"operator\" may also call the Control methods (hold, resume, the overrides).",
        ),
    ]
}
