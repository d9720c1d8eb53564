//! LinuxCNC canned cycles: G73, G81, G82, G83, G85, G86, G87, G88 and G89 with G98/G99,
//! R, L repeats and incremental mode, in the G17, G18 and G19 planes, resolved into the
//! moves and events LinuxCNC's interpreter (rs274, 2.9) produces for them.
//!
//! The cycle works in the active plane: `u`, `v` are the plane's axes (G17: X, Y; G18: Z,
//! X; G19: Y, Z) and `w` the drilling axis along its normal (G17: Z, G18: Y, G19: X). As in
//! rs274, the values are computed in program coordinates and program units and only the
//! resulting points are converted to machine millimetres, so that every decision (a peck
//! more or less, a preliminary move or not) is the one rs274 takes:
//!
//! - Absolute (G90): R and the `w` word are positions, the `u`/`v` words the hole position
//!   (a missing one keeps the current value). Incremental (G91): R is measured from the
//!   initial level, the `w` word from R, and the `u`/`v` words are added to the current
//!   position before each repeat (so L repeats step along a line).
//! - The initial level is the `w` position when the series of cycles started; it is kept
//!   while the motion mode stays a cycle (changing from one cycle to another keeps it) and
//!   is forgotten when G0, G1, G2, G3 or G80 is programmed (even without axis words).
//! - If the initial level is below R, a rapid along `w` to R comes first (once per block).
//!   The clearance level is R under G99, the initial level (raised to R) under G98.
//! - Before each repeat: on the first, when the current `w` is above R, a rapid in the
//!   plane at the current `w`, then a rapid down to R; otherwise a rapid to the hole at
//!   the clearance level, then down to R if that is above it. (rs274 does this even when
//!   the tool is below the clearance level, which makes a slanted rapid: Kerf does the same.)
//! - R, the `w` word, P, Q and G87's I J K are kept for the following blocks of the same
//!   cycle; a block with another cycle code needs them again. L is not kept.
//! - G73 and G83 peck by Q from R: `d = R − Q, R − 2Q, …` while `d` is above the bottom;
//!   G73 backs off 0.010 in (0.254 mm) after each peck, G83 goes back out to R and returns
//!   rapidly to 0.010 in (0.254 mm) above `d`.

use super::{Block, BlockError, State, fail};
use crate::EventCode;
use crate::codes::*;
use crate::lex::{K_AT, K_CARET};

mod run;

/// The most moves and events one canned-cycle block may produce (its L repeats and pecks
/// together). A block's items are held until the whole block is resolved, so this bounds
/// the memory a block can take; rs274 has no such limit.
pub(crate) const MAX_CYCLE_ITEMS: usize = 100_000;

/// The longest dwell accepted, seconds (as for G4).
const MAX_DWELL_S: f64 = 1e6;

/// rs274's message for a word no G code of the block uses (I, J, K, L, P, Q, R).
pub(crate) fn unused_word_message(k: u8) -> &'static str {
    match k {
        KI => "I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it",
        KJ => "J word with no G2, G3, G5, G5.1, G10, G76 or G87 to use it",
        KK => "K word with no G2, G3, G33, G33.1, G76, or G87 to use it",
        KL => {
            "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code"
        }
        KP => {
            "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it"
        }
        KQ => {
            "Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it"
        }
        _ => "R word with no g code that uses it",
    }
}

/// A canned cycle (LinuxCNC motion modes G73, G81–G83, G85–G89).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CycleKind {
    G73,
    G81,
    G82,
    G83,
    G85,
    G86,
    G87,
    G88,
    G89,
}

impl CycleKind {
    /// What the cycle does, in one line.
    pub(crate) fn describe(self) -> &'static str {
        match self {
            CycleKind::G73 => "drilling cycle with chip break",
            CycleKind::G81 => "drilling cycle",
            CycleKind::G82 => "drilling cycle with dwell",
            CycleKind::G83 => "peck drilling cycle",
            CycleKind::G85 => "boring cycle, feed out",
            CycleKind::G86 => "boring cycle, spindle stop, rapid out",
            CycleKind::G87 => "back boring cycle",
            CycleKind::G88 => "boring cycle, spindle stop, manual out",
            CycleKind::G89 => "boring cycle, dwell, feed out",
        }
    }

    /// The cycle of a G number times ten, if it is one.
    pub(crate) fn from_code10(code10: u16) -> Option<CycleKind> {
        Some(match code10 {
            730 => CycleKind::G73,
            810 => CycleKind::G81,
            820 => CycleKind::G82,
            830 => CycleKind::G83,
            850 => CycleKind::G85,
            860 => CycleKind::G86,
            870 => CycleKind::G87,
            880 => CycleKind::G88,
            890 => CycleKind::G89,
            _ => return None,
        })
    }

    /// The code as rs274 writes it in its messages.
    fn name(self) -> &'static str {
        match self {
            CycleKind::G73 => "g73",
            CycleKind::G81 => "g81",
            CycleKind::G82 => "g82",
            CycleKind::G83 => "g83",
            CycleKind::G85 => "g85",
            CycleKind::G86 => "g86",
            CycleKind::G87 => "g87",
            CycleKind::G88 => "g88",
            CycleKind::G89 => "g89",
        }
    }

    /// The cycles with a dwell P.
    fn uses_p(self) -> bool {
        matches!(
            self,
            CycleKind::G82 | CycleKind::G86 | CycleKind::G88 | CycleKind::G89
        )
    }

    /// The peck cycles, with a Q.
    fn uses_q(self) -> bool {
        matches!(self, CycleKind::G73 | CycleKind::G83)
    }
}

/// The spindle direction, as the cycles that stop and restart it need to know.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Spindle {
    Stopped,
    Cw,
    Ccw,
}

/// What the canned cycles keep from block to block (rs274's `cycle_*` settings).
pub(crate) struct CycleState {
    /// The cycle of the last cycle block executed while the motion mode stayed a cycle
    /// (rs274's motion mode, for the sticky words); `None` after G0–G3 or G80.
    last: Option<CycleKind>,
    /// The initial level along the drilling axis, program units (rs274's `cycle_il`).
    initial_level: Option<f64>,
    /// The last R word, as written (incremental R stays an increment).
    r: f64,
    /// The last word along the drilling axis, as written.
    bottom: f64,
    /// The last dwell P of G82/G86/G88/G89, seconds.
    p: f64,
    /// The last peck Q of G73/G83.
    q: f64,
    /// The last I, J, K of G87.
    ijk: [f64; 3],
    /// The spindle direction (M3, M4, M5).
    pub(crate) spindle: Spindle,
    /// The plane before the current block's plane code (rs274 checks polar words in a cycle
    /// against it).
    pub(crate) block_plane: crate::arc::Plane,
}

impl CycleState {
    pub(crate) fn new() -> Self {
        CycleState {
            last: None,
            initial_level: None,
            r: 0.0,
            bottom: 0.0,
            p: 0.0,
            q: 0.0,
            ijk: [0.0; 3],
            spindle: Spindle::Stopped,
            block_plane: crate::arc::Plane::Xy,
        }
    }

    /// Follows the spindle events of a block (M3, M4, M5).
    pub(crate) fn note_spindle(&mut self, ev: EventCode) {
        match ev {
            EventCode::M3 => self.spindle = Spindle::Cw,
            EventCode::M4 => self.spindle = Spindle::Ccw,
            EventCode::M5 | EventCode::M2 | EventCode::M30 => self.spindle = Spindle::Stopped,
            _ => {}
        }
    }
}

impl State {
    /// Called with the block's group-1 code before its motion: G80 with axis words is an
    /// error, and any motion code that is not a cycle ends the series of cycles.
    pub(super) fn cycle_motion_code(
        &mut self,
        blk: &Block,
        code: Option<(G, u32)>,
    ) -> Result<(), BlockError> {
        match code {
            Some((G::NoMotion, col)) => {
                if blk.any(&XYZ) || blk.any(&ABC) || blk.has(K_AT) || blk.has(K_CARET) {
                    return fail(col, "Cannot use axis values with g80");
                }
                self.cycle_forget();
            }
            Some((G::Motion(Motion::Cycle(_)), _)) => {}
            Some((G::Motion(_), _)) => self.cycle_forget(),
            _ => {}
        }
        Ok(())
    }

    /// A motion code other than a cycle (or G80) ends the cycle: the next one starts
    /// afresh (its initial level, its sticky words' check).
    pub(super) fn cycle_forget(&mut self) {
        self.cycles.last = None;
        self.cycles.initial_level = None;
    }

    /// LinuxCNC: axis words without a motion mode, an error rs274 reports before the words
    /// no G code uses.
    pub(super) fn axes_without_motion(&self, blk: &Block) -> bool {
        self.motion.is_none()
            && (blk.any(&XYZ) || blk.any(&ABC) || blk.has(K_AT) || blk.has(K_CARET))
    }

    /// Whether the active motion mode is a cycle that uses P (G82, G86, G88, G89).
    pub(super) fn cycle_uses_p(&self) -> bool {
        matches!(self.motion, Some(Motion::Cycle(k)) if k.uses_p())
    }

    /// Whether the active motion mode is a peck cycle that uses Q (G73, G83).
    pub(super) fn cycle_uses_q(&self) -> bool {
        matches!(self.motion, Some(Motion::Cycle(k)) if k.uses_q())
    }

    /// LinuxCNC: an L word needs a canned cycle that moves (or G10, which is not supported
    /// yet). Axis words without a motion mode are reported first, as rs274 does.
    /// `explicit_cycle`: the block names a cycle (then a missing axis word is the error).
    pub(super) fn check_l_word(&self, blk: &Block, explicit_cycle: bool) -> Result<(), BlockError> {
        let cycle = matches!(self.motion, Some(Motion::Cycle(_)));
        let axes = blk.any(&XYZ) || blk.has(K_AT) || blk.has(K_CARET);
        let used = cycle && (explicit_cycle || axes);
        if blk.has(KL) && !used && !self.axes_without_motion(blk) {
            return fail(blk.col(KL), unused_word_message(KL));
        }
        Ok(())
    }
}
