//! LinuxCNC modal state beyond the geometry: feed modes (G93/G94/G95), path control with
//! its tolerances (G61/G61.1/G64 P Q), saving and restoring modal state (M70–M73), the
//! stops and user M codes (M60, M100–M199) and the spindle and coolant state they need.
//!
//! The order of execution inside a block is LinuxCNC's (manual, "G-code Order of
//! Execution"): feed mode, F, S, T, M6, M3/M4/M5, M70–M73, M7/M8/M9, M100–M199, G4, then
//! plane, units, compensation, length offset, coordinate system, path control, distance
//! mode, G92 and the motion, then M0/M1/M2/M30/M60. `State::exec` runs it; this module
//! holds the pieces.

use kerf_geom::{CornerMode, Path};

use super::{Block, BlockError, MM_PER_INCH, Out, State, fail};
use crate::arc::Plane;
use crate::codes::{Comp, KF, KP, KQ, KR};
use crate::{Dialect, Event, EventCode, Item};

/// The feed rate mode (LinuxCNC modal group 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FeedMode {
    /// G94: F is a rate, length units per minute.
    PerMinute,
    /// G93: F is the inverse of the move's time in minutes, given on every feed move.
    InverseTime,
    /// G95: F is length units per spindle revolution.
    PerRev,
}

/// What the spindle does (M3, M4, M5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Spindle {
    Off,
    Cw,
    Ccw,
}

/// The LinuxCNC M codes of this module that are not events of their own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StateOp {
    /// M70: save the modal state at the current call level.
    Save,
    /// M71: invalidate the state saved at the current call level.
    Invalidate,
    /// M72: restore the state saved at the current call level.
    Restore,
    /// M73: save, and restore at the end of the current subroutine.
    SaveAutoRestore,
}

/// The modal state M70 saves and M72 restores: the manual's list (11.6.19) as far as Kerf
/// has the state. Not in it: the motion mode (LinuxCNC does not restore it either).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Snapshot {
    inch: bool,
    feed_inch: bool,
    plane: Plane,
    comp: Comp,
    absolute: bool,
    arc_absolute: bool,
    feed_mode: FeedMode,
    feed_mm_min: Option<f64>,
    feed_mm_rev: Option<f64>,
    coord_system: Option<usize>,
    tool_length_on: bool,
    corner: CornerMode,
    spindle_rpm: Option<f64>,
    spindle: Spindle,
    mist: bool,
    flood: bool,
    /// G98 (`false`) / G99 (`true`).
    retract_r: bool,
}

/// The saved modal state of one call level (the program, or one subroutine call).
#[derive(Clone, Debug, Default)]
pub(crate) struct ModalFrame {
    saved: Option<Box<Snapshot>>,
    /// M73 ran at this level: leaving the subroutine restores `saved`.
    auto_restore: bool,
}

/// How a feed move's feed is given.
#[derive(Clone, Copy, Debug)]
pub(crate) enum MoveFeed {
    /// A rate, mm/min.
    MmMin(f64),
    /// G93: the inverse of the move's time, 1/min.
    InverseTime(f64),
}

/// The slowest inverse-time rate, program units per minute: LinuxCNC never commands less
/// (an F too small for the move's length, or F0, runs at this rate).
const INVERSE_TIME_MIN_RATE: f64 = 0.1;

impl State {
    /// The LinuxCNC M codes this module handles besides the shared ones: M19, M48–M53,
    /// M60 (a stop, as M0), the machine I/O M62–M68 (`io`) and M100–M199 as events,
    /// M70–M73 as state operations. `None` for others.
    pub(super) fn linuxcnc_m(&self, code: u16) -> Option<Result<EventCode, StateOp>> {
        if self.dialect != Dialect::LinuxCnc {
            return None;
        }
        Some(match code {
            19 => Ok(EventCode::M19),
            48 => Ok(EventCode::M48),
            49 => Ok(EventCode::M49),
            50 => Ok(EventCode::M50),
            51 => Ok(EventCode::M51),
            52 => Ok(EventCode::M52),
            53 => Ok(EventCode::M53),
            60 => Ok(EventCode::M60),
            // Machine I/O (`io`): M66 is the digital wait until its words say otherwise.
            62 => Ok(EventCode::M62),
            63 => Ok(EventCode::M63),
            64 => Ok(EventCode::M64),
            65 => Ok(EventCode::M65),
            66 => Ok(EventCode::M66),
            67 => Ok(EventCode::M67),
            68 => Ok(EventCode::M68),
            70 => Err(StateOp::Save),
            71 => Err(StateOp::Invalidate),
            72 => Err(StateOp::Restore),
            73 => Err(StateOp::SaveAutoRestore),
            100..=199 => Ok(EventCode::User((code - 100) as u8)),
            _ => return None,
        })
    }

    /// The LinuxCNC M codes that Kerf refuses, with the reason: it does not take
    /// Fanuc-style subprograms (M98/M99).
    pub(super) fn linuxcnc_m_refusal(&self, code: u16) -> Option<&'static str> {
        if self.dialect != Dialect::LinuxCnc {
            return None;
        }
        linuxcnc_m_refusal_of(code)
    }

    /// Checks the words of LinuxCNC M19 as rs274 does: R from 0 to 360 degrees, Q above
    /// zero, P 0, 1 or 2.
    pub(super) fn check_m19(blk: &Block) -> Result<(), BlockError> {
        if let Some(r) = blk.get(KR)
            && !(0.0..=360.0).contains(&r)
        {
            return Err(BlockError {
                col: blk.col(KR),
                message: "R value must be within 0..360 with M19".into(),
            });
        }
        if let Some(q) = blk.get(KQ)
            && q <= 0.0
        {
            return Err(BlockError {
                col: blk.col(KQ),
                message: "Q word with M19 requires a value > 0".into(),
            });
        }
        if let Some(p) = blk.get(KP)
            && !(p == 0.0 || p == 1.0 || p == 2.0)
        {
            return Err(BlockError {
                col: blk.col(KP),
                message: "P value must be 0,1,or 2 with M19".into(),
            });
        }
        Ok(())
    }

    /// LinuxCNC M19: the orientation event (angle R, direction P, wait Q).
    pub(super) fn orient_event(&self, blk: &Block, out: &mut Out<'_>) {
        out.items.push(Item::Event(Event {
            line: out.line,
            code: EventCode::M19,
            value: Some(blk.get(KR).unwrap_or(0.0)),
            q: blk.get(KQ),
            p: Some(blk.get(KP).unwrap_or(0.0)),
            text: None,
        }));
    }

    /// LinuxCNC M48–M53: M48/M49 without a value, M50–M53 with 1 (enabled: no P word or
    /// a non-zero one) or 0 (`P0`: disabled), as rs274 reads them.
    pub(super) fn override_event(&self, ev: EventCode, blk: &Block, out: &mut Out<'_>) {
        let value = match ev {
            EventCode::M48 | EventCode::M49 => None,
            _ => Some(if blk.get(KP) == Some(0.0) { 0.0 } else { 1.0 }),
        };
        out.event(ev, value);
    }

    /// G93/G94/G95 (LinuxCNC): the mode changes and the feed rate becomes zero, as in
    /// LinuxCNC (rs274 follows SET_FEED_MODE with SET_FEED_RATE(0), even when the mode
    /// does not change): a feed move needs a new F.
    pub(super) fn set_feed_mode(&mut self, mode: FeedMode) {
        self.feed_mode = mode;
        self.feed_mm_min = None;
        self.feed_mm_rev = None;
    }

    /// An F word (LinuxCNC), read in the length unit in force before the block's own
    /// G20/G21 (F comes first in the order of execution).
    pub(super) fn set_feed_word(&mut self, f: f64) {
        let s = if self.feed_inch { MM_PER_INCH } else { 1.0 };
        match self.feed_mode {
            FeedMode::PerMinute => self.feed_mm_min = Some(f * s),
            FeedMode::PerRev => self.feed_mm_rev = Some(f * s),
            // Inverse time: the F of the block itself is read by the move.
            FeedMode::InverseTime => {}
        }
    }

    /// The feed of a feed move of this block, or LinuxCNC's error.
    #[inline]
    pub(super) fn move_feed(
        &self,
        blk: &Block,
        is_arc: bool,
        motion_col: u32,
    ) -> Result<MoveFeed, BlockError> {
        let d = self.dialect;
        let zero = || {
            let message = match (d, is_arc) {
                (Dialect::LinuxCnc, false) => "Cannot do G1 with zero feed rate",
                (Dialect::LinuxCnc, true) => "Cannot make arc with zero feed rate",
                _ => "no feed rate programmed (F)",
            };
            fail(motion_col, message)
        };
        match self.feed_mode {
            FeedMode::PerMinute => match self.feed_mm_min {
                Some(f) if f > 0.0 => Ok(MoveFeed::MmMin(f)),
                _ => zero(),
            },
            FeedMode::InverseTime => match blk.get(KF) {
                Some(f) => Ok(MoveFeed::InverseTime(f)),
                None if is_arc => fail(motion_col, "F word missing with inverse time arc move"),
                None => fail(motion_col, "F word missing with inverse time G1 move"),
            },
            FeedMode::PerRev => {
                let Some(per_rev) = self.feed_mm_rev.filter(|&f| f > 0.0) else {
                    return zero();
                };
                // Kerf has no spindle feedback: the commanded speed stands for the real one.
                match self.spindle_rpm.filter(|&s| s > 0.0) {
                    Some(rpm) => Ok(MoveFeed::MmMin(per_rev * rpm)),
                    None => fail(
                        motion_col,
                        "Cannot feed with zero spindle speed in feed per rev mode",
                    ),
                }
            }
        }
    }

    /// The rate of a feed move, mm/min (degrees/min for a move of rotary axes only).
    /// Inverse time: the move's length times F, where the length is the XYZ path length,
    /// or the rotary axes' distance in degrees for a rotary-only move, as LinuxCNC
    /// measures it; at least 0.1 program units per minute, as in LinuxCNC.
    #[inline]
    pub(super) fn feed_rate_mm_min(
        &self,
        feed: MoveFeed,
        path: &Path,
        abc_start: [f64; 3],
        abc_end: [f64; 3],
    ) -> f64 {
        let f = match feed {
            MoveFeed::MmMin(f) => return f,
            MoveFeed::InverseTime(f) => f,
        };
        let xyz_mm = match path {
            Path::Line(l) => (l.end - l.start).norm(),
            Path::Arc(a) => {
                let axial = (a.end - a.start).dot(&a.axis);
                let planar = a.radius() * a.sweep_rad.abs();
                planar.hypot(axial)
            }
        };
        if xyz_mm > 0.0 {
            (xyz_mm * f).max(INVERSE_TIME_MIN_RATE * self.scale())
        } else {
            let deg = (0..3)
                .map(|i| (abc_end[i] - abc_start[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            (deg * f).max(INVERSE_TIME_MIN_RATE)
        }
    }

    /// G64 (LinuxCNC): `P` the blend tolerance, `Q` the naive-CAM tolerance (`P` when Q
    /// is absent, as LinuxCNC does), both in program units.
    pub(super) fn g64_corner(&self, blk: &Block) -> Result<CornerMode, BlockError> {
        let mm = |k: u8, what: &str| match blk.get(k) {
            Some(v) if v < 0.0 => fail(blk.col(k), format!("negative {what} word with G64")),
            Some(v) => Ok(Some(v * self.scale())),
            None => Ok(None),
        };
        let tolerance_mm = mm(KP, "P")?;
        let naive_cam_mm = mm(KQ, "Q")?.or(tolerance_mm);
        Ok(CornerMode::Blend {
            tolerance_mm,
            naive_cam_mm,
        })
    }

    /// Keeps the spindle and coolant state of an M3/M4/M5/M7/M8/M9 event.
    pub(super) fn note_machine_event(&mut self, ev: EventCode) {
        match ev {
            EventCode::M3 => self.spindle = Spindle::Cw,
            EventCode::M4 => self.spindle = Spindle::Ccw,
            EventCode::M5 => self.spindle = Spindle::Off,
            EventCode::M7 => self.mist = true,
            EventCode::M8 => self.flood = true,
            EventCode::M9 => {
                self.mist = false;
                self.flood = false;
            }
            _ => {}
        }
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            inch: self.inch,
            feed_inch: self.feed_inch,
            plane: self.plane,
            comp: self.comp,
            absolute: self.absolute,
            arc_absolute: self.arc_absolute,
            feed_mode: self.feed_mode,
            feed_mm_min: self.feed_mm_min,
            feed_mm_rev: self.feed_mm_rev,
            coord_system: self.coord_system,
            tool_length_on: self.tool_length_on,
            corner: self.corner,
            spindle_rpm: self.spindle_rpm,
            spindle: self.spindle,
            mist: self.mist,
            flood: self.flood,
            retract_r: self.retract_r,
        }
    }

    /// M70–M73 at the current call level (`col` is the M code).
    pub(super) fn state_op(
        &mut self,
        op: StateOp,
        col: u32,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let snapshot = match op {
            StateOp::Save | StateOp::SaveAutoRestore => Some(Box::new(self.snapshot())),
            _ => None,
        };
        let frame = self.modal_frame();
        match op {
            StateOp::Save => frame.saved = snapshot,
            StateOp::SaveAutoRestore => {
                frame.saved = snapshot;
                frame.auto_restore = true;
            }
            StateOp::Invalidate => {
                frame.saved = None;
                frame.auto_restore = false;
            }
            StateOp::Restore => {
                let Some(saved) = frame.saved.clone() else {
                    return fail(
                        col,
                        "Cannot restore context from invalid stack frame - missing M70/M73?",
                    );
                };
                self.restore(&saved, out);
            }
        }
        Ok(())
    }

    /// The saved state of the current call level (the program level always exists).
    fn modal_frame(&mut self) -> &mut ModalFrame {
        if self.modal_frames.is_empty() {
            self.modal_frames.push(ModalFrame::default());
        }
        let last = self.modal_frames.len() - 1;
        &mut self.modal_frames[last]
    }

    /// A subroutine call begins: a new call level, with nothing saved (for the
    /// subroutines of the language helper: call it at `o<..> call`).
    pub(crate) fn modal_enter_call(&mut self) {
        self.modal_frame();
        self.modal_frames.push(ModalFrame::default());
    }

    /// A subroutine call ends (`endsub` or `return`): when M73 ran in it and M71 did not
    /// invalidate it, the caller's state saved by M73 is restored, with its spindle and
    /// coolant events in `items`; the call level goes away. Call it at `endsub`/`return`.
    pub(crate) fn modal_leave_call(&mut self, items: &mut Vec<Item>, line: u32) {
        if self.modal_frames.len() < 2 {
            return;
        }
        if let Some(frame) = self.modal_frames.pop()
            && frame.auto_restore
            && let Some(saved) = frame.saved
        {
            let mut out = Out { items, line };
            self.restore(&saved, &mut out);
        }
    }

    /// Puts the saved state back: units first (so that the feed is read in the right
    /// unit, as the manual says), then the rest, as rs274 does; spindle events only where
    /// they change, coolant as rs274 restores it (below). Like LinuxCNC, the tool length offset is applied
    /// anew when it was on (the loaded tool's length), and when the restore changes the
    /// feed mode the feed rate is left at zero (rs274 sets the feed mode after the feed).
    fn restore(&mut self, s: &Snapshot, out: &mut Out<'_>) {
        self.inch = s.inch;
        self.feed_inch = s.feed_inch;
        if self.feed_mode != s.feed_mode {
            self.set_feed_mode(s.feed_mode);
        } else {
            self.feed_mm_min = s.feed_mm_min;
            self.feed_mm_rev = s.feed_mm_rev;
        }
        // No S programmed is LinuxCNC's speed 0.
        let saved_rpm = s.spindle_rpm.unwrap_or(0.0);
        if saved_rpm != self.spindle_rpm.unwrap_or(0.0) {
            out.event(EventCode::S, Some(saved_rpm));
        }
        self.spindle_rpm = s.spindle_rpm;
        if s.spindle != self.spindle {
            out.event(
                match s.spindle {
                    Spindle::Off => EventCode::M5,
                    Spindle::Cw => EventCode::M3,
                    Spindle::Ccw => EventCode::M4,
                },
                None,
            );
            self.spindle = s.spindle;
        }
        if s.plane != self.plane {
            self.set_plane(s.plane);
        }
        self.comp = s.comp;
        self.coord_system = s.coord_system;
        self.tool_length_on = s.tool_length_on;
        let offsets = if s.tool_length_on {
            self.tool(self.tool_loaded)
                .map_or([0.0; 6], |t| t.offsets_mm_deg())
        } else {
            [0.0; 6]
        };
        self.set_tool_offsets(offsets);
        self.corner = s.corner;
        self.absolute = s.absolute;
        self.arc_absolute = s.arc_absolute;
        self.retract_r = s.retract_r;
        // Coolant as rs274 restores it: when neither was on, whatever is on goes off (M9);
        // otherwise what was on comes on again, and what was off but is on now stays on.
        if !s.mist && !s.flood {
            if self.mist || self.flood {
                out.event(EventCode::M9, None);
            }
            self.mist = false;
            self.flood = false;
        } else {
            if s.mist && !self.mist {
                out.event(EventCode::M7, None);
                self.mist = true;
            }
            if s.flood && !self.flood {
                out.event(EventCode::M8, None);
                self.flood = true;
            }
        }
    }

    /// A user M code M100–M199: the event, with its P and Q words. LinuxCNC runs the
    /// program file `M1nn` found on its search path and refuses the code without one;
    /// Kerf runs no user programs and hands the code on as an event.
    pub(super) fn user_m_event(&self, n: u8, blk: &Block, out: &mut Out<'_>) {
        out.items.push(Item::Event(Event {
            line: out.line,
            code: EventCode::User(n),
            value: blk.get(KP),
            q: blk.get(KQ),
            p: None,
            text: None,
        }));
    }
}

/// The LinuxCNC M codes that Kerf refuses, with the reason (`State::linuxcnc_m_refusal`).
pub(crate) fn linuxcnc_m_refusal_of(code: u16) -> Option<&'static str> {
    Some(match code {
        98 => {
            "M98 is not supported: Fanuc-style subprograms (M98/M99) are not supported, use o-word subroutines (o<name> call)"
        }
        99 => {
            "M99 is not supported: Fanuc-style subprograms (M98/M99) are not supported, use o-word subroutines (o<name> call)"
        }
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lex::Lexer;
    use crate::{Settings, Vec3};

    /// Runs each line as one block of `state`, returning the items.
    fn run(state: &mut State, lines: &[&str]) -> Vec<Item> {
        let lexer = Lexer::new(Dialect::LinuxCnc);
        let mut words = Vec::new();
        let mut blk = Block::new();
        let mut items = Vec::new();
        for (n, line) in lines.iter().enumerate() {
            let mut pos = 0;
            let found = lexer.next_block(line.as_bytes(), &mut pos, &mut words);
            assert!(matches!(found, Ok(Some(_))), "{line}");
            let mut out = Out {
                items: &mut items,
                line: n as u32 + 1,
            };
            let done = state
                .build_block(&words, &mut blk)
                .and_then(|()| state.exec(&blk, false, &mut out));
            assert!(done.is_ok(), "{line}: {:?}", done.err());
        }
        items
    }

    fn ends(items: &[Item]) -> Vec<(Vec3, Option<f64>)> {
        items
            .iter()
            .filter_map(|i| match i {
                Item::Move(m) => Some((m.path.end(), m.feed_mm_min)),
                Item::Event(_) => None,
            })
            .collect()
    }

    #[test]
    fn m73_in_a_subroutine_restores_at_its_end() {
        // The manual's M73 example: the subroutine switches to G20, G91, F5, S300; after
        // its endsub the caller's G21, G90, F200, S2500 are back.
        let mut s = State::new(Dialect::LinuxCnc, Settings::default());
        run(&mut s, &["G21 G90 F200 S2500"]);
        s.modal_enter_call();
        let inside = run(&mut s, &["M73", "G20 G91 F5 S300", "G1 X1"]);
        assert_eq!(ends(&inside), [(Vec3::new(25.4, 0.0, 0.0), Some(5.0))]);
        let mut restored = Vec::new();
        s.modal_leave_call(&mut restored, 4);
        let speeds: Vec<Option<f64>> = restored
            .iter()
            .filter_map(|i| match i {
                Item::Event(e) if e.code == EventCode::S => Some(e.value),
                _ => None,
            })
            .collect();
        assert_eq!(speeds, [Some(2500.0)]);
        let after = run(&mut s, &["G1 X1"]);
        assert_eq!(ends(&after), [(Vec3::new(1.0, 0.0, 0.0), Some(200.0))]);
    }

    #[test]
    fn m70_in_a_subroutine_is_its_own_and_m71_stops_the_auto_restore() {
        let mut s = State::new(Dialect::LinuxCnc, Settings::default());
        run(&mut s, &["G21 G90 F100", "M70"]);
        s.modal_enter_call();
        // Nothing saved at this level yet: M72 here would fail; M73 then M71 leaves the
        // subroutine's changes in force.
        run(&mut s, &["M73", "G91", "M71"]);
        let mut restored = Vec::new();
        s.modal_leave_call(&mut restored, 5);
        assert!(restored.is_empty());
        let after = run(&mut s, &["G1 X2", "M72", "G1 X5"]);
        // G91 stayed: X+2; the program level's M70 then gives G90 back.
        assert_eq!(
            ends(&after),
            [
                (Vec3::new(2.0, 0.0, 0.0), Some(100.0)),
                (Vec3::new(5.0, 0.0, 0.0), Some(100.0))
            ]
        );
        // Leaving without a call level is harmless.
        s.modal_leave_call(&mut restored, 9);
        assert!(restored.is_empty());
    }
}
