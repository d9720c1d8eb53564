//! The words no code of a block uses: LinuxCNC's L, P and Q checks, Heidenhain R without
//! an arc, the centre words of an axis code, Rockwell P and Q. Each is refused rather than
//! silently dropped.

use super::exec::Slots;
use super::mcodes::MCodes;
use super::{Block, BlockError, State, cycles, fail};
use crate::codes::*;
use crate::{Dialect, EventCode};

impl State {
    /// Refuses the words of a block that no code of it uses (after the motion mode of the
    /// block is set; `dwell`: the block holds G4; `consumed_axes`: a code other than the
    /// motion used the axis words).
    pub(super) fn check_unused_words(
        &self,
        blk: &Block,
        slots: &Slots,
        mc: &MCodes,
        dwell: bool,
        consumed_axes: bool,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        let g64 = matches!(slots[9], Some((G::Corner { exact: false }, _)));
        let motion_g = slots[1];
        // LinuxCNC's I/O codes: M62–M66 take P, M66–M68 Q, M66 L, M66–M68 E.
        let io = mc.io.map(|(code, _)| code);
        let io_p = matches!(
            io,
            Some(EventCode::M62 | EventCode::M63 | EventCode::M64 | EventCode::M65)
                | Some(EventCode::M66)
        );
        let io_qe = matches!(io, Some(EventCode::M66 | EventCode::M67 | EventCode::M68));
        if d == Dialect::LinuxCnc {
            if blk.has(KE) && !io_qe {
                return fail(
                    blk.col(KE),
                    "E word with no G70, G76, M66, M67 or M68 to use it",
                );
            }
            let explicit_cycle = matches!(motion_g, Some((G::Motion(Motion::Cycle(_)), _)));
            // G10, G41.1/G42.1 and M66 take L too, and check it themselves.
            let g10 = slots[0].is_some_and(|(g, _)| g == G::SetData);
            let g41_1 = matches!(slots[6], Some((G::CompDiameter(_), _)));
            if !g10 && !g41_1 && io != Some(EventCode::M66) {
                self.check_l_word(blk, explicit_cycle)?;
            }
        }
        if d == Dialect::LinuxCnc
            && blk.present & (1 << KP | 1 << KQ) != 0
            && !self.axes_without_motion(blk)
        {
            // LinuxCNC refuses words that no G code of the block uses.
            let arc = matches!(self.motion, Some(Motion::Arc(_)));
            let user = mc.user_m.is_some();
            let g10 = slots[0].is_some_and(|(g, _)| g == G::SetData);
            if blk.has(KP)
                && !(dwell
                    || g64
                    || arc
                    || user
                    || g10
                    || mc.orient
                    || mc.override_p
                    || io_p
                    || self.cycle_uses_p())
            {
                return fail(blk.col(KP), cycles::unused_word_message(KP));
            }
            if blk.has(KQ)
                && !(g64
                    || user
                    || g10
                    || mc.orient
                    || mc.m61.is_some()
                    || io_qe
                    || self.cycle_uses_q())
            {
                return fail(blk.col(KQ), cycles::unused_word_message(KQ));
            }
        }
        if d == Dialect::Heidenhain
            && blk.has(KR)
            && matches!(self.motion, Some(Motion::Rapid | Motion::Linear))
        {
            return fail(blk.col(KR), "R word with no G02, G03, G10 or G11 to use it");
        }
        // The axis words belong to the G52/G92 or G28/G30 code (a motion code with them
        // was refused above): the centre words have no arc to use them.
        let axis_code = slots[0].is_some_and(|(g, _)| {
            matches!(
                g,
                G::G92Set
                    | G::G92Reset
                    | G::G92Suspend
                    | G::G92Restore
                    | G::LocalOffset
                    | G::Home(_)
            )
        });
        if consumed_axes && axis_code {
            self.check_unused(blk, false)?;
        }
        if d == Dialect::Rockwell {
            // P is the dwell time, Q and R belong to cycles (not supported) and arcs.
            if blk.has(KP) && !dwell {
                return fail(blk.col(KP), "P word with no G code that uses it");
            }
            if blk.has(KQ) {
                return fail(blk.col(KQ), "Q word with no G code that uses it");
            }
        }
        Ok(())
    }
}
