//! Checks `docs/PROTOCOL.md` against the code: every message table (offset, size, type,
//! field), every message heading (size, alignment, type name) and the constants table.

use core::mem::{align_of, offset_of, size_of};
use std::collections::BTreeMap;

use iceoryx2::prelude::ZeroCopySend;

use crate::*;

/// The size and the Rust type name of a field.
fn field_type<T, F>(_: fn(&T) -> &F) -> (usize, &'static str) {
    (size_of::<F>(), core::any::type_name::<F>())
}

/// (field, offset, size, Rust type) of every field of a struct, in declaration order.
macro_rules! fields {
    ($t:ty; $($f:ident),* $(,)?) => {
        vec![$({
            let (size, ty) = field_type(|m: &$t| &m.$f);
            (stringify!($f), offset_of!($t, $f), size, ty)
        }),*]
    };
}

struct Message {
    name: &'static str,
    size: usize,
    align: usize,
    type_name: &'static str,
    fields: Vec<(&'static str, usize, usize, &'static str)>,
}

fn messages() -> Vec<Message> {
    // SAFETY: `type_name` is only unsafe to implement; calling it reads a constant.
    let tn = |f: unsafe fn() -> &'static str| unsafe { f() };
    vec![
        Message {
            name: "MoveMsg",
            size: size_of::<MoveMsg>(),
            align: align_of::<MoveMsg>(),
            type_name: tn(<MoveMsg as ZeroCopySend>::type_name),
            fields: fields!(MoveMsg; version, kind, program_id, seq, line, flags, corner,
                event_code, feed_mm_min, tolerance_mm, start_mm, end_mm, center_mm, axis,
                sweep_rad, abc_start_deg, abc_end_deg, event_value, count, naive_cam_mm,
                event_p, event_q, reserved),
        },
        Message {
            name: "SetpointMsg",
            size: size_of::<SetpointMsg>(),
            align: align_of::<SetpointMsg>(),
            type_name: tn(<SetpointMsg as ZeroCopySend>::type_name),
            fields: fields!(SetpointMsg; version, state, seq, time_ns, program_id,
                program_cycle, position_mm_deg, velocity_mm_deg_s, feed_mm_s, line, axes_mask,
                missed_periods),
        },
        Message {
            name: "Request",
            size: size_of::<Request>(),
            align: align_of::<Request>(),
            type_name: tn(<Request as ZeroCopySend>::type_name),
            fields: fields!(Request; version, kind, id, value, program_id, index, mode, speed),
        },
        Message {
            name: "StatusMsg",
            size: size_of::<StatusMsg>(),
            align: align_of::<StatusMsg>(),
            type_name: tn(<StatusMsg as ZeroCopySend>::type_name),
            fields: fields!(StatusMsg; state, line, position_mm_deg, override_pct,
                queued_moves, queued_s, cycles, overruns, rt, program_done, program_id,
                moves_received, window_items, rejected, fault, axes_mask, fault_text,
                period_ns, program_end, drives, safety_check, safety_axis, safety_value,
                safety_limit, safety_line, drive_error_code, safety_cycle, fault_dump,
                bus_subdevices, bus_recovering, bus_states, bus_al_codes, bus_cycles_complete,
                bus_cycles_lost, bus_cycles_short, bus_cycles_not_op, bus_longest_gap_cycles,
                dc_used, dc_offset_ns, dc_offset_abs_p50_ns, dc_offset_abs_p99_ns,
                dc_offset_abs_p999_ns, dc_offset_abs_max_ns, dc_samples, pause_reason,
                pause_line, pause_value, switches, tool_in_spindle, tool_changer,
                tool_length_mm, spindle_kind, spindle_dir, spindle_programmed_rpm,
                spindle_commanded_rpm, spindle_actual_rpm, spindle_override_pct,
                spindle_at_speed, overrides_enabled, coolant, input_result_line,
                digital_outputs, digital_inputs, analog_outputs, analog_inputs,
                input_result_seq, input_result_program, input_result_value, pause_text, homed,
                homing_required, homing, jogging, home_switches, min_limit_switches,
                max_limit_switches, limit_released, home_phase),
        },
        Message {
            name: "Response",
            size: size_of::<Response>(),
            align: align_of::<Response>(),
            type_name: tn(<Response as ZeroCopySend>::type_name),
            fields: fields!(Response; version, accepted, request_id, reason, program_fate,
                message, status),
        },
    ]
}

fn constants() -> BTreeMap<&'static str, u32> {
    macro_rules! consts {
        ($($c:ident),* $(,)?) => { BTreeMap::from([$((stringify!($c), u32::try_from($c).unwrap())),*]) };
    }
    consts!(
        PROTOCOL_VERSION,
        KIND_BEGIN,
        KIND_LINE,
        KIND_ARC,
        KIND_EVENT,
        KIND_END,
        FLAG_RAPID,
        FLAG_ABC,
        FLAG_EVENT_VALUE,
        FLAG_EVENT_P,
        FLAG_EVENT_Q,
        FLAG_NAIVE_CAM,
        CORNER_EXACT_STOP,
        CORNER_BLEND_DEFAULT,
        CORNER_BLEND_TOLERANCE,
        EVENT_M0,
        EVENT_M1,
        EVENT_M2,
        EVENT_M30,
        EVENT_M3,
        EVENT_M4,
        EVENT_M5,
        EVENT_M6,
        EVENT_M7,
        EVENT_M8,
        EVENT_M9,
        EVENT_S,
        EVENT_T,
        EVENT_G4,
        EVENT_M60,
        EVENT_MSG,
        EVENT_DEBUG,
        EVENT_PRINT,
        EVENT_M19,
        EVENT_M48,
        EVENT_M49,
        EVENT_M50,
        EVENT_M51,
        EVENT_M52,
        EVENT_M53,
        EVENT_LOG,
        EVENT_M62,
        EVENT_M63,
        EVENT_M64,
        EVENT_M65,
        EVENT_M66,
        EVENT_M66_ANALOG,
        EVENT_M67,
        EVENT_M68,
        EVENT_USER_M100,
        EVENT_USER_M199,
        STATE_IDLE,
        STATE_RUNNING,
        STATE_HOLDING,
        STATE_STARVED,
        STATE_FAULT,
        STATE_PAUSED,
        STATE_MANUAL,
        REQUEST_OPTIONAL_STOP,
        REQUEST_BLOCK_DELETE,
        REQUEST_SINGLE_BLOCK,
        REQUEST_SPINDLE_OVERRIDE,
        REQUEST_SET_INPUT,
        REQUEST_SET_ANALOG_INPUT,
        REQUEST_JOG,
        REQUEST_JOG_STOP,
        REQUEST_HOME,
        JOG_CONTINUOUS,
        JOG_STEP,
        JOG_TO,
        HOME_PHASE_IDLE,
        HOME_PHASE_WAITING,
        HOME_PHASE_MOVE_OFF,
        HOME_PHASE_SEARCH,
        HOME_PHASE_BACK_OFF,
        HOME_PHASE_LATCH,
        HOME_PHASE_FINAL,
        SAFETY_HOME_SEARCH,
        SAFETY_HOME_RELEASE,
        SAFETY_HOME_LATCH,
        SAFETY_HARD_LIMIT,
        SAFETY_DRIVE_HOMING,
        DIGITAL_IO,
        ANALOG_IO,
        PAUSE_NONE,
        PAUSE_PROGRAM_STOP,
        PAUSE_OPTIONAL_STOP,
        PAUSE_PALLET_CHANGE,
        PAUSE_SINGLE_BLOCK,
        PAUSE_TOOL_CHANGE,
        PAUSE_TOOL_CHANGING,
        PAUSE_WAIT_INPUT,
        PAUSE_AT_SPEED,
        PAUSE_ORIENT,
        SWITCH_OPTIONAL_STOP,
        SWITCH_BLOCK_DELETE,
        SWITCH_SINGLE_BLOCK,
        TOOL_CHANGER_NONE,
        TOOL_CHANGER_MANUAL,
        TOOL_CHANGER_AUTOMATIC,
        SPINDLE_NONE,
        SPINDLE_DRIVE,
        SPINDLE_OUTPUTS,
        OVERRIDES_FEED,
        OVERRIDES_SPINDLE,
        COOLANT_MIST,
        COOLANT_FLOOD,
        SAFETY_SPINDLE_AT_SPEED,
        SAFETY_SPINDLE_BAND,
        SAFETY_SPINDLE_ORIENT,
        SAFETY_TOOL_CHANGE,
        SAFETY_SPINDLE_DRIVE,
        STATE_STOPPING,
        REQUEST_STATUS,
        REQUEST_HOLD,
        REQUEST_RESUME,
        REQUEST_ABORT,
        REQUEST_OVERRIDE,
        REQUEST_RESET,
        REQUEST_DUMP,
        REQUEST_INJECT,
        REQUEST_PROGRAM,
        PROGRAM_FATE_UNKNOWN,
        PROGRAM_FATE_RECEIVING,
        PROGRAM_FATE_RUNNING,
        PROGRAM_FATE_FINISHED,
        PROGRAM_FATE_ABORTED,
        PROGRAM_FATE_REFUSED,
        REASON_OK,
        REASON_WRONG_VERSION,
        REASON_UNKNOWN_KIND,
        REASON_BAD_VALUE,
        REASON_NOT_ALLOWED,
        REASON_NOT_IMPLEMENTED,
        PROGRAM_END_NONE,
        PROGRAM_END_FINISHED,
        PROGRAM_END_ABORTED,
        PROGRAM_END_REFUSED,
        DRIVES_ENABLING,
        DRIVES_RUNNING,
        DRIVES_HOLDING,
        DRIVES_QUICK_STOP,
        DRIVES_STOPPED,
        DRIVES_RESETTING,
        SAFETY_NONE,
        SAFETY_VELOCITY,
        SAFETY_ACCELERATION,
        SAFETY_SOFT_LIMIT,
        SAFETY_FOLLOWING_ERROR,
        SAFETY_STREAM_STALL,
        SAFETY_DRIVE_FAULT,
        SAFETY_ENABLE_TIMEOUT,
        SAFETY_DRIVE_DISABLED,
        SAFETY_FIELDBUS,
        SAFETY_SUBDEVICE_STATE,
        SAFETY_AXIS_NONE,
        BUS_MAX_SUBDEVICES,
        BUS_STATE_INIT,
        BUS_STATE_PRE_OP,
        BUS_STATE_BOOT,
        BUS_STATE_SAFE_OP,
        BUS_STATE_OP,
    )
}

/// Whether a documented type (`u16`, `f64[6]`, `StatusMsg`) is the Rust type `rust`
/// (`u16`, `[f64; 6]`, `kerf_proto::control::StatusMsg`): a signed field documented as
/// unsigned fails, not only a field of another size.
fn same_type(ty: &str, rust: &str) -> bool {
    if let Some((base, n)) = ty.strip_suffix(']').and_then(|t| t.split_once('[')) {
        return rust
            .strip_prefix('[')
            .and_then(|r| r.strip_suffix(&format!("; {n}]")))
            .is_some_and(|inner| same_type(base, inner));
    }
    match ty {
        "u8" | "u16" | "u32" | "i32" | "u64" | "i64" | "f64" => rust == ty,
        message => rust.ends_with(&format!("::{message}")),
    }
}

/// The size of a documented type: `u8`, `u16`, `u32`, `u64`, `i64`, `f64`, `T[n]`, or a
/// message name.
fn type_size(ty: &str, msgs: &[Message]) -> usize {
    if let Some((base, n)) = ty.strip_suffix(']').and_then(|t| t.split_once('[')) {
        let n: usize = n.parse().unwrap_or_else(|_| panic!("array length in {ty}"));
        return n * type_size(base, msgs);
    }
    match ty {
        "u8" => 1,
        "u16" => 2,
        "u32" | "i32" => 4,
        "u64" | "i64" | "f64" => 8,
        other => {
            msgs.iter()
                .find(|m| m.name == other)
                .unwrap_or_else(|| panic!("unknown type {other}"))
                .size
        }
    }
}

fn cells(row: &str) -> Vec<String> {
    let inner = row.trim().trim_start_matches('|').trim_end_matches('|');
    inner
        .split('|')
        .map(|c| c.trim().trim_matches('`').to_string())
        .collect()
}

#[test]
fn documented_types_are_matched_by_name_and_sign() {
    assert!(same_type("i64", "i64"));
    assert!(!same_type("u64", "i64"));
    assert!(same_type("u16[32]", "[u16; 32]"));
    assert!(!same_type("u16[32]", "[u16; 31]"));
    assert!(!same_type("u8[32]", "[u16; 32]"));
    assert!(same_type("StatusMsg", "kerf_proto::control::StatusMsg"));
    assert!(!same_type("StatusMsg", "kerf_proto::control::Response"));
}

#[test]
fn protocol_md_matches_the_code() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/PROTOCOL.md");
    let doc = std::fs::read_to_string(path).expect("docs/PROTOCOL.md");
    let msgs = messages();
    let mut seen_msgs = Vec::new();
    let mut seen_consts = BTreeMap::new();
    let lines: Vec<&str> = doc.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        i += 1;
        if let Some(heading) = line.strip_prefix("### ") {
            // "### Name: N bytes, align A, type name `T`"
            let (name, rest) = heading.split_once(':').expect("message heading");
            let msg = msgs
                .iter()
                .find(|m| m.name == name.trim())
                .unwrap_or_else(|| panic!("documented message {name} is not in the code"));
            let words: Vec<String> = cells(&rest.replace(',', "|").replace('`', ""));
            assert_eq!(words[0], format!("{} bytes", msg.size), "{name}: size");
            assert_eq!(
                words[1],
                format!("align {}", msg.align),
                "{name}: alignment"
            );
            assert_eq!(
                words[2],
                format!("type name {}", msg.type_name),
                "{name}: type name"
            );
            // Skip to the table, then read its rows.
            while i < lines.len() && !lines[i].starts_with("| offset") {
                i += 1;
            }
            i += 2;
            let mut rows = Vec::new();
            while i < lines.len() && lines[i].starts_with('|') {
                rows.push(cells(lines[i]));
                i += 1;
            }
            let mut next_offset = 0;
            for row in &rows {
                let [offset, size, ty, field, _meaning] = &row[..] else {
                    panic!("{name}: row {row:?} has not 5 cells");
                };
                let offset: usize = offset.parse().expect("offset");
                let size: usize = size.parse().expect("size");
                let &(_, code_offset, code_size, code_type) =
                    msg.fields.iter().find(|f| f.0 == field).unwrap_or_else(|| {
                        panic!("{name}.{field} is documented but not in the code")
                    });
                assert_eq!(offset, code_offset, "{name}.{field}: offset");
                assert_eq!(size, code_size, "{name}.{field}: size");
                assert_eq!(type_size(ty, &msgs), size, "{name}.{field}: type {ty}");
                assert!(
                    same_type(ty, code_type),
                    "{name}.{field}: documented as {ty}, the code has {code_type}"
                );
                assert_eq!(
                    offset, next_offset,
                    "{name}.{field}: gap or overlap before it"
                );
                next_offset = offset + size;
            }
            // Every byte is a documented field: no padding, nothing undocumented.
            assert_eq!(
                next_offset, msg.size,
                "{name}: the table does not cover every byte"
            );
            assert_eq!(rows.len(), msg.fields.len(), "{name}: field count");
            seen_msgs.push(msg.name);
        } else if line.starts_with("| constant") {
            i += 1;
            while i < lines.len() && lines[i].starts_with('|') {
                let row = cells(lines[i]);
                let value: u32 = row[1].parse().expect("constant value");
                seen_consts.insert(row[0].clone(), value);
                i += 1;
            }
        }
    }
    let mut all: Vec<&str> = msgs.iter().map(|m| m.name).collect();
    all.sort();
    seen_msgs.sort();
    assert_eq!(seen_msgs, all, "every message is documented");
    let code: BTreeMap<String, u32> = constants()
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
    assert_eq!(seen_consts, code, "the constants table");
}
