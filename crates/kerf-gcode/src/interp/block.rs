//! One block's words, indexed by key, and how the lexed words of a line fill it: repeats,
//! per-dialect letters, G and M codes and Heidenhain's per-word G90/G91.

use super::{BlockError, State, fail};
use crate::Dialect;
use crate::codes::*;
use crate::lex::{Form, N_KEYS, Word};

/// The words of one block, indexed by key. Values are only meaningful where `present`
/// has the key's bit set, so a block is reset by clearing one integer.
pub(crate) struct Block {
    pub(super) present: u32,
    pub(super) vals: [f64; N_KEYS],
    pub(super) cols: [u32; N_KEYS],
    pub(super) forms: [Form; N_KEYS],
    pub(super) gs: [(u16, u32); 16],
    pub(super) ng: usize,
    pub(super) ms: [(u16, u32); 8],
    pub(super) nm: usize,
    pub(super) first_col: u32,
}

impl Block {
    pub(crate) fn new() -> Self {
        Block {
            present: 0,
            vals: [0.0; N_KEYS],
            cols: [0; N_KEYS],
            forms: [Form::Plain; N_KEYS],
            gs: [(0, 0); 16],
            ng: 0,
            ms: [(0, 0); 8],
            nm: 0,
            first_col: 1,
        }
    }

    pub(super) fn has(&self, k: u8) -> bool {
        self.present & (1 << k) != 0
    }

    pub(super) fn get(&self, k: u8) -> Option<f64> {
        if self.has(k) {
            Some(self.vals[k as usize])
        } else {
            None
        }
    }

    pub(super) fn col(&self, k: u8) -> u32 {
        self.cols[k as usize]
    }

    pub(super) fn any(&self, keys: &[u8]) -> bool {
        keys.iter().any(|&k| self.has(k))
    }

    pub(super) fn first_of(&self, keys: &[u8]) -> Option<u8> {
        keys.iter().copied().find(|&k| self.has(k))
    }
}

impl State {
    /// Fills `blk` from the lexed words, checking repeats and per-dialect letters.
    ///
    /// A code Kerf refuses (M98 P100) is named before any error of its words: the words are
    /// searched for one only when the block fails (every M word is checked for a refusal
    /// as it is met, so a block without error has none).
    pub(crate) fn build_block(&self, words: &[Word], blk: &mut Block) -> Result<(), BlockError> {
        self.fill_block(words, blk).map_err(|e| {
            match words
                .iter()
                .filter(|w| w.key == crate::lex::key(b'M'))
                .find_map(|w| Some((w.col, self.m_refusal(w.value)?)))
            {
                Some((col, message)) => BlockError {
                    col,
                    message: message.into(),
                },
                None => e,
            }
        })
    }

    /// The refusal of the M code with the value `v`, if Kerf refuses it.
    fn m_refusal(&self, v: f64) -> Option<&'static str> {
        code10(v).and_then(|c| self.linuxcnc_m_refusal(c / 10))
    }

    fn fill_block(&self, words: &[Word], blk: &mut Block) -> Result<(), BlockError> {
        blk.present = 0;
        blk.ng = 0;
        blk.nm = 0;
        blk.first_col = words.first().map_or(1, |w| w.col);
        // Heidenhain lets G90/G91 switch per axis inside a block: the words after a G90 or
        // G91 take that mode, the ones before the first one the modal one (the mode before
        // the block), which exec() would otherwise replace before reading them.
        let mut local: Option<bool> = None;
        let modal = if self.absolute { Form::Abs } else { Form::Inc };
        let allowed = allowed_keys(self.dialect);
        for w in words {
            let letter = if w.key < 26 { b'A' + w.key } else { 0 };
            match letter {
                b'G' => {
                    if blk.ng == blk.gs.len() {
                        return fail(w.col, "too many G codes in one block");
                    }
                    let code = code10(w.value).ok_or_else(|| BlockError {
                        col: w.col,
                        message: format!("unknown G code G{}", w.value),
                    })?;
                    if self.dialect == Dialect::Heidenhain && (code == 900 || code == 910) {
                        if local.is_none() {
                            for k in 0..N_KEYS as u8 {
                                if blk.has(k)
                                    && takes_distance_mode(k)
                                    && blk.forms[k as usize] == Form::Plain
                                {
                                    blk.forms[k as usize] = modal;
                                }
                            }
                        }
                        local = Some(code == 900);
                    }
                    blk.gs[blk.ng] = (code, w.col);
                    blk.ng += 1;
                    continue;
                }
                b'M' => {
                    if let Some(msg) = self.m_refusal(w.value) {
                        return fail(w.col, msg);
                    }
                    if blk.nm == blk.ms.len() {
                        return fail(w.col, "too many M codes in one block");
                    }
                    let code =
                        code10(w.value)
                            .filter(|c| c % 10 == 0)
                            .ok_or_else(|| BlockError {
                                col: w.col,
                                message: format!("unknown M code M{}", w.value),
                            })?;
                    blk.ms[blk.nm] = (code / 10, w.col);
                    blk.nm += 1;
                    continue;
                }
                b'N' => continue,
                _ => {}
            }
            if allowed & (1u32 << w.key) == 0 {
                self.check_letter(w)?;
            }
            if blk.has(w.key) {
                return fail(w.col, format!("word {} repeated", key_name(w.key)));
            }
            let k = w.key as usize;
            blk.present |= 1 << w.key;
            blk.vals[k] = w.value;
            blk.cols[k] = w.col;
            blk.forms[k] = match (w.form, local) {
                (Form::Plain, Some(abs)) if takes_distance_mode(w.key) => {
                    if abs {
                        Form::Abs
                    } else {
                        Form::Inc
                    }
                }
                (f, _) => f,
            };
        }
        Ok(())
    }

    fn check_letter(&self, w: &Word) -> Result<(), BlockError> {
        let k = w.key;
        let ok = allowed_keys(self.dialect) & (1u32 << k) != 0;
        if ok {
            return Ok(());
        }
        if matches!(k, 20..=22) {
            return fail(w.col, "U, V and W axes are not supported");
        }
        if self.dialect == Dialect::Sinumerik && k == KR {
            return fail(w.col, "R parameters are not supported yet");
        }
        if self.dialect == Dialect::Heidenhain && k == KQ {
            return fail(w.col, "Q parameters are not supported yet");
        }
        if self.dialect == Dialect::Fagor && k == KP {
            return fail(w.col, "arithmetic parameters (P) are not supported yet");
        }
        fail(w.col, format!("unknown word {}", key_name(k)))
    }
}

/// Heidenhain words whose value G90/G91 make absolute or incremental.
fn takes_distance_mode(k: u8) -> bool {
    XYZ.contains(&k) || ABC.contains(&k) || IJK.contains(&k) || k == KR || k == KH
}
