//! The M codes of a block: their classification into modal groups and into the events
//! that run before the motion and the stops that run after it, and the two stages that
//! emit them.

use super::modal::{Spindle, StateOp};
use super::{Block, BlockError, Out, State, fail, params};
use crate::codes::m_event;
use crate::{Dialect, EventCode};

/// The M codes of one block, sorted by when they run.
pub(super) struct MCodes {
    /// The events that run before the motion, at the code's place in the block.
    pre: [Option<EventCode>; 8],
    /// The events that run after the motion (stops, ends; Heidenhain M5 and M9), at the
    /// code's place in the block.
    pub(super) post: [Option<EventCode>; 8],
    /// LinuxCNC M70–M73 and its column.
    state_op: Option<(StateOp, u32)>,
    /// A user M code M100–M199.
    pub(super) user_m: Option<u8>,
    /// LinuxCNC M61 (set the tool number): its column.
    pub(super) m61: Option<u32>,
    /// M19 (spindle orientation), which takes R, Q and P.
    pub(super) orient: bool,
    /// One of M50–M53, which take P.
    pub(super) override_p: bool,
    /// LinuxCNC M62–M68 (modal group 5, `io`) and its column.
    pub(super) io: Option<(EventCode, u32)>,
}

impl MCodes {
    /// A block without M codes.
    pub(super) const NONE: MCodes = MCodes {
        pre: [None; 8],
        post: [None; 8],
        state_op: None,
        user_m: None,
        m61: None,
        orient: false,
        override_p: false,
        io: None,
    };
}

impl State {
    /// Classifies the M codes of a block into `mc` and checks their modal groups: they
    /// are all known before anything is emitted. Filled in place (not returned) so that
    /// a block without M codes, nearly every block, costs no copy of the record.
    pub(super) fn m_codes(&mut self, blk: &Block, mc: &mut MCodes) -> Result<(), BlockError> {
        if blk.nm == 0 {
            self.m19_in_block = false;
            *mc = MCodes::NONE;
            return Ok(());
        }
        let d = self.dialect;
        let mut m_pre: [Option<EventCode>; 8] = [None; 8];
        let mut m_post: [Option<EventCode>; 8] = [None; 8];
        let mut m_groups = 0u8;
        let mut state_op: Option<(StateOp, u32)> = None;
        let mut user_m: Option<u8> = None;
        let mut m61: Option<u32> = None;
        let mut io: Option<(EventCode, u32)> = None;
        for (i, &(code, col)) in blk.ms[..blk.nm].iter().enumerate() {
            if d == Dialect::LinuxCnc && code == 61 {
                // M61 Q: set the tool number (tool change group), no event.
                if m_groups & 2 != 0 {
                    return fail(col, "two M codes used from same modal group");
                }
                m_groups |= 2;
                m61 = Some(col);
                continue;
            }
            if let Some(msg) = self.linuxcnc_m_refusal(code) {
                return fail(col, msg);
            }
            let ev = match (m_event(code), self.linuxcnc_m(code)) {
                (Some(ev), _) | (None, Some(Ok(ev))) => ev,
                (None, Some(Err(op))) => {
                    // LinuxCNC keeps M70–M73 in the spindle group (M3 M70 is refused).
                    if m_groups & 4 != 0 {
                        return fail(col, "two M codes used from same modal group");
                    }
                    m_groups |= 4;
                    state_op = Some((op, col));
                    continue;
                }
                (None, None) => return fail(col, format!("unknown M code M{code}")),
            };
            if matches!(
                ev,
                EventCode::M62
                    | EventCode::M63
                    | EventCode::M64
                    | EventCode::M65
                    | EventCode::M66
                    | EventCode::M67
                    | EventCode::M68
            ) {
                // LinuxCNC modal group 5: one I/O code per block.
                if io.is_some() {
                    return fail(col, "two M codes used from same modal group");
                }
                io = Some((ev, col));
                continue;
            }
            if let EventCode::User(n) = ev {
                if user_m.is_some() {
                    return fail(col, "two M codes used from same modal group");
                }
                user_m = Some(n);
                continue;
            }
            // Modal groups of M codes (stop, tool change, spindle, coolant): at most one
            // of each per block, except that mist (M7) and flood (M8) may be turned on together.
            let grp = match ev {
                EventCode::M0 | EventCode::M1 | EventCode::M2 | EventCode::M30 | EventCode::M60 => {
                    1
                }
                EventCode::M6 => 2,
                EventCode::M3 | EventCode::M4 | EventCode::M5 | EventCode::M19 => 4,
                // LinuxCNC modal group 9: the override controls.
                EventCode::M48
                | EventCode::M49
                | EventCode::M50
                | EventCode::M51
                | EventCode::M52
                | EventCode::M53 => 32,
                // LinuxCNC (rs274) refuses M7 and M8 in one block: one coolant group.
                EventCode::M7 | EventCode::M8 if d == Dialect::LinuxCnc => 8 | 16,
                EventCode::M7 => 8,
                EventCode::M8 => 16,
                _ => 8 | 16,
            };
            if m_groups & grp != 0 {
                return fail(col, "two M codes used from same modal group");
            }
            m_groups |= grp;
            let after = match ev {
                EventCode::M0 | EventCode::M1 | EventCode::M2 | EventCode::M30 | EventCode::M60 => {
                    true
                }
                // TNC: M5 and M9 take effect at the end of the block, M3/M4/M8 at its start.
                EventCode::M5 | EventCode::M9 => d == Dialect::Heidenhain,
                _ => false,
            };
            if after {
                m_post[i] = Some(ev);
            } else {
                m_pre[i] = Some(ev);
            }
        }

        let orient = m_pre.contains(&Some(EventCode::M19));
        if orient {
            State::check_m19(blk)?;
        }
        let override_p = [
            EventCode::M50,
            EventCode::M51,
            EventCode::M52,
            EventCode::M53,
        ]
        .iter()
        .any(|&ev| m_pre.contains(&Some(ev)));
        self.m19_in_block = orient;
        *mc = MCodes {
            pre: m_pre,
            post: m_post,
            state_op,
            user_m,
            m61,
            orient,
            override_p,
            io,
        };
        Ok(())
    }

    /// The M codes that run before the motion, in LinuxCNC's order: M6, the spindle
    /// (M3, M4, M5, M19), M70–M73, the coolant (M7, M8, M9), the overrides (M48–M53), the
    /// user M code, then M61.
    pub(super) fn exec_m_before_motion(
        &mut self,
        blk: &Block,
        mc: &MCodes,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        let m_pre = &mc.pre;
        for ev in [
            EventCode::M6,
            EventCode::M3,
            EventCode::M4,
            EventCode::M5,
            EventCode::M19,
            EventCode::M7,
            EventCode::M8,
            EventCode::M9,
        ] {
            if blk.nm == 0 {
                break;
            }
            if ev == EventCode::M7
                && let Some((op, col)) = mc.state_op
            {
                // LinuxCNC M70–M73 run after the spindle and before the coolant.
                self.state_op(op, col, out)?;
            }
            if blk.nm > 0 && m_pre.contains(&Some(ev)) {
                if ev == EventCode::M6 {
                    if d == Dialect::LinuxCnc {
                        self.comp_refuse(
                            blk.first_col,
                            "Cannot change tools with cutter radius compensation on",
                        )?;
                        self.load_tool(self.tool_selected, true);
                        self.m6_in_block = true;
                        // After a tool change LinuxCNC reads its current point back from
                        // where the tool is: after G40, the last compensated end, not the
                        // programmed point (LinuxCNC's useful-subroutines.ngc).
                        self.crc.exit_ref = None;
                        // LinuxCNC stops the spindle for the change (rs274:
                        // STOP_SPINDLE_TURNING before CHANGE_TOOL).
                        self.spindle = Spindle::Off;
                    } else {
                        self.tool_loaded = self.tool_selected;
                    }
                }
                if ev == EventCode::M19 {
                    // The spindle stops to orient (rs274: "Spindle not turning" after it).
                    self.note_machine_event(EventCode::M5);
                    self.cycles.note_spindle(EventCode::M5);
                    self.orient_event(blk, out);
                    continue;
                }
                self.note_machine_event(ev);
                self.cycles.note_spindle(ev);
                out.event(ev, None);
            }
        }
        // LinuxCNC M48–M53 after the coolant, before the user M codes.
        for ev in [
            EventCode::M48,
            EventCode::M49,
            EventCode::M50,
            EventCode::M51,
            EventCode::M52,
            EventCode::M53,
        ] {
            if blk.nm > 0 && m_pre.contains(&Some(ev)) {
                self.override_event(ev, blk, out);
            }
        }
        if let Some(n) = mc.user_m {
            self.user_m_event(n, blk, out);
        }

        if let Some(col) = mc.m61 {
            self.exec_m61(blk, col)?;
        }
        Ok(())
    }

    /// The M codes that run after the motion: Heidenhain M5 and M9, the stops and the
    /// program ends.
    pub(super) fn finish_block(
        &mut self,
        blk: &Block,
        m_post: &[Option<EventCode>; 8],
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if blk.nm == 0 {
            return Ok(());
        }
        self.comp_before_stops(m_post, blk.first_col, out)?;
        for ev in [
            EventCode::M5,
            EventCode::M9,
            EventCode::M0,
            EventCode::M1,
            EventCode::M60,
            EventCode::M2,
            EventCode::M30,
        ] {
            if m_post.contains(&Some(ev)) {
                out.event(ev, None);
                if matches!(ev, EventCode::M2 | EventCode::M30) {
                    self.done = true;
                    if self.dialect == Dialect::LinuxCnc {
                        // LinuxCNC's program end selects G54 again (#5220 = 1).
                        self.coord_system = Some(0);
                        self.params.set(params::COORD_SYSTEM, 1.0);
                    }
                }
            }
        }
        Ok(())
    }
}
