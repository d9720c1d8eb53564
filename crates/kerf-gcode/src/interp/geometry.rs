//! Geometry of one motion block: the end point of each axis word (distance mode, program
//! origin, unit) and the words no G code of the block uses.

use super::{Block, BlockError, State, fail};
use crate::Dialect;
use crate::codes::*;
use crate::lex::{Form, K_CR, K_TURN};

impl State {
    /// The machine coordinate of linear axis `i` after a word with `value`, honouring the
    /// word's form, the modal distance mode and the program origin.
    pub(super) fn linear_target(&self, blk: &Block, k: u8, i: usize) -> f64 {
        match blk.get(k) {
            None => self.pos[i],
            Some(v) => {
                let v = v * self.scale();
                if self.word_absolute(blk, k) {
                    v + self.origin[i]
                } else {
                    self.pos[i] + v
                }
            }
        }
    }

    pub(super) fn word_absolute(&self, blk: &Block, k: u8) -> bool {
        match blk.forms[k as usize] {
            Form::Abs => true,
            Form::Inc => false,
            Form::Plain => self.absolute,
        }
    }

    pub(super) fn abc_target(&self, blk: &Block) -> [f64; 3] {
        let mut abc = self.abc;
        for (i, &k) in ABC.iter().enumerate() {
            if let Some(v) = blk.get(k) {
                abc[i] = if self.word_absolute(blk, k) {
                    v + self.origin_abc[i]
                } else {
                    self.abc[i] + v
                };
            }
        }
        abc
    }

    /// Errors for words no G code of this block uses (LinuxCNC is strict about them).
    pub(super) fn check_unused(&self, blk: &Block, arc: bool) -> Result<(), BlockError> {
        if !arc {
            let centre_words: &[u8] = match self.dialect {
                Dialect::Heidenhain => &[],
                Dialect::Sinumerik => &[KI, KJ, KK, K_CR, K_TURN],
                Dialect::Fagor => &[KI, KJ, KK],
                // LinuxCNC M19 takes R (its angle).
                Dialect::LinuxCnc if self.m19_in_block => &[KI, KJ, KK],
                _ => &[KI, KJ, KK, KR],
            };
            if let Some(k) = blk.first_of(centre_words) {
                if self.dialect == Dialect::LinuxCnc {
                    return fail(blk.col(k), super::cycles::unused_word_message(k));
                }
                return fail(
                    blk.col(k),
                    format!("{} word with no G2 or G3 to use it", key_name(k)),
                );
            }
        }
        Ok(())
    }
}
