//! Word keys, G and M code tables of each dialect, and the modal groups.

use crate::Dialect;
use crate::EventCode;
use crate::arc::Plane;
use crate::lex::{K_AP, K_AT, K_CARET, K_CR, K_RP, K_TURN, key};

// Keys of the letter words the interpreter looks at.
pub(crate) const KX: u8 = key(b'X');
pub(crate) const KY: u8 = key(b'Y');
pub(crate) const KZ: u8 = key(b'Z');
pub(crate) const KA: u8 = key(b'A');
pub(crate) const KB: u8 = key(b'B');
pub(crate) const KC: u8 = key(b'C');
pub(crate) const KI: u8 = key(b'I');
pub(crate) const KJ: u8 = key(b'J');
pub(crate) const KK: u8 = key(b'K');
pub(crate) const KR: u8 = key(b'R');
pub(crate) const KH: u8 = key(b'H');
pub(crate) const KQ: u8 = key(b'Q');
pub(crate) const KP: u8 = key(b'P');
pub(crate) const KF: u8 = key(b'F');
pub(crate) const KS: u8 = key(b'S');
pub(crate) const KT: u8 = key(b'T');
pub(crate) const KD: u8 = key(b'D');
pub(crate) const KL: u8 = key(b'L');
pub(crate) const KE: u8 = key(b'E');

/// Linear axis words, indexed like machine axes (0 = X).
pub(crate) const XYZ: [u8; 3] = [KX, KY, KZ];
/// Rotary axis words.
pub(crate) const ABC: [u8; 3] = [KA, KB, KC];
/// Centre words, indexed like the axes they are parallel to.
pub(crate) const IJK: [u8; 3] = [KI, KJ, KK];

/// The word's address as written, for messages.
pub(crate) fn key_name(k: u8) -> String {
    match k {
        K_CR => "CR".into(),
        K_TURN => "TURN".into(),
        K_RP => "RP".into(),
        K_AP => "AP".into(),
        K_AT => "@".into(),
        K_CARET => "^".into(),
        _ => ((b'A' + k) as char).to_string(),
    }
}

/// Motion modes (G group 1 and the Heidenhain polar motions).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Motion {
    Rapid,
    Linear,
    /// Circular; `None` direction = Heidenhain G05 (last direction).
    Arc(Option<bool>),
    /// Heidenhain G10 (rapid) / G11 (feed) polar lines.
    PolarLine {
        rapid: bool,
    },
    /// Heidenhain G12/G13/G15 polar circles; `None` = G15.
    PolarArc(Option<bool>),
    /// LinuxCNC canned cycles G73, G81–G83, G85–G89 (`interp::cycles`).
    Cycle(crate::interp::cycles::CycleKind),
}

/// What a G code does in a dialect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum G {
    Motion(Motion),
    NoMotion,
    Dwell,
    Plane(Plane),
    Units {
        inch: bool,
        feed_too: bool,
    },
    Distance {
        absolute: bool,
    },
    ArcDistance {
        absolute: bool,
    },
    Comp(Comp),
    /// LinuxCNC G41.1/G42.1: compensation with the diameter in the D word.
    CompDiameter(Comp),
    ToolLength(crate::interp::ToolLength),
    CoordSystem(Option<usize>),
    Corner {
        exact: bool,
    },
    ExactStopOnce,
    G92Set,
    G92Reset,
    G92Suspend,
    G92Restore,
    MachineCoords,
    /// LinuxCNC G10 (L1/L2/L10/L11/L20).
    SetData,
    /// G28 (`false`) / G30 (`true`).
    Home(bool),
    /// G28.1 (`false`) / G30.1 (`true`).
    HomeSet(bool),
    /// LinuxCNC G52.
    LocalOffset,
    FeedPerMinute,
    /// LinuxCNC G93/G94/G95.
    FeedMode(crate::interp::FeedMode),
    /// LinuxCNC G98 (`r_plane: false`, back to the initial level) / G99 (to R).
    Retract {
        r_plane: bool,
    },
    Pole(PoleRef),
    PoleFromLast,
    PolarOrigin,
    AbsCentreOnce,
    BlankForm,
    ToolDef,
    NoOp,
    Unsupported(&'static str),
}

/// Cutter radius compensation (G40/G41/G42).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Comp {
    Off,
    Left,
    Right,
}

/// What a Sinumerik pole is programmed relative to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PoleRef {
    /// G110: relative to the last programmed position.
    LastPosition,
    /// G111: absolute in the workpiece coordinate system.
    Workpiece,
    /// G112: relative to the last pole.
    LastPole,
}

pub(crate) const N_GROUPS: usize = 14;
pub(crate) const GROUP_DISTANCE: usize = 4;

/// The modal group of a G action, for the "same modal group" check. Group 0 holds the
/// non-modal codes, of which a block may use one.
pub(crate) fn group(g: G) -> usize {
    match g {
        G::Motion(_) | G::NoMotion => 1,
        G::Plane(_) => 2,
        G::Units { .. } => 3,
        G::Distance { .. } => GROUP_DISTANCE,
        G::ArcDistance { .. } => 5,
        G::Comp(_) | G::CompDiameter(_) => 6,
        G::ToolLength { .. } => 7,
        G::CoordSystem(_) => 8,
        G::Corner { .. } => 9,
        G::ExactStopOnce => 10,
        G::FeedPerMinute | G::FeedMode(_) => 11,
        G::AbsCentreOnce => 12,
        G::Retract { .. } => 13,
        G::Dwell
        | G::G92Set
        | G::G92Reset
        | G::G92Suspend
        | G::G92Restore
        | G::MachineCoords
        | G::SetData
        | G::Home(_)
        | G::HomeSet(_)
        | G::LocalOffset
        | G::Pole(_)
        | G::PoleFromLast
        | G::PolarOrigin
        | G::BlankForm
        | G::ToolDef
        | G::NoOp
        | G::Unsupported(_) => 0,
    }
}

/// What G code `code10` (the number times ten: G59.1 is 591) does in dialect `d`; `None`
/// for a code the dialect does not know.
///
/// One piece on purpose: it is the table of every G code of every dialect, one match arm
/// per code, read top to bottom like the manuals' code lists; cutting it would scatter
/// the table without making any step of it shorter.
pub(crate) fn classify_g(d: Dialect, code10: u16) -> Option<G> {
    use crate::interp::ToolLength as TL;
    use G::*;
    let m = |x| Some(Motion(x));
    let common = match code10 {
        0 => m(self::Motion::Rapid),
        10 => m(self::Motion::Linear),
        20 => m(self::Motion::Arc(Some(false))),
        30 => m(self::Motion::Arc(Some(true))),
        170 => Some(Plane(self::Plane::Xy)),
        180 => Some(Plane(self::Plane::Zx)),
        190 => Some(Plane(self::Plane::Yz)),
        400 => Some(Comp(self::Comp::Off)),
        410 => Some(Comp(self::Comp::Left)),
        420 => Some(Comp(self::Comp::Right)),
        900 => Some(Distance { absolute: true }),
        910 => Some(Distance { absolute: false }),
        _ => None,
    };
    if common.is_some() {
        return common;
    }
    let r = match d {
        Dialect::LinuxCnc => match code10 {
            40 => Dwell,
            200 => Units {
                inch: true,
                feed_too: true,
            },
            210 => Units {
                inch: false,
                feed_too: true,
            },
            100 => SetData,
            280 => Home(false),
            281 => HomeSet(false),
            300 => Home(true),
            301 => HomeSet(true),
            430 => ToolLength(TL::Apply),
            431 => ToolLength(TL::Dynamic),
            432 => ToolLength(TL::Add),
            490 => ToolLength(TL::Cancel),
            520 => LocalOffset,
            530 => MachineCoords,
            540 | 550 | 560 | 570 | 580 | 590 => CoordSystem(Some(usize::from(code10 / 10 - 54))),
            591..=593 => CoordSystem(Some(usize::from(code10 - 591 + 6))),
            610 | 611 => Corner { exact: true },
            640 => Corner { exact: false },
            800 => NoMotion,
            730 | 810..=830 | 850..=890 if code10.is_multiple_of(10) => {
                match crate::interp::cycles::CycleKind::from_code10(code10) {
                    Some(k) => Motion(self::Motion::Cycle(k)),
                    None => return None,
                }
            }
            330 => Unsupported("G33 is not supported: needs spindle synchronisation"),
            331 => Unsupported("G33.1 is not supported: needs spindle synchronisation"),
            740 => Unsupported("G74 is not supported: needs spindle synchronisation"),
            760 => Unsupported("G76 is not supported: needs spindle synchronisation"),
            840 => Unsupported("G84 is not supported: needs spindle synchronisation"),
            901 => ArcDistance { absolute: true },
            911 => ArcDistance { absolute: false },
            920 => G92Set,
            921 => G92Reset,
            922 => G92Suspend,
            923 => G92Restore,
            411 => CompDiameter(self::Comp::Left),
            421 => CompDiameter(self::Comp::Right),
            930 => FeedMode(crate::interp::FeedMode::InverseTime),
            940 => FeedMode(crate::interp::FeedMode::PerMinute),
            950 => FeedMode(crate::interp::FeedMode::PerRev),
            970 => NoOp,
            980 => Retract { r_plane: false },
            990 => Retract { r_plane: true },
            // Not supported: each refusal names its code and the construct.
            50 => Unsupported("G5 is not supported: splines"),
            51 => Unsupported("G5.1 is not supported: splines"),
            52 => Unsupported("G5.2 is not supported: splines (NURBS)"),
            53 => Unsupported("G5.3 is not supported: splines (NURBS)"),
            70 => Unsupported("G7 is not supported: diameter mode is a lathe code"),
            80 => Unsupported("G8 is not supported: radius mode is a lathe code"),
            171 => Unsupported("G17.1 is not supported: U/V/W planes (U/V/W axes)"),
            181 => Unsupported("G18.1 is not supported: U/V/W planes (U/V/W axes)"),
            191 => Unsupported("G19.1 is not supported: U/V/W planes (U/V/W axes)"),
            382 => Unsupported("G38.2 is not supported: probing"),
            383 => Unsupported("G38.3 is not supported: probing"),
            384 => Unsupported("G38.4 is not supported: probing"),
            385 => Unsupported("G38.5 is not supported: probing"),
            700 => Unsupported("G70 is not supported: lathe finishing cycle"),
            710 => Unsupported("G71 is not supported: lathe roughing cycle"),
            711 => Unsupported("G71.1 is not supported: lathe roughing cycle"),
            712 => Unsupported("G71.2 is not supported: lathe roughing cycle"),
            720 => Unsupported("G72 is not supported: lathe roughing cycle"),
            721 => Unsupported("G72.1 is not supported: lathe roughing cycle"),
            722 => Unsupported("G72.2 is not supported: lathe roughing cycle"),
            960 => Unsupported("G96 is not supported: constant surface speed is a lathe code"),
            _ => return None,
        },
        Dialect::Rockwell => match code10 {
            40 => Dwell,
            90 => ExactStopOnce,
            200 => Units {
                inch: true,
                feed_too: true,
            },
            210 => Units {
                inch: false,
                feed_too: true,
            },
            430 => ToolLength(TL::Apply),
            490 => ToolLength(TL::Cancel),
            540 | 550 | 560 | 570 | 580 | 590 => CoordSystem(Some(usize::from(code10 / 10 - 54))),
            610 => Corner { exact: true },
            640 => Corner { exact: false },
            800 => NoOp,
            940 => FeedPerMinute,
            950 => Unsupported("feed per revolution (G95) is not supported"),
            _ => return None,
        },
        Dialect::Sinumerik => match code10 {
            40 => Dwell,
            90 => ExactStopOnce,
            540 | 550 | 560 | 570 => CoordSystem(Some(usize::from(code10 / 10 - 54))),
            5000 => CoordSystem(None),
            600 => Corner { exact: true },
            640 => Corner { exact: false },
            700 => Units {
                inch: true,
                feed_too: false,
            },
            710 => Units {
                inch: false,
                feed_too: false,
            },
            7000 => Units {
                inch: true,
                feed_too: true,
            },
            7100 => Units {
                inch: false,
                feed_too: true,
            },
            940 => FeedPerMinute,
            950 => Unsupported("feed per revolution (G95) is not supported"),
            1100 => Pole(PoleRef::LastPosition),
            1110 => Pole(PoleRef::Workpiece),
            1120 => Pole(PoleRef::LastPole),
            _ => return None,
        },
        Dialect::Heidenhain => match code10 {
            40 => Dwell,
            50 => Motion(self::Motion::Arc(None)),
            60 => Unsupported("tangential arcs (G06) are not supported yet"),
            100 => Motion(self::Motion::PolarLine { rapid: true }),
            110 => Motion(self::Motion::PolarLine { rapid: false }),
            120 => Motion(self::Motion::PolarArc(Some(false))),
            130 => Motion(self::Motion::PolarArc(Some(true))),
            150 => Motion(self::Motion::PolarArc(None)),
            160 => Unsupported("tangential polar arcs (G16) are not supported yet"),
            240 => Unsupported("chamfers (G24) are not supported yet"),
            250 => Unsupported("corner rounding (G25) is not supported yet"),
            290 => PoleFromLast,
            300 | 310 => BlankForm,
            700 => Units {
                inch: true,
                feed_too: true,
            },
            710 => Units {
                inch: false,
                feed_too: true,
            },
            990 => ToolDef,
            _ => return None,
        },
        Dialect::Fagor => match code10 {
            40 => Dwell,
            50 | 500 => Corner { exact: false },
            60 => AbsCentreOnce,
            70 => Corner { exact: true },
            200 => Unsupported("the general plane (G20) is not supported"),
            300 => PolarOrigin,
            540 | 550 | 560 | 570 | 580 | 590 => CoordSystem(Some(usize::from(code10 / 10 - 54))),
            700 => Units {
                inch: true,
                feed_too: true,
            },
            710 => Units {
                inch: false,
                feed_too: true,
            },
            940 => FeedPerMinute,
            950 => Unsupported("feed per revolution (G95) is not supported"),
            _ => return None,
        },
    };
    Some(r)
}

/// The event of an M code the dialects share, if it is one.
pub(crate) fn m_event(code: u16) -> Option<EventCode> {
    Some(match code {
        0 => EventCode::M0,
        1 => EventCode::M1,
        2 => EventCode::M2,
        30 => EventCode::M30,
        3 => EventCode::M3,
        4 => EventCode::M4,
        5 => EventCode::M5,
        6 => EventCode::M6,
        7 => EventCode::M7,
        8 => EventCode::M8,
        9 => EventCode::M9,
        _ => return None,
    })
}

/// The word keys a dialect accepts besides G, M and N (bit k = key k).
pub(crate) const fn allowed_keys(d: Dialect) -> u32 {
    const fn mask(keys: &[u8]) -> u32 {
        let mut m = 0u32;
        let mut i = 0;
        while i < keys.len() {
            m |= 1 << keys[i];
            i += 1;
        }
        m
    }
    match d {
        Dialect::LinuxCnc => mask(&[
            KA, KB, KC, KD, KE, KF, KH, KI, KJ, KK, KL, KP, KQ, KR, KS, KT, KX, KY, KZ, K_AT,
            K_CARET,
        ]),
        Dialect::Rockwell => mask(&[
            KA, KB, KC, KD, KF, KH, KI, KJ, KK, KP, KQ, KR, KS, KT, KX, KY, KZ,
        ]),
        Dialect::Sinumerik => mask(&[
            KA, KB, KC, KD, KF, KH, KI, KJ, KK, KS, KT, KX, KY, KZ, K_CR, K_TURN, K_RP, K_AP,
        ]),
        Dialect::Heidenhain => mask(&[KA, KB, KC, KF, KH, KI, KJ, KK, KL, KR, KS, KT, KX, KY, KZ]),
        Dialect::Fagor => mask(&[KA, KB, KC, KD, KF, KI, KJ, KK, KQ, KR, KS, KT, KX, KY, KZ]),
    }
}

/// A G or M number times ten (G59.1 → 591), if it has at most one decimal.
pub(crate) fn code10(v: f64) -> Option<u16> {
    let t = v * 10.0;
    // A whole number in range (G1 is 10.0), the common case, is its own rounding; `round`
    // is a library call on the baseline x86-64 target.
    if (0.0..=65535.0).contains(&t) && f64::from(t as u16) == t {
        return Some(t as u16);
    }
    let r = t.round();
    if !(0.0..=65535.0).contains(&r) || (t - r).abs() > 1e-6 {
        return None;
    }
    Some(r as u16)
}

/// The G code as written, for messages.
pub(crate) fn g_name(code10: u16) -> String {
    if code10.is_multiple_of(10) {
        format!("G{}", code10 / 10)
    } else {
        format!("G{}.{}", code10 / 10, code10 % 10)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn g_numbers() {
        assert_eq!(code10(59.1), Some(591));
        assert_eq!(code10(1.0), Some(10));
        assert_eq!(code10(1.25), None);
        assert_eq!(code10(-1.0), None);
        assert_eq!(g_name(591), "G59.1");
        assert_eq!(g_name(30), "G3");
    }
}

/// One line of the G or M code reference of a dialect ([`code_reference`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CodeInfo {
    /// The code as written, e.g. `G59.1`, `M3`, `M100–M199`.
    pub code: String,
    /// What it does, or `None` when the dialect refuses it.
    pub does: Option<&'static str>,
    /// The error a refused code gives (`None` when it is supported).
    pub error: Option<String>,
}

/// What a G code does, in one line.
fn describe_g(g: G) -> &'static str {
    use crate::interp::FeedMode as FM;
    use crate::interp::ToolLength as TL;
    match g {
        G::Motion(Motion::Rapid) => "rapid move",
        G::Motion(Motion::Linear) => "linear feed move",
        G::Motion(Motion::Arc(Some(false))) => "clockwise arc or helix",
        G::Motion(Motion::Arc(Some(true))) => "counter-clockwise arc or helix",
        G::Motion(Motion::Arc(None)) => "arc in the direction of the last programmed arc",
        G::Motion(Motion::PolarLine { rapid: true }) => "rapid polar line (about the pole)",
        G::Motion(Motion::PolarLine { rapid: false }) => "polar feed line (about the pole)",
        G::Motion(Motion::PolarArc(Some(false))) => "clockwise polar arc (about the pole)",
        G::Motion(Motion::PolarArc(Some(true))) => "counter-clockwise polar arc (about the pole)",
        G::Motion(Motion::PolarArc(None)) => {
            "polar arc in the direction of the last programmed arc"
        }
        G::Motion(Motion::Cycle(k)) => k.describe(),
        G::NoMotion => "cancel the modal motion (canned cycles)",
        G::Dwell => "dwell",
        G::Plane(Plane::Xy) => "XY plane",
        G::Plane(Plane::Zx) => "ZX plane",
        G::Plane(Plane::Yz) => "YZ plane",
        G::Units { inch: true, .. } => "inch units",
        G::Units { inch: false, .. } => "millimetre units",
        G::Distance { absolute: true } => "absolute distances",
        G::Distance { absolute: false } => "incremental distances",
        G::ArcDistance { absolute: true } => "absolute arc centres (I, J, K)",
        G::ArcDistance { absolute: false } => "incremental arc centres (I, J, K)",
        G::Comp(Comp::Off) => "cutter radius compensation off",
        G::Comp(Comp::Left) => "cutter radius compensation left of the path",
        G::Comp(Comp::Right) => "cutter radius compensation right of the path",
        G::CompDiameter(Comp::Left) => "cutter compensation left, diameter from D",
        G::CompDiameter(_) => "cutter compensation right, diameter from D",
        G::ToolLength(TL::Apply) => "tool length offset on",
        G::ToolLength(TL::Dynamic) => "tool length offset from the axis words",
        G::ToolLength(TL::Add) => "add a tool's length offset",
        G::ToolLength(TL::Cancel) => "tool length offset off",
        G::CoordSystem(Some(_)) => "select a work coordinate system",
        G::CoordSystem(None) => "cancel the work offset",
        G::Corner { exact: true } => "exact stop mode",
        G::Corner { exact: false } => "continuous path (blending within the tolerance)",
        G::ExactStopOnce => "exact stop for this block",
        G::G92Set => "coordinate system offset from the axis words",
        G::G92Reset => "clear the coordinate system offset",
        G::G92Suspend => "suspend the coordinate system offset",
        G::G92Restore => "restore the coordinate system offset",
        G::MachineCoords => "this block in machine coordinates",
        G::SetData => "set tool table or work offset data (L1, L2, L10, L11, L20)",
        G::Home(false) => "go to the G28 reference position",
        G::Home(true) => "go to the G30 reference position",
        G::HomeSet(false) => "store the G28 reference position",
        G::HomeSet(true) => "store the G30 reference position",
        G::LocalOffset => "local coordinate system offset",
        G::FeedPerMinute => "feed per minute",
        G::FeedMode(FM::InverseTime) => "inverse time feed",
        G::FeedMode(FM::PerMinute) => "feed per minute",
        G::FeedMode(FM::PerRev) => "feed per revolution (at the commanded S)",
        G::Retract { r_plane: false } => "canned cycle return to the initial level",
        G::Retract { r_plane: true } => "canned cycle return to the R level",
        G::Pole(PoleRef::LastPosition) => "pole relative to the last position",
        G::Pole(PoleRef::Workpiece) => "pole absolute in the workpiece",
        G::Pole(PoleRef::LastPole) => "pole relative to the last pole",
        G::PoleFromLast => "pole at the last programmed position",
        G::PolarOrigin => "polar origin",
        G::AbsCentreOnce => "absolute arc centre for this block",
        G::BlankForm => "blank form definition (for graphics; no motion)",
        G::ToolDef => "tool definition",
        G::NoOp => "accepted, no effect on the motion",
        G::Unsupported(_) => "not supported",
    }
}

/// The M codes of a dialect that are events or LinuxCNC state operations, with what they
/// do, and the LinuxCNC M codes refused with their errors.
fn m_codes(d: Dialect) -> Vec<CodeInfo> {
    let ok = |code: &str, does| CodeInfo {
        code: code.to_string(),
        does: Some(does),
        error: None,
    };
    let mut out = vec![
        ok("M0", "program pause"),
        ok("M1", "optional program pause"),
        ok("M2", "program end"),
        ok("M3", "spindle clockwise"),
        ok("M4", "spindle counter-clockwise"),
        ok("M5", "spindle stop"),
        ok("M6", "tool change"),
        ok("M7", "mist coolant on"),
        ok("M8", "flood coolant on"),
        ok("M9", "coolant off"),
        ok("M30", "program end and rewind"),
    ];
    // The shared table is the truth for the codes above.
    debug_assert!(out.iter().all(|c| {
        let n: u16 = c.code[1..].parse().unwrap_or(u16::MAX);
        m_event(n).is_some()
    }));
    if d == Dialect::LinuxCnc {
        for (code, does) in [
            ("M19", "spindle orient (event)"),
            ("M48", "enable the speed and feed overrides (event)"),
            ("M49", "disable the speed and feed overrides (event)"),
            ("M50", "feed override control (event)"),
            ("M51", "spindle speed override control (event)"),
            ("M52", "adaptive feed control (event)"),
            ("M53", "feed stop control (event)"),
            ("M60", "pallet change pause"),
            ("M61", "set the current tool number"),
            ("M62", "digital output P on with the next move (event)"),
            ("M63", "digital output P off with the next move (event)"),
            ("M64", "digital output P on at once (event)"),
            ("M65", "digital output P off at once (event)"),
            (
                "M66",
                "wait on digital input P or analog input E (L mode, Q timeout; result in #5399)",
            ),
            ("M67", "analog output E to Q with the next move (event)"),
            ("M68", "analog output E to Q at once (event)"),
            ("M70", "save the modal state"),
            ("M71", "invalidate the saved modal state"),
            ("M72", "restore the saved modal state"),
            (
                "M73",
                "save the modal state, restore it at the end of the subroutine",
            ),
            ("M100–M199", "user M codes (events)"),
        ] {
            out.push(ok(code, does));
        }
        for code in [98u16, 99] {
            out.push(CodeInfo {
                code: format!("M{code}"),
                does: None,
                error: crate::interp::linuxcnc_m_refusal_of(code).map(str::to_string),
            });
        }
    }
    out.sort_by_key(|c| {
        c.code[1..]
            .split(|ch: char| !ch.is_ascii_digit())
            .next()
            .and_then(|n| n.parse::<u32>().ok())
            .unwrap_or(u32::MAX)
    });
    out
}

/// The G codes (`g = true`) or M codes of dialect `d`: every code it supports with what it
/// does, and every code it knows but refuses with its error; codes it does not know are
/// refused as unknown and not listed. Generated from the tables the interpreter uses.
pub fn code_reference(d: Dialect, g: bool) -> Vec<CodeInfo> {
    if !g {
        return m_codes(d);
    }
    let mut out = Vec::new();
    for code10 in 0..=9999u16 {
        let Some(info) = classify_g(d, code10) else {
            continue;
        };
        out.push(CodeInfo {
            code: g_name(code10),
            does: match info {
                G::Unsupported(_) => None,
                other => Some(describe_g(other)),
            },
            error: match info {
                G::Unsupported(msg) => Some(msg.to_string()),
                _ => None,
            },
        });
    }
    out
}

/// The word addresses dialect `d` accepts besides G, M and N (and its own block syntax,
/// e.g. LinuxCNC's O-words and parameters), as written.
pub fn word_addresses(d: Dialect) -> Vec<String> {
    let mask = allowed_keys(d);
    (0u8..32)
        .filter(|k| mask & (1 << k) != 0)
        .map(key_name)
        .collect()
}
