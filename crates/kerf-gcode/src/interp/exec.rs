//! The execution of one block: [`State::exec`] and `exec_block`, which runs the block's
//! stages in LinuxCNC's order of execution (the manual's "G-code Order of Execution"):
//! the G and M codes are classified and checked first, then feed mode and F, S, T, the M
//! codes before the motion, the dwell, the modes (plane, units, distance, path control,
//! coordinate system), tool definition, cutter compensation, tool length offset, the axis
//! codes (G52/G92, G10, G28/G30), poles, the motion, and last the stops and program ends.
//! The other controls set the modes before reading the block's values (see
//! [`State::apply_modes`]). Each stage is a function of its own, here or in the module of
//! its subject.

use kerf_geom::CornerMode;
use kerf_geom::PerAxis;

use super::mcodes::MCodes;
use super::{Block, BlockError, LINUXCNC_MOTION_WORDS, MM_PER_INCH, Out, State, fail, params};
use crate::arc::Plane;
use crate::codes::*;
use crate::{Dialect, EventCode, Item};

/// The G codes of a block, one slot per modal group (each group holds at most one code
/// per block).
pub(super) type Slots = [Option<(G, u32)>; N_GROUPS];

impl State {
    /// Resolves one block into `out`. On error, the caller discards what this block pushed.
    ///
    /// LinuxCNC: after a block with M6, the current point is read back as rs274 reads it:
    /// the program point of the last move, in which tool offset changes made since that
    /// move (`T1 M6 G43 H1`, or a G43 before the M6) are not yet counted. So the axes the
    /// next move does not name go to that program point with the new offsets, as rs274
    /// prints it (the machine moves by the offset change), and the move starts where the
    /// machine is. (A real LinuxCNC reads back the machine position instead; Kerf follows
    /// rs274, its reference for LinuxCNC.) An arc cannot start at two points: an arc as that
    /// next move, with the point changed, is an error.
    pub(crate) fn exec(
        &mut self,
        blk: &Block,
        percent: bool,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        self.m6_in_block = false;
        if !percent && self.exec_plain(blk, out) {
            return Ok(());
        }
        let start = out.items.len();
        let readback = self.readback_from;
        self.exec_block(blk, percent, out)?;
        let mut moved = false;
        if let Some(i) = (start..out.items.len()).find(|&i| matches!(out.items[i], Item::Move(_))) {
            moved = true;
            if let (Some((pos, abc)), Item::Move(m)) = (readback, &mut out.items[i]) {
                match &mut m.path {
                    kerf_geom::Path::Line(l) => l.start = pos,
                    kerf_geom::Path::Arc(a) if (a.start - pos).norm() <= 1e-9 => {}
                    kerf_geom::Path::Arc(_) => {
                        return fail(
                            blk.first_col,
                            "an arc right after a tool change that changed the tool offset is not supported (LinuxCNC reads the position back there; program a straight move first)",
                        );
                    }
                }
                if let Some((s, _)) = &mut m.abc_deg {
                    *s = abc;
                }
            }
        }
        if moved {
            self.readback_from = None;
            self.tool_offset_at_move = self.tool_offset;
        }
        if self.m6_in_block && !moved {
            let delta: PerAxis<f64> =
                std::array::from_fn(|i| self.tool_offset[i] - self.tool_offset_at_move[i]);
            if delta.iter().any(|&d| d != 0.0) {
                if self.readback_from.is_none() {
                    self.readback_from = Some((self.pos, self.abc));
                }
                for i in 0..3 {
                    self.pos[i] += delta[i];
                    self.abc[i] += delta[i + 3];
                }
                // Seen from the machine, the offsets are now in effect from this point.
                self.tool_offset_at_move = self.tool_offset;
            }
        }
        Ok(())
    }

    /// The stages of one block, in execution order. A stage that ends the block (a
    /// program header, a blank form, a tool definition, a polar origin) returns early.
    fn exec_block(
        &mut self,
        blk: &Block,
        percent: bool,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if percent && self.dialect == Dialect::Heidenhain {
            return self.program_header(blk);
        }
        if blk.ng == 0 && blk.nm == 0 && blk.present == 0 {
            return Ok(());
        }
        let d = self.dialect;
        self.cycles.block_plane = self.plane;
        self.comp_begin_block(out);

        let mut slots: Slots = [None; N_GROUPS];
        self.g_slots(blk, &mut slots)?;
        if matches!(slots[0], Some((G::BlankForm, _))) {
            return blank_form(blk);
        }
        let mut m = MCodes::NONE;
        self.m_codes(blk, &mut m)?;

        // LinuxCNC sets the modes after F, S, T, the M codes and the dwell (its order of
        // execution: `G20 F40` is 40 mm/min); the other controls read every value of the
        // block in its new unit.
        let linuxcnc = d == Dialect::LinuxCnc;
        if !linuxcnc {
            self.apply_modes(&slots, blk)?;
        }
        let dwell = self.dwell_of(blk, &slots)?;
        self.exec_feed(blk, &slots, dwell.word)?;
        // Spindle, tool and coolant events run before the motion of the block. (The
        // stages below are only called when the block holds what they act on: each
        // does nothing otherwise, and a plain move should not pay for the calls.)
        self.exec_spindle_speed(blk, dwell.word, out)?;
        if blk.has(KT) {
            self.exec_tool_call(blk, &slots, out)?;
        }
        // LinuxCNC: the I/O codes M62–M68 after T, before M6.
        if m.io.is_some() {
            self.exec_io(blk, &m, out)?;
        }
        if blk.nm > 0 {
            self.exec_m_before_motion(blk, &m, out)?;
        }

        // The dwell runs after the spindle and coolant events and before the motion (the
        // LinuxCNC order of execution); a G4 without a time word still stops the motion.
        if let Some(seconds) = dwell.seconds {
            out.event(EventCode::G4, Some(seconds));
        }
        if linuxcnc {
            self.apply_modes(&slots, blk)?;
        }

        // Heidenhain G99: tool definition (T number, L length, R radius).
        if d == Dialect::Heidenhain && slots[0].is_some_and(|(g, _)| g == G::ToolDef) {
            self.define_tool(blk)?;
            return self.finish_block(blk, &m.post, out);
        }
        if d == Dialect::Heidenhain && blk.has(KL) {
            return fail(blk.col(KL), "L word with no G99 to use it");
        }

        // Tool offset words that Kerf does not apply: refused where they would act.
        self.check_tool_offset_words(blk, slots[6])?;
        self.exec_cutter_comp(blk, slots[6], out)?;

        // LinuxCNC: one G code of the block may use the axis words.
        let axis_g0 = slots[0]
            .filter(|&(g, _)| matches!(g, G::G92Set | G::LocalOffset | G::SetData | G::Home(_)));
        let motion_in_block = matches!(slots[1], Some((G::Motion(_), _)));
        if d == Dialect::LinuxCnc
            && motion_in_block
            && let Some((_, col)) = axis_g0
        {
            return fail(col, "Cannot use two g codes that both use axis values");
        }

        let mut consumed_axes = false;
        if slots[7].is_some() || blk.has(KH) {
            consumed_axes = self.exec_tool_length_code(blk, slots[7], motion_in_block)?;
        }
        if slots[0].is_some() {
            consumed_axes |= self.exec_axis_code(blk, slots[0], out)?;
            consumed_axes |= self.exec_pole(blk, slots[0])?;
        }
        if let Some((_, col)) = slots[0].filter(|&(g, _)| g == G::PolarOrigin) {
            self.exec_polar_origin(blk, col)?;
            return self.finish_block(blk, &m.post, out);
        }
        if d == Dialect::Heidenhain && blk.any(&IJK) {
            self.set_heidenhain_cc(blk)?;
        }

        self.exec_motion(blk, &slots, &m, dwell.col.is_some(), consumed_axes, out)?;
        self.finish_block(blk, &m.post, out)?;
        self.comp_end_block(out)
    }

    /// Heidenhain: `%NAME G71 *` opens the program and names its unit; the same line at
    /// the end closes it.
    fn program_header(&mut self, blk: &Block) -> Result<(), BlockError> {
        if self.header_seen {
            self.done = true;
            return Ok(());
        }
        self.header_seen = true;
        for &(code, col) in &blk.gs[..blk.ng] {
            match code {
                700 => self.inch = true,
                710 => self.inch = false,
                _ => return fail(col, "only G70 or G71 may follow the program name"),
            }
        }
        self.feed_inch = self.inch;
        Ok(())
    }

    /// Classifies the G codes of a block and checks the modal groups. Each group holds at
    /// most one code per block, so the block's codes are kept in one slot per group.
    /// `slots` comes in empty and is filled in place (a returned array is copied).
    fn g_slots(&self, blk: &Block, slots: &mut Slots) -> Result<(), BlockError> {
        let d = self.dialect;
        for &(code, col) in &blk.gs[..blk.ng] {
            let g = classify_g(d, code).ok_or_else(|| BlockError {
                col,
                message: format!("unknown G code {}", g_name(code)),
            })?;
            if let G::Unsupported(msg) = g {
                return fail(col, msg);
            }
            if g == G::NoOp {
                continue;
            }
            let grp = group(g);
            let heidenhain_distance = d == Dialect::Heidenhain && grp == GROUP_DISTANCE;
            // rs274 takes G80 beside a motion code of group 1 (`G80 G0 X5`): the motion.
            let g80_with_motion = d == Dialect::LinuxCnc
                && grp == 1
                && matches!(
                    (slots[1], g),
                    (Some((G::NoMotion, _)), G::Motion(_)) | (Some((G::Motion(_), _)), G::NoMotion)
                );
            if g80_with_motion {
                if g != G::NoMotion {
                    slots[1] = Some((g, col));
                }
                continue;
            }
            if slots[grp].is_some() && !heidenhain_distance {
                return fail(col, "two G codes used from same modal group");
            }
            slots[grp] = Some((g, col));
        }
        Ok(())
    }

    /// Units, then the modal G codes of distance, arc distance, plane, path control and
    /// coordinate system of a block.
    pub(super) fn apply_modes(
        &mut self,
        slots: &[Option<(G, u32)>; N_GROUPS],
        blk: &Block,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        // Units first: every value in the block is read in the new unit.
        if let Some((G::Units { inch, feed_too }, _)) = slots[3] {
            self.inch = inch;
            // Sinumerik G70/G71 leave F in the basic unit of the control (mm); only
            // G700/G710 make F follow the geometry unit.
            self.feed_inch = feed_too && inch;
        }
        // Each group's slot is read directly (a plain move has none of them). Heidenhain
        // may repeat G90/G91 in a block; the slot holds the last one, which stays modal.
        if let Some((G::Plane(p), col)) = slots[2]
            && p != self.plane
        {
            self.comp_refuse(
                col,
                "Cannot change planes with cutter radius compensation on",
            )?;
            self.set_plane(p);
        }
        if let Some((G::Distance { absolute }, _)) = slots[GROUP_DISTANCE] {
            self.absolute = absolute;
        }
        if let Some((G::ArcDistance { absolute }, _)) = slots[5] {
            self.arc_absolute = absolute;
        }
        if let Some((G::CoordSystem(cs), col)) = slots[8] {
            self.comp_refuse(
                col,
                "Cannot change coordinate systems with cutter radius compensation on",
            )?;
            self.coord_system = cs;
            if let Some(i) = cs {
                self.params.set(params::COORD_SYSTEM, i as f64 + 1.0);
            }
            self.update_origin();
        }
        if let Some((G::Retract { r_plane }, _)) = slots[13] {
            self.retract_r = r_plane;
        }
        if let Some((G::Corner { exact }, _)) = slots[9] {
            self.corner = if exact {
                CornerMode::ExactStop
            } else if d == Dialect::LinuxCnc {
                self.g64_corner(blk)?
            } else {
                CornerMode::Blend {
                    tolerance_mm: None,
                    naive_cam_mm: None,
                }
            };
        }
        Ok(())
    }

    /// A plane change; it forgets the Sinumerik polar values and the Fagor polar origin,
    /// as their manuals say.
    pub(super) fn set_plane(&mut self, p: Plane) {
        self.plane = p;
        self.rp_mm = None;
        self.ap_deg = None;
        self.polar_origin = None;
        self.polar_last = None;
    }

    /// Feed mode (LinuxCNC), then feed. The F of a Sinumerik or Heidenhain dwell block
    /// (`dwell_word`) is the dwell, not a feed.
    fn exec_feed(
        &mut self,
        blk: &Block,
        slots: &Slots,
        dwell_word: Option<u8>,
    ) -> Result<(), BlockError> {
        let linuxcnc = self.dialect == Dialect::LinuxCnc;
        if let Some((G::FeedMode(m), _)) = slots[11] {
            self.set_feed_mode(m);
        }
        if let Some(f) = blk.get(KF).filter(|_| dwell_word != Some(KF)) {
            if f < 0.0 {
                if linuxcnc {
                    return fail(blk.col(KF), "Negative F word used");
                }
                return fail(blk.col(KF), "negative F word");
            }
            if linuxcnc {
                self.set_feed_word(f);
            } else {
                let s = if self.feed_inch { MM_PER_INCH } else { 1.0 };
                self.feed_mm_min = Some(f * s);
            }
        }
        Ok(())
    }

    /// The spindle speed S (unless it is the Sinumerik dwell in revolutions).
    fn exec_spindle_speed(
        &mut self,
        blk: &Block,
        dwell_word: Option<u8>,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if let Some(s) = blk.get(KS).filter(|_| dwell_word != Some(KS)) {
            if s < 0.0 {
                return fail(blk.col(KS), "negative spindle speed");
            }
            self.spindle_rpm = Some(s);
            out.event(EventCode::S, Some(s));
        }
        Ok(())
    }

    /// G52/G92 family, G10, G28/G30 and their stored positions (LinuxCNC order of
    /// execution: after the tool length offset and the coordinate system selection,
    /// before the motion). Returns whether the code used the block's axis words.
    fn exec_axis_code(
        &mut self,
        blk: &Block,
        slot0: Option<(G, u32)>,
        out: &mut Out<'_>,
    ) -> Result<bool, BlockError> {
        let d = self.dialect;
        let mut consumed_axes = false;
        if let Some((g, col)) = slot0 {
            if d == Dialect::LinuxCnc
                && matches!(
                    g,
                    G::G92Set | G::G92Reset | G::G92Suspend | G::G92Restore | G::LocalOffset
                )
            {
                self.comp_refuse(col, "Cannot change axis offsets with cutter radius comp")?;
            }
            match g {
                G::G92Set | G::G92Reset | G::G92Suspend | G::G92Restore | G::LocalOffset => {
                    self.exec_g92(blk, g, col)?;
                    consumed_axes = true;
                }
                G::SetData => {
                    self.exec_g10(blk, col)?;
                    consumed_axes = true;
                }
                G::HomeSet(g30) => {
                    if let Some(k) = blk.first_of(&[KX, KY, KZ, KA, KB, KC]) {
                        return fail(
                            blk.col(k),
                            "Cannot use axis values without a g code that uses them",
                        );
                    }
                    self.store_home(g30);
                }
                G::Home(g30) => {
                    self.exec_home(blk, g30, col, out)?;
                    consumed_axes = true;
                }
                _ => {}
            }
        }
        Ok(consumed_axes)
    }

    /// Poles: the Sinumerik pole (G110–G112, which uses the axis words: returns `true`)
    /// and the Heidenhain pole at the current point (G29).
    fn exec_pole(&mut self, blk: &Block, slot0: Option<(G, u32)>) -> Result<bool, BlockError> {
        let mut consumed_axes = false;
        if let Some((G::Pole(r), col)) = slot0 {
            self.set_sinumerik_pole(blk, r, col)?;
            consumed_axes = true;
        }
        if slot0.is_some_and(|(g, _)| g == G::PoleFromLast) {
            self.cc = Some(self.pos);
            self.polar_last = None;
        }
        Ok(consumed_axes)
    }

    /// The Fagor polar origin (G30): a block of its own, without axis words.
    fn exec_polar_origin(&mut self, blk: &Block, col: u32) -> Result<(), BlockError> {
        if let Some(k) = blk.first_of(&[KX, KY, KZ, KA, KB, KC, KR, KQ]) {
            return fail(
                blk.col(k),
                format!("{} word with G30 (polar origin)", key_name(k)),
            );
        }
        self.set_fagor_origin(blk, col)
    }

    /// The motion of the block: the motion mode (group 1), the check of the words no code
    /// of the block uses, then the canned cycle or the move (none when the axis words
    /// belonged to another code, or in a dwell block outside LinuxCNC).
    fn exec_motion(
        &mut self,
        blk: &Block,
        slots: &Slots,
        mc: &MCodes,
        dwell: bool,
        consumed_axes: bool,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        let motion_g = slots[1];
        if d == Dialect::LinuxCnc {
            self.cycle_motion_code(blk, motion_g)?;
        }
        match motion_g {
            Some((G::Motion(m), _)) => self.motion = Some(m),
            Some((G::NoMotion, _)) => self.motion = None,
            _ => {}
        }
        self.check_unused_words(blk, slots, mc, dwell, consumed_axes)?;
        let machine = slots[0].filter(|&(g, _)| g == G::MachineCoords);
        let exact_once = slots[10].is_some();
        let abs_centre_once = slots[12].is_some();
        // A dwell block holds no motion words (checked by `dwell_of`), except in LinuxCNC,
        // whose motion then runs after the dwell.
        let motion_after_dwell = d == Dialect::LinuxCnc && blk.any(&LINUXCNC_MOTION_WORDS);
        if let (Some(Motion::Cycle(kind)), false) = (self.motion, consumed_axes) {
            let explicit = motion_g.map(|(_, c)| c);
            if let Some((_, col)) = machine {
                return fail(col, "must use G0 or G1 with G53");
            }
            self.cycle(blk, out, kind, explicit)?;
        } else if !consumed_axes && (!dwell || motion_after_dwell) {
            let motion_col = motion_g.map_or(blk.first_col, |(_, c)| c);
            self.motion(
                blk,
                out,
                motion_col,
                machine.map(|(_, c)| c),
                exact_once,
                abs_centre_once,
            )?;
        }
        Ok(())
    }
}

/// Heidenhain G30/G31 describe the blank for the control's graphics: no motion. Anything
/// else in the block would be dropped: an error instead.
fn blank_form(blk: &Block) -> Result<(), BlockError> {
    if let Some(&(_, col)) = blk.ms[..blk.nm].first() {
        return fail(col, "a blank form block (G30/G31) holds no M codes");
    }
    if let Some(k) = blk.first_of(&[KF, KS, KT]) {
        return fail(
            blk.col(k),
            format!("a blank form block (G30/G31) holds no {} word", key_name(k)),
        );
    }
    Ok(())
}
