//! One motion block: cutter compensation's programmed point around it, then the end point,
//! feed and path of the move (line, arc or polar) and its output.

use kerf_geom::{CornerMode, Line, Move, Path, Vec3};

use super::modal::MoveFeed;
use super::{Block, BlockError, Out, State, fail};
use crate::arc::{self};
use crate::codes::*;
use crate::lex::{K_AP, K_AT, K_CARET, K_CR, K_RP, K_TURN};
use crate::{Dialect, Item};

impl State {
    /// One motion block. While LinuxCNC cutter compensation is active, the block's end point
    /// is resolved from the programmed point (as LinuxCNC does) and `comp` makes the moves.
    pub(super) fn motion(
        &mut self,
        blk: &Block,
        out: &mut Out<'_>,
        motion_col: u32,
        machine: Option<u32>,
        exact_once: bool,
        abs_centre_once: bool,
    ) -> Result<(), BlockError> {
        if self.dialect != Dialect::LinuxCnc {
            return self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
        }
        if let Some(reference) = self.crc.exit_ref {
            // The move after G40: its words refer to the programmed point (LinuxCNC's
            // current point after G40); it starts where the tool is.
            let actual = self.pos;
            self.pos = reference;
            self.crc.exit_actual = Some(actual);
            let r = self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
            if self.crc.exit_actual.take().is_some() {
                self.pos = actual;
            }
            return r;
        }
        if !self.comp_active() {
            return self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
        }
        let actual = self.pos;
        if let Some(p) = self.comp_reference() {
            self.pos = p;
        }
        self.crc.actual = Some(actual);
        let r = self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
        if self.crc.actual.take().is_some() {
            // No move was made: the position stays the compensated one.
            self.pos = actual;
        }
        r
    }

    #[allow(clippy::too_many_arguments)]
    fn motion_inner(
        &mut self,
        blk: &Block,
        out: &mut Out<'_>,
        motion_col: u32,
        machine: Option<u32>,
        exact_once: bool,
        abs_centre_once: bool,
    ) -> Result<(), BlockError> {
        let Some(MotionWords {
            motion,
            has_polar,
            is_arc,
            has_radius,
        }) = self.motion_words(blk, motion_col, machine)?
        else {
            return Ok(());
        };

        // Feed.
        let rapid = is_rapid(motion);
        let feed = if rapid {
            None
        } else {
            Some(self.move_feed(blk, is_arc, motion_col)?)
        };

        let start = self.pos;
        let abc_end = self.abc_end(blk, machine);
        // End point.
        let (mut end, new_polar) = self.move_end(blk, motion, machine, has_polar, start)?;

        let corner = if exact_once {
            CornerMode::ExactStop
        } else {
            self.corner
        };
        let abc = if self.abc_used {
            Some((self.abc, abc_end))
        } else {
            None
        };

        let path = match motion {
            Motion::Rapid | Motion::Linear | Motion::PolarLine { .. } => {
                // After a tool change's read-back the move starts where the machine is.
                let (start, abc_start) = match (self.crc.exit_actual, self.readback_from) {
                    (Some(p), _) => (p, self.abc),
                    (None, Some((p, abc))) => (p, abc),
                    (None, None) => (start, self.abc),
                };
                if (end - start).norm() < arc::SAME_POINT_MM && abc_end == abc_start {
                    // A zero-length line moves nothing; it is not emitted. (A polar end point
                    // a whole turn round can differ from the start by a rounding error.)
                    self.polar_last = new_polar;
                    return Ok(());
                }
                Path::Line(Line { start, end })
            }
            Motion::Cycle(_) => {
                // Canned cycles are resolved by `State::cycle`, never here.
                return fail(motion_col, "canned cycle outside its resolution");
            }
            Motion::Arc(dir) | Motion::PolarArc(dir) => {
                let ccw = self.arc_direction(dir, motion_col)?;
                match self.arc_path(
                    blk,
                    motion,
                    start,
                    &mut end,
                    ccw,
                    has_polar,
                    has_radius,
                    abs_centre_once,
                    motion_col,
                )? {
                    Some(a) => {
                        self.last_ccw = Some(ccw);
                        Path::Arc(a)
                    }
                    None => {
                        // Rockwell: R with the end point equal to the start is a 0° arc.
                        return Ok(());
                    }
                }
            }
        };
        let finite_path = path_is_finite(&path);
        if !finite_path || !abc_end.iter().all(|x| x.is_finite()) {
            return fail(blk.first_col, "coordinate out of range");
        }
        let feed = match feed {
            Some(MoveFeed::MmMin(f)) => Some(f),
            Some(f) => Some(self.feed_rate_mm_min(f, &path, self.abc, abc_end)),
            None => None,
        };
        let mv = Move {
            line: out.line,
            rapid,
            path: self.path_to_machine(path),
            feed_mm_min: feed,
            abc_deg: abc,
            corner,
        };
        if self.crc.actual.is_some() && self.rotation_deg != 0.0 {
            // Compensation works in the frame of the program; with a rotated coordinate
            // system the frame and the machine differ, which comp does not model.
            return fail(
                motion_col,
                "cutter compensation in a rotated coordinate system (G10 L2 R) is not supported",
            );
        }
        if let Some(actual) = self.crc.actual.take() {
            self.pos = actual;
            self.comp_move(mv, motion_col, out)?;
            self.abc = abc_end;
            self.polar_last = None;
            return Ok(());
        }
        if self.crc.exit_actual.take().is_some() {
            self.crc.exit_ref = None;
        }
        out.items.push(Item::Move(mv));
        self.pos = path.end();
        if let Some(tail) = self.arc_tail.take() {
            // The radial line after LinuxCNC's whole turn (`arc_path`).
            let line = Path::Line(Line {
                start: path.end(),
                end: tail,
            });
            out.items.push(Item::Move(Move {
                line: out.line,
                rapid,
                path: self.path_to_machine(line),
                feed_mm_min: feed,
                abc_deg: abc.map(|_| (abc_end, abc_end)),
                corner,
            }));
            self.pos = tail;
        }
        self.abc = abc_end;
        if !matches!(motion, Motion::PolarArc(_)) {
            self.polar_last = new_polar;
        }
        Ok(())
    }

    /// The motion words of a block in motion mode: `None` when the block makes no move
    /// (no motion mode, or no word that asks for one; its other words checked). Checks the
    /// words no code uses and G53's conditions, as rs274 checks them.
    fn motion_words(
        &mut self,
        blk: &Block,
        motion_col: u32,
        machine: Option<u32>,
    ) -> Result<Option<MotionWords>, BlockError> {
        let d = self.dialect;
        let (u, v, _) = self.plane.axes();
        let has_axes = blk.any(&XYZ) || blk.any(&ABC);
        if blk.any(&ABC) {
            self.abc_used = true;
        }
        let Some(motion) = self.motion else {
            let polar_words: &[u8] = match d {
                Dialect::LinuxCnc => &[K_AT, K_CARET],
                Dialect::Sinumerik => &[K_RP, K_AP],
                Dialect::Heidenhain => &[KR, KH],
                Dialect::Fagor => &[KR, KQ],
                Dialect::Rockwell => &[],
            };
            if has_axes || blk.any(polar_words) {
                let k = blk
                    .first_of(&[KX, KY, KZ, KA, KB, KC])
                    .or(blk.first_of(polar_words))
                    .unwrap_or(KX);
                return fail(
                    blk.col(k),
                    "cannot use axis values without a G code that uses them",
                );
            }
            return self.check_unused(blk, false).map(|()| None);
        };
        let has_polar = match d {
            Dialect::LinuxCnc => blk.has(K_AT) || blk.has(K_CARET),
            Dialect::Sinumerik => blk.has(K_RP) || blk.has(K_AP),
            Dialect::Heidenhain => {
                blk.has(KH)
                    || (blk.has(KR)
                        && matches!(motion, Motion::PolarLine { .. } | Motion::PolarArc(_)))
            }
            Dialect::Fagor => blk.has(KQ) || (blk.has(KR) && !blk.has(XYZ[u]) && !blk.has(XYZ[v])),
            Dialect::Rockwell => false,
        };
        let is_arc = matches!(motion, Motion::Arc(_) | Motion::PolarArc(_));
        let has_centre = blk.any(&IJK) && d != Dialect::Heidenhain;
        let has_radius = match d {
            Dialect::Sinumerik => blk.has(K_CR),
            Dialect::Heidenhain => blk.has(KR) && matches!(motion, Motion::Arc(_)),
            Dialect::Fagor => blk.has(KR) && (blk.has(XYZ[u]) || blk.has(XYZ[v])),
            _ => blk.has(KR),
        };
        let wants_motion = has_axes
            || has_polar
            || (is_arc && (has_centre || blk.has(K_TURN)) && d != Dialect::Heidenhain);
        if !wants_motion {
            return self.check_unused(blk, false).map(|()| None);
        }
        self.check_unused(blk, is_arc)?;
        if d == Dialect::LinuxCnc {
            self.comp_check_arc(is_arc, motion_col)?;
        }

        // G53's conditions come first, as rs274 checks them.
        if let Some(col) = machine {
            if !self.absolute {
                return fail(col, "Cannot use g53 incremental");
            }
            if !matches!(motion, Motion::Rapid | Motion::Linear) {
                return fail(col, "Must use g0 or g1 with g53");
            }
            self.comp_refuse(col, "Cannot use g53 with cutter radius comp")?;
        }
        Ok(Some(MotionWords {
            motion,
            has_polar,
            is_arc,
            has_radius,
        }))
    }

    /// The direction of an arc (`true`: counter-clockwise): the block's, or the last
    /// arc's for Heidenhain G05/G15.
    fn arc_direction(&self, dir: Option<bool>, motion_col: u32) -> Result<bool, BlockError> {
        match dir.or(self.last_ccw) {
            Some(c) => Ok(c),
            None => fail(
                motion_col,
                "no direction of rotation programmed before G05/G15",
            ),
        }
    }

    /// The A, B, C end of a move; with G53 the words are machine values.
    fn abc_end(&self, blk: &Block, machine: Option<u32>) -> [f64; 3] {
        let mut abc_end = self.abc_target(blk);
        if machine.is_some() {
            for (i, &k) in ABC.iter().enumerate() {
                if let Some(v) = blk.get(k) {
                    abc_end[i] = v;
                }
            }
        }
        abc_end
    }

    /// The end point of a move from `start` (frame coordinates) and, for a polar end
    /// point, its radius and angle.
    fn move_end(
        &mut self,
        blk: &Block,
        motion: Motion,
        machine: Option<u32>,
        has_polar: bool,
        start: Vec3,
    ) -> Result<(Vec3, Option<(f64, f64)>), BlockError> {
        let d = self.dialect;
        let (u, v, w) = self.plane.axes();
        let mut end = start;
        let mut new_polar: Option<(f64, f64)> = None;
        if machine.is_some() {
            // Machine coordinates: the named axes go there, the others stay where they
            // are on the machine (under a rotated system too).
            let mut m = self.frame_to_machine(start);
            for (i, &k) in XYZ.iter().enumerate() {
                if let Some(val) = blk.get(k) {
                    m[i] = val * self.scale();
                }
            }
            end = self.machine_to_frame(m);
        } else if has_polar && !matches!(motion, Motion::PolarArc(_)) {
            let (r, a_deg) = self.polar_end(blk, motion)?;
            let pole = self.polar_reference();
            let a = a_deg.to_radians();
            // LinuxCNC polar words always give X and Y; the others work in the active plane.
            let (pu, pv, pw) = if d == Dialect::LinuxCnc {
                (0, 1, 2)
            } else {
                (u, v, w)
            };
            end[pu] = pole[pu] + r * a.cos();
            end[pv] = pole[pv] + r * a.sin();
            end[pw] = self.linear_target(blk, XYZ[pw], pw);
            new_polar = Some((r, a_deg));
        } else {
            for (i, &k) in XYZ.iter().enumerate() {
                end[i] = self.linear_target(blk, k, i);
            }
        }
        Ok((end, new_polar))
    }
}

/// What a motion block's words ask for (see `State::motion_words`).
struct MotionWords {
    motion: Motion,
    /// The end point is given in polar words.
    has_polar: bool,
    is_arc: bool,
    /// The arc is given by its radius.
    has_radius: bool,
}

/// Whether every coordinate of the path is finite.
pub(super) fn path_is_finite(path: &Path) -> bool {
    let finite = |p: &Vec3| p.iter().all(|x| x.is_finite());
    match path {
        Path::Line(l) => finite(&l.start) && finite(&l.end),
        Path::Arc(a) => {
            finite(&a.start) && finite(&a.end) && finite(&a.center) && a.sweep_rad.is_finite()
        }
    }
}

/// Whether the motion mode moves at rapid rate.
fn is_rapid(motion: Motion) -> bool {
    match motion {
        Motion::Rapid => true,
        Motion::PolarLine { rapid } => rapid,
        _ => false,
    }
}
