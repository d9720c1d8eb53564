//! The dwell G4: its time word per dialect, checked before F and S are read (on Sinumerik
//! and Heidenhain the F, and Sinumerik S, of a dwell block is the dwell).

use super::exec::Slots;
use super::{Block, BlockError, State, fail};
use crate::Dialect;
use crate::codes::*;
use crate::lex::{K_AP, K_AT, K_CARET, K_CR, K_RP, K_TURN};

/// The longest dwell accepted, in the unit of the dwell word (seconds; spindle revolutions
/// for Sinumerik `G4 S`): 1e6 s is eleven and a half days, far beyond any dwell a part
/// needs (the ISO dwell word of Fanuc-style controls stops at 99,999.999 s) and short of
/// the values at which adding it to a clock loses precision.
const MAX_DWELL: f64 = 1e6;

/// The words that describe motion or geometry: a dwell block may not hold them, except
/// in LinuxCNC, where the motion runs after the dwell.
const MOTION_WORDS: [u8; 18] = [
    KX, KY, KZ, KA, KB, KC, KI, KJ, KK, KR, KQ, KH, K_CR, K_TURN, K_RP, K_AP, K_AT, K_CARET,
];

/// The dwell of a block, as `dwell_of` found it.
pub(super) struct Dwell {
    /// The column of the G4 (`None`: no dwell in the block).
    pub(super) col: Option<u32>,
    /// The word that gave the time (that word is then not a feed or a spindle speed).
    pub(super) word: Option<u8>,
    /// The dwell time in seconds, when the block dwells.
    pub(super) seconds: Option<f64>,
}

impl State {
    /// Dwell: the time word is checked here, before F and S are read, because on
    /// Sinumerik and Heidenhain the F (and Sinumerik S) of a dwell block is the dwell,
    /// not a feed or a spindle speed.
    pub(super) fn dwell_of(&self, blk: &Block, slots: &Slots) -> Result<Dwell, BlockError> {
        let dwell_col = slots[0].filter(|&(g, _)| g == G::Dwell).map(|(_, c)| c);
        let dwell_checked = match dwell_col {
            Some(col) => Some(self.check_dwell(blk, col)?),
            None => None,
        };
        Ok(Dwell {
            col: dwell_col,
            word: dwell_checked.and_then(|(word, _)| word),
            seconds: dwell_checked.map(|(_, seconds)| seconds),
        })
    }

    /// Checks the dwell word of a G4 block (`col` is the G4) and returns its key, if given,
    /// and the dwell time in seconds (zero without a time word).
    ///
    /// The dwell word: LinuxCNC `P` (seconds, required); Rockwell `X` or `P`; Sinumerik `F`
    /// (seconds) or `S` (spindle revolutions, timed at the last programmed spindle
    /// speed); Heidenhain `F` (seconds); Fagor `K` (seconds). Its value must be from 0 to
    /// [`MAX_DWELL`]. Except in LinuxCNC, the block
    /// may not hold motion words (the Sinumerik manual: "G4 must be programmed in a
    /// separate block"); a word that would be an axis elsewhere is never silently dropped.
    fn check_dwell(&self, blk: &Block, col: u32) -> Result<(Option<u8>, f64), BlockError> {
        let d = self.dialect;
        let (g, words): (&str, &[u8]) = match d {
            Dialect::LinuxCnc => ("G4", &[KP]),
            Dialect::Rockwell => ("G04", &[KX, KP]),
            Dialect::Sinumerik => ("G4", &[KF, KS]),
            Dialect::Heidenhain => ("G04", &[KF]),
            Dialect::Fagor => ("G04", &[KK]),
        };
        if d != Dialect::LinuxCnc
            && let Some(k) = MOTION_WORDS
                .iter()
                .copied()
                .filter(|k| !words.contains(k))
                .find(|&k| blk.has(k))
        {
            return fail(
                blk.col(k),
                format!(
                    "{g} must be programmed in a separate block ({} word with {g})",
                    key_name(k)
                ),
            );
        }
        let mut given = words.iter().copied().filter(|&k| blk.has(k));
        let Some(word) = given.next() else {
            if d == Dialect::LinuxCnc {
                return fail(col, "Dwell time P word missing with G4");
            }
            // Rockwell, Sinumerik, Heidenhain and Fagor accept G4 without a time: a dwell
            // of zero, still an exact stop.
            return Ok((None, 0.0));
        };
        if let Some(second) = given.next() {
            return fail(
                blk.col(second),
                format!(
                    "dwell time given twice with {g} ({} and {})",
                    key_name(word),
                    key_name(second)
                ),
            );
        }
        let name = key_name(word);
        let value = blk.vals[word as usize];
        if value < 0.0 {
            if d == Dialect::LinuxCnc {
                return fail(blk.col(word), "Negative P word used");
            }
            return fail(
                blk.col(word),
                format!("negative dwell time {name} with {g}"),
            );
        }
        if !(0.0..=MAX_DWELL).contains(&value) {
            return fail(
                blk.col(word),
                format!("dwell time {name} with {g} must be at most 1000000, found {value}"),
            );
        }
        if word != KS {
            return Ok((Some(word), value));
        }
        // Sinumerik G4 S: spindle revolutions at the programmed speed.
        match self.spindle_rpm.filter(|&rpm| rpm > 0.0) {
            Some(rpm) => Ok((Some(word), value * 60.0 / rpm)),
            None => fail(
                blk.col(KS),
                "G4 S dwells in spindle revolutions: no spindle speed S programmed",
            ),
        }
    }
}
