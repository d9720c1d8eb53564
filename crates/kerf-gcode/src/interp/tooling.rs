//! Tools: the T word (tool call), the Heidenhain tool definition G99, the tool offset
//! words Kerf does not apply (D, Sinumerik H), cutter radius compensation and the tool
//! length offset of a block.

use super::exec::Slots;
use super::{Block, BlockError, Out, State, ToolLength, fail, tool_number};
use crate::codes::*;
use crate::{Dialect, EventCode, Tool};

/// The most tools a program may define with Heidenhain G99.
const MAX_TOOLS: usize = 10_000;

impl State {
    /// The T word: selects the tool (and, except in LinuxCNC, makes it current: the
    /// events are T and a tool change M6). In a Heidenhain tool definition (G99) T is the
    /// number being defined.
    pub(super) fn exec_tool_call(
        &mut self,
        blk: &Block,
        slots: &Slots,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        if let Some(t) = blk.get(KT) {
            let n = tool_number(t).ok_or_else(|| BlockError {
                col: blk.col(KT),
                message: "tool number must be a non-negative integer".into(),
            })?;
            if d != Dialect::Heidenhain || slots[0].is_none_or(|(g, _)| g != G::ToolDef) {
                self.check_tool_exists(n, blk.col(KT))?;
                self.tool_selected = Some(n);
                if d != Dialect::LinuxCnc {
                    // On the other controls the T word (Heidenhain tool call, Sinumerik
                    // T with automatic change) makes the tool current.
                    self.tool_loaded = Some(n);
                }
                if matches!(d, Dialect::Sinumerik | Dialect::Heidenhain | Dialect::Fagor)
                    && let Some(tool) = self.tool(Some(n)).filter(|t| t.length_mm != 0.0)
                {
                    // These controls apply the called tool's length (Sinumerik with D1
                    // active after the change); Kerf does not, so it refuses the call
                    // rather than cut at the wrong depth.
                    return fail(
                        blk.col(KT),
                        format!(
                            "tool length compensation is not supported (tool {} has a non-zero length)",
                            tool.number
                        ),
                    );
                }
                out.event(EventCode::T, Some(f64::from(n)));
                let m6_written = blk.ms[..blk.nm].iter().any(|&(m, _)| m == 6);
                if d != Dialect::LinuxCnc && !m6_written {
                    // The call is the change: the machine puts the tool in the spindle
                    // (its tool changer; a change to the tool already there is nothing).
                    // With M6 in the block, that M6 is the change.
                    out.event(EventCode::M6, None);
                }
            }
        }
        Ok(())
    }

    /// Heidenhain G99: tool definition (T number, L length, R radius).
    pub(super) fn define_tool(&mut self, blk: &Block) -> Result<(), BlockError> {
        if let Some(k) = blk.first_of(&[KX, KY, KZ, KA, KB, KC, KI, KJ, KK, KH]) {
            return fail(
                blk.col(k),
                format!("{} word in a tool definition (G99)", key_name(k)),
            );
        }
        let Some(t) = blk.get(KT).and_then(tool_number) else {
            return fail(blk.first_col, "G99 needs a tool number T");
        };
        let tool = Tool {
            number: t,
            length_mm: blk.get(KL).unwrap_or(0.0) * self.scale(),
            radius_mm: blk.get(KR).unwrap_or(0.0) * self.scale(),
            ..Tool::default()
        };
        // Redefinition replaces the entry and the table is capped, so that memory stays
        // bounded whatever the program does.
        let tools = &mut self.settings.tools;
        if let Some(entry) = tools.iter_mut().find(|t| t.number == tool.number) {
            *entry = tool;
        } else if tools.len() < MAX_TOOLS {
            tools.push(tool);
        } else {
            return fail(
                blk.first_col,
                format!("more than {MAX_TOOLS} tools defined"),
            );
        }
        Ok(())
    }

    /// D words: LinuxCNC and Rockwell take D (the tool whose radius compensation uses)
    /// only with G41/G42 in the block ("D word with no G41 or G42 to use it"); Sinumerik
    /// and Fagor D select the tool's offsets (length and radius), which Kerf does not
    /// apply: D0 (no offsets) is accepted, and D1 and up only while the active tool has a
    /// zero length and radius. Sinumerik H words are auxiliary functions for the machine's
    /// logic, which Kerf does not have: an error.
    #[inline]
    pub(super) fn check_tool_offset_words(
        &self,
        blk: &Block,
        comp: Option<(G, u32)>,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        if d == Dialect::Sinumerik && blk.has(KH) {
            return fail(blk.col(KH), "H auxiliary functions are not supported");
        }
        let Some(dv) = blk.get(KD) else {
            return Ok(());
        };
        match d {
            Dialect::LinuxCnc | Dialect::Rockwell => {
                if !matches!(
                    comp,
                    Some((G::Comp(Comp::Left | Comp::Right) | G::CompDiameter(_), _))
                ) {
                    return fail(blk.col(KD), "D word with no G41 or G42 to use it");
                }
            }
            Dialect::Sinumerik | Dialect::Fagor => {
                if dv != 0.0
                    && let Some(t) = self.tool(self.tool_loaded.or(self.tool_selected))
                    && (t.length_mm != 0.0 || t.radius_mm != 0.0)
                {
                    return fail(
                        blk.col(KD),
                        format!(
                            "tool offsets (D) are not supported (tool {} has a non-zero length or radius)",
                            t.number
                        ),
                    );
                }
            }
            Dialect::Heidenhain => {}
        }
        Ok(())
    }

    /// Cutter radius compensation: LinuxCNC computes it; the other controls accept it
    /// only while the active tool has a zero radius.
    pub(super) fn exec_cutter_comp(
        &mut self,
        blk: &Block,
        slot6: Option<(G, u32)>,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        if d == Dialect::LinuxCnc {
            self.linuxcnc_comp(blk, slot6, out)?;
        } else {
            if let Some((G::Comp(c) | G::CompDiameter(c), _)) = slot6 {
                self.comp = c;
            }
            if self.comp != Comp::Off {
                let number = match (d, blk.get(KD)) {
                    (Dialect::Rockwell, Some(dv)) => tool_number(dv),
                    _ => self.tool_loaded.or(self.tool_selected),
                };
                if self.tool(number).is_some_and(|t| t.radius_mm != 0.0) {
                    let col = slot6.map_or(blk.first_col, |(_, c)| c);
                    return fail(
                        col,
                        "cutter compensation not supported (the active tool has a non-zero radius)",
                    );
                }
            }
        }
        Ok(())
    }

    /// Tool length offset (G43 family, G49). Returns whether the code used the block's
    /// axis words.
    pub(super) fn exec_tool_length_code(
        &mut self,
        blk: &Block,
        slot7: Option<(G, u32)>,
        motion_in_block: bool,
    ) -> Result<bool, BlockError> {
        let d = self.dialect;
        let mut consumed_axes = false;
        if let Some((G::ToolLength(kind), col)) = slot7 {
            if kind == ToolLength::Cancel
                && matches!(d, Dialect::LinuxCnc | Dialect::Rockwell)
                && blk.has(KH)
            {
                return fail(blk.col(KH), "H word with no G43 to use it");
            }
            if d == Dialect::LinuxCnc {
                self.comp_refuse(
                    col,
                    "Cannot change tool offset with cutter radius compensation on",
                )?;
            }
            consumed_axes = self.exec_tool_length(blk, kind, col, motion_in_block)?;
            self.tool_length_on = kind != ToolLength::Cancel;
        } else if blk.has(KH) && matches!(d, Dialect::LinuxCnc | Dialect::Rockwell) {
            return fail(blk.col(KH), "H word with no G43 to use it");
        }
        Ok(consumed_axes)
    }
}
