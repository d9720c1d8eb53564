//! The items of a resolved program besides its geometry: the non-motion events
//! ([`Event`], [`EventCode`]) and the program item ([`Item`]: a move or an event), in
//! program order. They live here, below both the G-code front end that produces them and
//! the shared-memory protocol that carries them, so that neither depends on the other.

use crate::Move;

/// The kind of a non-motion event.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EventCode {
    /// Program stop.
    M0,
    /// Optional program stop.
    M1,
    /// Program end.
    M2,
    /// Program end and rewind.
    M30,
    /// Spindle on clockwise.
    M3,
    /// Spindle on counter-clockwise.
    M4,
    /// Spindle stop.
    M5,
    /// Tool change.
    M6,
    /// Mist coolant on.
    M7,
    /// Flood coolant on.
    M8,
    /// Coolant off.
    M9,
    /// Spindle speed, rpm.
    S,
    /// Tool select.
    T,
    /// Dwell: the motion comes to an exact stop and waits; the value is the time in
    /// seconds (zero for a dwell without a time word).
    G4,
    /// Pallet change pause (LinuxCNC M60): a program pause like M0.
    M60,
    /// Spindle orientation (LinuxCNC M19, and ORIENT_SPINDLE of G87 back boring, which
    /// stops the spindle in a fixed orientation before moving the tool sideways): `value`
    /// is the angle R, degrees (0 to 360, 0 without R); for M19 `p` is its P word, the
    /// direction (LinuxCNC's `spindle.N.orient-mode`: 0 the shorter way, 1 clockwise, 2
    /// counter-clockwise; 0 without P) and `q` its Q word, the time to wait for the
    /// orientation, seconds (`None` without Q).
    M19,
    /// Enable the feed and spindle overrides (LinuxCNC M48).
    M48,
    /// Disable the feed and spindle overrides (LinuxCNC M49).
    M49,
    /// The feed override enabled (`value` 1) or disabled (0) (LinuxCNC M50, `M50 P0`).
    M50,
    /// The spindle speed override enabled (1) or disabled (0) (LinuxCNC M51).
    M51,
    /// Adaptive feed control enabled (1) or disabled (0) (LinuxCNC M52).
    M52,
    /// The feed stop (hold) control enabled (1) or disabled (0) (LinuxCNC M53).
    M53,
    /// Digital output on, synchronised with the start of the next move (LinuxCNC M62):
    /// `value` is the output number (P).
    M62,
    /// Digital output off, synchronised with the next move (M63): `value` the P word.
    M63,
    /// Digital output on at once (M64): `value` the P word.
    M64,
    /// Digital output off at once (M65): `value` the P word.
    M65,
    /// Wait on a digital input (LinuxCNC M66 P): `value` is the input number, `p` the L
    /// word (wait mode 0–4, 0 without L), `q` the Q word (timeout, s; `None` without).
    /// The input's state, or -1 on a timeout, goes to parameter #5399.
    M66,
    /// Wait on an analog input (M66 E): `value` is the input number, `p` and `q` as
    /// [`EventCode::M66`] (only L0 is defined for analog inputs).
    M66Analog,
    /// Analog output, synchronised with the next move (M67): `value` the output number
    /// (E), `q` the value (Q).
    M67,
    /// Analog output at once (M68): `value` the E word, `q` the Q word.
    M68,
    /// A user-defined M code M100–M199 (LinuxCNC), by its number less 100: `value` is its
    /// P word, `q` its Q word.
    User(u8),
    /// An operator message (`(MSG, text)`): `text` holds it.
    Msg,
    /// A debug message (`(DEBUG, text)`, parameters substituted): `text` holds it.
    Debug,
    /// A print message (`(PRINT, text)`, parameters substituted): `text` holds it.
    Print,
    /// A LinuxCNC log call: `text` holds `LOGOPEN,FILE` or `LOGAPPEND,FILE` (the file name
    /// as written), `LOG,TEXT` (parameters substituted as in DEBUG) or `LOGCLOSE`. Kerf
    /// opens and writes no file; the control receiving the events may.
    Log,
}

impl EventCode {
    /// The code as written: "M3", "S", "T", ...
    pub fn as_str(self) -> &'static str {
        match self {
            EventCode::M0 => "M0",
            EventCode::M1 => "M1",
            EventCode::M2 => "M2",
            EventCode::M30 => "M30",
            EventCode::M3 => "M3",
            EventCode::M4 => "M4",
            EventCode::M5 => "M5",
            EventCode::M6 => "M6",
            EventCode::M7 => "M7",
            EventCode::M8 => "M8",
            EventCode::M9 => "M9",
            EventCode::S => "S",
            EventCode::T => "T",
            EventCode::G4 => "G4",
            EventCode::M60 => "M60",
            EventCode::M19 => "M19",
            EventCode::M48 => "M48",
            EventCode::M49 => "M49",
            EventCode::M50 => "M50",
            EventCode::M51 => "M51",
            EventCode::M52 => "M52",
            EventCode::M53 => "M53",
            EventCode::M62 => "M62",
            EventCode::M63 => "M63",
            EventCode::M64 => "M64",
            EventCode::M65 => "M65",
            EventCode::M66 | EventCode::M66Analog => "M66",
            EventCode::M67 => "M67",
            EventCode::M68 => "M68",
            EventCode::User(n) => {
                let i = 4 * usize::from(n.min(99));
                &USER_M_NAMES[i..i + 4]
            }
            EventCode::Msg => "MSG",
            EventCode::Debug => "DEBUG",
            EventCode::Print => "PRINT",
            EventCode::Log => "LOG",
        }
    }
}

/// "M100M101…M199": the names of the user M codes, four bytes each.
const USER_M_NAMES: &str = "M100M101M102M103M104M105M106M107M108M109M110M111M112M113M114M115M116M117M118M119M120M121M122M123M124M125M126M127M128M129M130M131M132M133M134M135M136M137M138M139M140M141M142M143M144M145M146M147M148M149M150M151M152M153M154M155M156M157M158M159M160M161M162M163M164M165M166M167M168M169M170M171M172M173M174M175M176M177M178M179M180M181M182M183M184M185M186M187M188M189M190M191M192M193M194M195M196M197M198M199";

/// A non-motion event, in program order among the moves.
#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    /// 1-based source line.
    pub line: u32,
    /// What happens.
    pub code: EventCode,
    /// S: rpm; T: tool number; G4: dwell seconds; user M codes: the P word; M62–M68:
    /// the output or input number; other M codes: `None`.
    pub value: Option<f64>,
    /// User M codes, M19, M66, M67 and M68: the Q word; otherwise `None`.
    pub q: Option<f64>,
    /// M19: the P word (the direction mode); M66: the L word (the wait mode); otherwise
    /// `None` (a user M code's P word is its `value`).
    pub p: Option<f64>,
    /// Messages (MSG, DEBUG, PRINT): the text; otherwise `None`.
    pub text: Option<std::sync::Arc<str>>,
}

impl Event {
    /// An event with a value and no Q word or text.
    pub fn new(line: u32, code: EventCode, value: Option<f64>) -> Event {
        Event {
            line,
            code,
            value,
            q: None,
            p: None,
            text: None,
        }
    }
}

/// One output item of the interpreter.
#[derive(Clone, Debug, PartialEq)]
pub enum Item {
    /// A resolved move.
    Move(Move),
    /// A non-motion event.
    Event(Event),
}
