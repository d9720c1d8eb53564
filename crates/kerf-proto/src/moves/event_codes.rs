//! The `EVENT_*` codes of [`MoveMsg::event_code`](crate::MoveMsg::event_code) and their
//! translation to and from the program's [`EventCode`].

use kerf_geom::EventCode;

/// Event code M0 (program stop).
pub const EVENT_M0: u32 = 1;
/// Event code M1 (optional program stop).
pub const EVENT_M1: u32 = 2;
/// Event code M2 (program end).
pub const EVENT_M2: u32 = 3;
/// Event code M30 (program end and rewind).
pub const EVENT_M30: u32 = 4;
/// Event code M3 (spindle clockwise).
pub const EVENT_M3: u32 = 5;
/// Event code M4 (spindle counter-clockwise).
pub const EVENT_M4: u32 = 6;
/// Event code M5 (spindle stop).
pub const EVENT_M5: u32 = 7;
/// Event code M6 (tool change).
pub const EVENT_M6: u32 = 8;
/// Event code M7 (mist coolant on).
pub const EVENT_M7: u32 = 9;
/// Event code M8 (flood coolant on).
pub const EVENT_M8: u32 = 10;
/// Event code M9 (coolant off).
pub const EVENT_M9: u32 = 11;
/// Event code S (spindle speed, value rpm).
pub const EVENT_S: u32 = 12;
/// Event code T (tool select, value tool number).
pub const EVENT_T: u32 = 13;
/// Event code G4 (dwell, value seconds).
pub const EVENT_G4: u32 = 14;
/// Pallet change pause (LinuxCNC M60): a program pause like M0.
pub const EVENT_M60: u32 = 15;
/// Operator message (`(MSG, ...)`); the text stays with the planner process.
pub const EVENT_MSG: u32 = 16;
/// Debug message (`(DEBUG, ...)`); the text stays with the planner process.
pub const EVENT_DEBUG: u32 = 17;
/// Print message (`(PRINT, ...)`); the text stays with the planner process.
pub const EVENT_PRINT: u32 = 18;
/// Spindle orientation (LinuxCNC M19, and ORIENT_SPINDLE of G87 back boring); value: the
/// angle, degrees.
pub const EVENT_M19: u32 = 19;
/// Feed and spindle overrides enabled (LinuxCNC M48).
pub const EVENT_M48: u32 = 20;
/// Feed and spindle overrides disabled (LinuxCNC M49).
pub const EVENT_M49: u32 = 21;
/// Feed override control (LinuxCNC M50); value 1 enabled, 0 disabled.
pub const EVENT_M50: u32 = 22;
/// Spindle speed override control (LinuxCNC M51); value 1 enabled, 0 disabled.
pub const EVENT_M51: u32 = 23;
/// Adaptive feed control (LinuxCNC M52); value 1 enabled, 0 disabled.
pub const EVENT_M52: u32 = 24;
/// Feed stop control (LinuxCNC M53); value 1 enabled, 0 disabled.
pub const EVENT_M53: u32 = 25;
/// LinuxCNC log call (`LOGOPEN`, `LOGAPPEND`, `LOG`, `LOGCLOSE`); the text (the call) stays
/// with the planner process.
pub const EVENT_LOG: u32 = 26;
/// Digital output on with the next move (LinuxCNC M62); value: the output number (P).
pub const EVENT_M62: u32 = 27;
/// Digital output off with the next move (M63); value: the output number.
pub const EVENT_M63: u32 = 28;
/// Digital output on at once (M64); value: the output number.
pub const EVENT_M64: u32 = 29;
/// Digital output off at once (M65); value: the output number.
pub const EVENT_M65: u32 = 30;
/// Wait on a digital input (M66 P); value: the input number, P field: the L word (wait
/// mode), Q field: the timeout, s.
pub const EVENT_M66: u32 = 31;
/// Wait on an analog input (M66 E); value: the input number, P and Q as M66 P.
pub const EVENT_M66_ANALOG: u32 = 32;
/// Analog output with the next move (M67); value: the output number (E), Q: the value.
pub const EVENT_M67: u32 = 33;
/// Analog output at once (M68); value: the output number, Q: the value.
pub const EVENT_M68: u32 = 34;
/// User M code M100 (LinuxCNC); M100 + n is `EVENT_USER_M100 + n`; value: its P word.
pub const EVENT_USER_M100: u32 = 100;
/// User M code M199, the last one.
pub const EVENT_USER_M199: u32 = 199;

/// The `EVENT_*` code of an event code.
pub fn event_code_to_u32(code: EventCode) -> u32 {
    match code {
        EventCode::M0 => EVENT_M0,
        EventCode::M1 => EVENT_M1,
        EventCode::M2 => EVENT_M2,
        EventCode::M30 => EVENT_M30,
        EventCode::M3 => EVENT_M3,
        EventCode::M4 => EVENT_M4,
        EventCode::M5 => EVENT_M5,
        EventCode::M6 => EVENT_M6,
        EventCode::M7 => EVENT_M7,
        EventCode::M8 => EVENT_M8,
        EventCode::M9 => EVENT_M9,
        EventCode::S => EVENT_S,
        EventCode::T => EVENT_T,
        EventCode::G4 => EVENT_G4,
        EventCode::M60 => EVENT_M60,
        EventCode::M19 => EVENT_M19,
        EventCode::M48 => EVENT_M48,
        EventCode::M49 => EVENT_M49,
        EventCode::M50 => EVENT_M50,
        EventCode::M51 => EVENT_M51,
        EventCode::M52 => EVENT_M52,
        EventCode::M53 => EVENT_M53,
        EventCode::M62 => EVENT_M62,
        EventCode::M63 => EVENT_M63,
        EventCode::M64 => EVENT_M64,
        EventCode::M65 => EVENT_M65,
        EventCode::M66 => EVENT_M66,
        EventCode::M66Analog => EVENT_M66_ANALOG,
        EventCode::M67 => EVENT_M67,
        EventCode::M68 => EVENT_M68,
        EventCode::Msg => EVENT_MSG,
        EventCode::Debug => EVENT_DEBUG,
        EventCode::Print => EVENT_PRINT,
        EventCode::Log => EVENT_LOG,
        EventCode::User(n) => EVENT_USER_M100 + u32::from(n.min(99)),
    }
}

/// The event code of an `EVENT_*` value, `None` for any other.
pub fn event_code_from_u32(code: u32) -> Option<EventCode> {
    Some(match code {
        EVENT_M0 => EventCode::M0,
        EVENT_M1 => EventCode::M1,
        EVENT_M2 => EventCode::M2,
        EVENT_M30 => EventCode::M30,
        EVENT_M3 => EventCode::M3,
        EVENT_M4 => EventCode::M4,
        EVENT_M5 => EventCode::M5,
        EVENT_M6 => EventCode::M6,
        EVENT_M7 => EventCode::M7,
        EVENT_M8 => EventCode::M8,
        EVENT_M9 => EventCode::M9,
        EVENT_S => EventCode::S,
        EVENT_T => EventCode::T,
        EVENT_G4 => EventCode::G4,
        EVENT_M60 => EventCode::M60,
        EVENT_M19 => EventCode::M19,
        EVENT_M48 => EventCode::M48,
        EVENT_M49 => EventCode::M49,
        EVENT_M50 => EventCode::M50,
        EVENT_M51 => EventCode::M51,
        EVENT_M52 => EventCode::M52,
        EVENT_M53 => EventCode::M53,
        EVENT_M62 => EventCode::M62,
        EVENT_M63 => EventCode::M63,
        EVENT_M64 => EventCode::M64,
        EVENT_M65 => EventCode::M65,
        EVENT_M66 => EventCode::M66,
        EVENT_M66_ANALOG => EventCode::M66Analog,
        EVENT_M67 => EventCode::M67,
        EVENT_M68 => EventCode::M68,
        EVENT_MSG => EventCode::Msg,
        EVENT_DEBUG => EventCode::Debug,
        EVENT_PRINT => EventCode::Print,
        EVENT_LOG => EventCode::Log,
        c @ EVENT_USER_M100..=EVENT_USER_M199 => EventCode::User((c - EVENT_USER_M100) as u8),
        _ => return None,
    })
}
