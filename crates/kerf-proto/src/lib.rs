//! Kerf's shared-memory protocol: the messages that cross iceoryx2 between the planner
//! process (`kerf run`), clients and the real-time daemon (`kerfd`), their validation,
//! and the service names.
//!
//! `docs/PROTOCOL.md` is the byte-for-byte specification; a unit test parses its tables
//! and checks them against the types here, so the two cannot drift.
//!
//! Design decisions:
//! - **Plain old data only.** Every shared-memory type is `#[repr(C)]`, made of `u8`,
//!   `u16`, `u32`, `u64`, `i64`, `f64` and fixed arrays of them, with every padding byte
//!   spelled out as a reserved field. No Rust `enum`, `bool`, `Option` or reference crosses the shared
//!   memory: any bit pattern a (possibly broken or hostile) writer leaves there is a valid
//!   value of the type, so reading it is never undefined behaviour. Meaning is given by
//!   `u32` constants ([`KIND_LINE`], [`FLAG_RAPID`], ...), decoded by validating
//!   conversions into Rust types ([`Resolved`], [`MachineState`], [`ControlCommand`]).
//! - **One message per item.** A program is a stream of [`MoveMsg`]s: a BEGIN, one message
//!   per line, arc/helix or event, and an END. Each message is self-contained and
//!   [`TryFrom<&MoveMsg> for Resolved`](Resolved) checks it alone; [`StreamCheck`] adds the
//!   rules between messages (order, sequence numbers, continuity, counts).
//! - **Stable type names.** iceoryx2 matches publishers and subscribers by type name, size
//!   and alignment; the names are versioned (`kerf.MoveMsg.v1`), so a layout change is a
//!   new name and a new [`PROTOCOL_VERSION`], never a silent misreading.
//! - **Validation never panics** on any bytes and names the first reason it refuses
//!   ([`Reject`]); it allocates nothing, so the daemon may run it anywhere.
#![deny(missing_docs)]

mod control;
mod moves;
mod stream;

#[cfg(test)]
mod doc_layout;

pub use control::*;
pub use moves::{
    ARC_END_TOL_MM, ARC_MIN_RADIUS_MM, ARC_ROUNDING_REL, AXIS_UNIT_TOL, CORNER_BLEND_DEFAULT,
    CORNER_BLEND_TOLERANCE, CORNER_EXACT_STOP, EVENT_DEBUG, EVENT_G4, EVENT_LOG, EVENT_M0,
    EVENT_M1, EVENT_M2, EVENT_M3, EVENT_M4, EVENT_M5, EVENT_M6, EVENT_M7, EVENT_M8, EVENT_M9,
    EVENT_M19, EVENT_M30, EVENT_M48, EVENT_M49, EVENT_M50, EVENT_M51, EVENT_M52, EVENT_M53,
    EVENT_M60, EVENT_M62, EVENT_M63, EVENT_M64, EVENT_M65, EVENT_M66, EVENT_M66_ANALOG, EVENT_M67,
    EVENT_M68, EVENT_MSG, EVENT_PRINT, EVENT_S, EVENT_T, EVENT_USER_M100, EVENT_USER_M199,
    FLAG_ABC, FLAG_EVENT_P, FLAG_EVENT_Q, FLAG_EVENT_VALUE, FLAG_NAIVE_CAM, FLAG_RAPID, Field,
    KIND_ARC, KIND_BEGIN, KIND_END, KIND_EVENT, KIND_LINE, MoveMsg, Reject, Resolved,
    arc_tolerance_mm, event_code_from_u32, event_code_to_u32,
};
pub use stream::{CONTINUITY_TOL, StreamCheck, StreamError};

/// The protocol version carried by every message. A change to any layout or to the meaning
/// of any field is a new version (and new iceoryx2 type names); receivers refuse messages
/// of another version.
pub const PROTOCOL_VERSION: u32 = 6;

// The sizes in docs/PROTOCOL.md; a layout change must fail the build, not only the tests.
const _: () = {
    assert!(size_of::<MoveMsg>() == 256);
    assert!(size_of::<SetpointMsg>() == 160);
    assert!(size_of::<Request>() == 48);
    assert!(size_of::<StatusMsg>() == 1200);
    assert!(size_of::<Response>() == 1448);
};

/// The number of axes in positions and velocities: X, Y, Z (mm), A, B, C (degrees).
pub const AXES: usize = 6;

/// The most EtherCAT subdevices the status describes: the length of its per-position
/// arrays (`StatusMsg::bus_states`, `StatusMsg::bus_al_codes`). The daemon's bus takes no
/// more (`kerf_ethercat::bus::MAX_SUBDEVICES`; `kerfd` asserts the two are equal).
pub const BUS_MAX_SUBDEVICES: usize = 32;

/// Service carrying [`MoveMsg`]s from the planner to the daemon (publish/subscribe).
pub const SERVICE_MOVES: &str = "moves";
/// Service carrying one [`SetpointMsg`] per real-time cycle from the daemon (publish/subscribe).
pub const SERVICE_SETPOINTS: &str = "setpoints";
/// Service for [`Request`] / [`Response`] between clients and the daemon (request/response).
pub const SERVICE_CONTROL: &str = "control";
/// Event service a client notifies after sending a [`Request`], so that the daemon takes
/// it at once instead of at its next look (optional: requests of a client that does not
/// notify are still taken, every 200 µs at the latest).
pub const SERVICE_CONTROL_REQUEST: &str = "control-request";
/// Event service the daemon notifies after each [`Response`] it sends, so that a waiting
/// client wakes at once instead of polling (optional for clients).
pub const SERVICE_CONTROL_ANSWER: &str = "control-answer";

/// The longest machine name accepted by [`service_name`], bytes.
pub const MAX_MACHINE_NAME: usize = 64;

/// Why [`service_name`] refused its arguments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ServiceNameError {
    /// The machine name is empty.
    #[error("machine name is empty")]
    EmptyMachine,
    /// The machine name is longer than [`MAX_MACHINE_NAME`] bytes.
    #[error("machine name is {len} bytes long; at most {MAX_MACHINE_NAME} are allowed")]
    MachineTooLong {
        /// Its length, bytes.
        len: usize,
    },
    /// The machine name holds a character other than ASCII letters, digits, '-' and '_'.
    #[error(
        "machine name has the character {found:?} at byte {at}; only ASCII letters, digits, '-' and '_' are allowed"
    )]
    BadCharacter {
        /// The offending character.
        found: char,
        /// Its byte offset.
        at: usize,
    },
    /// `which` is not one of "moves", "setpoints", "control", "control-request",
    /// "control-answer".
    #[error(
        "unknown service (expected \"moves\", \"setpoints\", \"control\", \"control-request\" or \"control-answer\")"
    )]
    UnknownService,
}

/// Checks a machine name: 1 to [`MAX_MACHINE_NAME`] ASCII letters, digits, '-' or '_'.
pub fn validate_machine_name(machine: &str) -> Result<(), ServiceNameError> {
    if machine.is_empty() {
        return Err(ServiceNameError::EmptyMachine);
    }
    if let Some((at, found)) = machine
        .char_indices()
        .find(|&(_, c)| !(c.is_ascii_alphanumeric() || c == '-' || c == '_'))
    {
        return Err(ServiceNameError::BadCharacter { found, at });
    }
    if machine.len() > MAX_MACHINE_NAME {
        return Err(ServiceNameError::MachineTooLong { len: machine.len() });
    }
    Ok(())
}

/// The iceoryx2 service name `kerf/<machine>/<which>`, with `which` one of
/// [`SERVICE_MOVES`], [`SERVICE_SETPOINTS`], [`SERVICE_CONTROL`],
/// [`SERVICE_CONTROL_REQUEST`], [`SERVICE_CONTROL_ANSWER`].
///
/// ```
/// assert_eq!(kerf_proto::service_name("mill-1", "moves").unwrap(), "kerf/mill-1/moves");
/// assert!(kerf_proto::service_name("mill 1", "moves").is_err());
/// ```
pub fn service_name(machine: &str, which: &str) -> Result<String, ServiceNameError> {
    validate_machine_name(machine)?;
    if ![
        SERVICE_MOVES,
        SERVICE_SETPOINTS,
        SERVICE_CONTROL,
        SERVICE_CONTROL_REQUEST,
        SERVICE_CONTROL_ANSWER,
    ]
    .contains(&which)
    {
        return Err(ServiceNameError::UnknownService);
    }
    Ok(format!("kerf/{machine}/{which}"))
}

/// Writes `text` into a fixed, NUL-padded UTF-8 field: as many whole characters as fit,
/// the rest of the field zero. Returns the number of bytes written (less than
/// `text.len()` when it was truncated).
pub fn write_text(field: &mut [u8], text: &str) -> usize {
    let mut n = text.len().min(field.len());
    while !text.is_char_boundary(n) {
        n -= 1;
    }
    field[..n].copy_from_slice(&text.as_bytes()[..n]);
    field[n..].fill(0);
    n
}

/// Reads a fixed, NUL-padded UTF-8 field: the bytes before the first NUL (or all of them),
/// cut at the first invalid UTF-8 sequence if a writer broke the rule. Never fails.
pub fn read_text(field: &[u8]) -> &str {
    let end = field.iter().position(|&b| b == 0).unwrap_or(field.len());
    let bytes = &field[..end];
    match std::str::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) => std::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or_default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The protocol's clients must not drag the G-code interpreter in: the program items
    /// come from kerf-geom.
    #[test]
    fn the_protocol_does_not_depend_on_the_parser() {
        let manifest = include_str!("../Cargo.toml");
        let deps = manifest
            .split("\n[")
            .find(|section| section.starts_with("dependencies]"))
            .expect("a [dependencies] section");
        assert!(!deps.contains("kerf-gcode"), "{deps}");
    }

    #[test]
    fn service_names() {
        assert_eq!(
            service_name("mill_2-A", "setpoints").unwrap(),
            "kerf/mill_2-A/setpoints"
        );
        assert_eq!(service_name("m", "control").unwrap(), "kerf/m/control");
        assert_eq!(
            service_name("", "moves"),
            Err(ServiceNameError::EmptyMachine)
        );
        assert_eq!(
            service_name("a/b", "moves"),
            Err(ServiceNameError::BadCharacter { found: '/', at: 1 })
        );
        assert_eq!(
            service_name("mühle", "moves"),
            Err(ServiceNameError::BadCharacter { found: 'ü', at: 1 })
        );
        assert_eq!(
            service_name(&"x".repeat(65), "moves"),
            Err(ServiceNameError::MachineTooLong { len: 65 })
        );
        assert!(service_name(&"x".repeat(64), "moves").is_ok());
        assert_eq!(
            service_name("m", "status"),
            Err(ServiceNameError::UnknownService)
        );
    }

    #[test]
    fn text_fields_truncate_at_char_boundaries() {
        let mut f = [0xffu8; 5];
        assert_eq!(write_text(&mut f, "ab"), 2);
        assert_eq!(f, [b'a', b'b', 0, 0, 0]);
        assert_eq!(read_text(&f), "ab");
        // "é" is two bytes: "abcé" is 5 bytes and fits exactly, without a NUL.
        assert_eq!(write_text(&mut f, "abcé"), 5);
        assert_eq!(read_text(&f), "abcé");
        // "abcdé" is 6 bytes: the é does not fit whole and is dropped.
        assert_eq!(write_text(&mut f, "abcdé"), 4);
        assert_eq!(f, [b'a', b'b', b'c', b'd', 0]);
        // Invalid UTF-8 written by someone else: the valid prefix.
        let g = [b'o', b'k', 0xc3, b'x', 0];
        assert_eq!(read_text(&g), "ok");
        assert_eq!(read_text(&[]), "");
    }
}
