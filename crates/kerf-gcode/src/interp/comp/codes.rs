//! The G-code side of cutter compensation: the G40/G41/G42/G41.1/G42.1 step of a LinuxCNC
//! block with its D and L words, and the held moves released before the stops.

use crate::arc::Plane;
use crate::codes::{Comp, G};
use crate::interp::{Block, BlockError, Out, State, fail, tool_number};

impl State {
    /// The G40/G41/G42/G41.1/G42.1 step of a LinuxCNC block, and the D and L words.
    pub(in crate::interp) fn linuxcnc_comp(
        &mut self,
        blk: &Block,
        slot: Option<(G, u32)>,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        use crate::codes::{KD, KL};
        let (g, col) = match slot {
            Some((g @ (G::Comp(_) | G::CompDiameter(_)), col)) => (g, col),
            _ => {
                // L belongs to G10, the canned cycles (repeats) and G41.1/G42.1: the
                // canned-cycle check refuses it elsewhere.
                if blk.has(KD) {
                    return fail(
                        blk.col(KD),
                        "D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it",
                    );
                }
                return Ok(());
            }
        };
        if self.mdi() && !matches!(g, G::Comp(Comp::Off)) {
            return fail(
                col,
                "cutter radius compensation is not available in MDI (a compensated move waits for the next one)",
            );
        }
        match g {
            G::Comp(Comp::Off) => {
                if blk.has(KL) {
                    return fail(
                        blk.col(KL),
                        "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code",
                    );
                }
                if blk.has(KD) {
                    return fail(
                        blk.col(KD),
                        "D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it",
                    );
                }
                self.comp_set(Comp::Off, 0.0, col, out)
            }
            G::Comp(side) => {
                // LinuxCNC accepts (and ignores) an L word with G41/G42.
                let name = if side == Comp::Left { "G41" } else { "G42" };
                let number = match blk.get(KD) {
                    Some(dv) => {
                        // LinuxCNC takes the D word as the whole number `(int)(D + 0.5)`
                        // when D lies within 0.0001 of it (so a negative D is "not a whole
                        // number").
                        let rounded = (dv + 0.5).trunc();
                        if (rounded - dv).abs() >= 0.0001 {
                            return fail(
                                blk.col(KD),
                                format!("{name} requires D word to be a whole number"),
                            );
                        }
                        let n = tool_number(rounded);
                        match n.filter(|&n| n != 0) {
                            Some(n) => {
                                if self.tool(Some(n)).is_none() {
                                    return fail(
                                        blk.col(KD),
                                        format!("Requested tool {n} not found in the tool table"),
                                    );
                                }
                                Some(n)
                            }
                            None => self.tool_loaded,
                        }
                    }
                    None => self.tool_loaded,
                };
                let radius = self.tool(number).map_or(0.0, |t| t.radius_mm);
                self.comp_set(side, radius, col, out)
            }
            G::CompDiameter(side) => {
                let name = if side == Comp::Left { "G41.1" } else { "G42.1" };
                let Some(dia) = blk.get(KD) else {
                    return fail(col, format!("{name} with no D word"));
                };
                if let Some(l) = blk.get(KL) {
                    if self.plane != Plane::Zx {
                        return fail(
                            blk.col(KL),
                            format!("{name} with L word, but plane is not G18"),
                        );
                    }
                    if l != 0.0 && l != 9.0 {
                        return fail(
                            blk.col(KL),
                            format!("{name} L (lathe tool orientation 1 to 8) is not supported"),
                        );
                    }
                }
                self.comp_set(side, dia * self.scale() / 2.0, col, out)
            }
            _ => Ok(()),
        }
    }

    /// M0, M1, M60, M2 and M30 release the held moves first, through LinuxCNC's end-point
    /// check (their ends stay where they are); M2 and M30 turn compensation off.
    pub(in crate::interp) fn comp_before_stops(
        &mut self,
        m_post: &[Option<crate::EventCode>; 8],
        col: u32,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        use crate::EventCode as E;
        let stop = m_post
            .iter()
            .flatten()
            .any(|e| matches!(e, E::M0 | E::M1 | E::M2 | E::M30 | E::M60));
        if stop {
            if self.comp_active() && !self.crc.first {
                let (u, v, _) = self.uv_axes();
                self.crc.col = col;
                self.move_endpoint_and_flush((self.pos[u], self.pos[v]), out)?;
            }
            self.comp_flush(out);
        }
        if m_post.iter().flatten().any(|e| matches!(e, E::M2 | E::M30)) {
            self.crc.side = None;
            self.crc.radius_mm = 0.0;
            self.crc.first = true;
        }
        Ok(())
    }
}
