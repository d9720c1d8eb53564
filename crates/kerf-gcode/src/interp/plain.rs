//! The fast path of a plain LinuxCNC motion block: `G0`/`G1`/`G2`/`G3` (or the modal
//! motion) with X, Y, Z, the arc centre I, J, K and F, nothing else, while nothing modal
//! stands in its way (cutter compensation, a read-back after a tool change, a rotated
//! coordinate system, a feed mode other than G94, a canned cycle).
//!
//! Nearly every block of a CAM program is one of these. The general path
//! (`State::exec_block`) runs a dozen stages for it that find nothing to do, each with its
//! own checks; this one computes the move with the same functions, in the same order, and
//! makes the same changes to the state. It is all or nothing: it changes nothing until
//! the block is known to succeed, and leaves every block it does not finish (one that
//! holds anything else, or that the general path would refuse or treat specially, such as
//! a LinuxCNC whole turn) to the general path, which then runs it from the start as if the
//! fast path had never looked at it. The tests in `tests_plain` run programs both ways.

use kerf_geom::{Line, Move, Path};

use super::motion::path_is_finite;
use super::{Block, FeedMode, MM_PER_INCH, Out, State};
use crate::arc;
use crate::codes::*;
use crate::{Dialect, Item};

/// The words a plain block may hold (G codes and N are not kept as words).
const PLAIN_WORDS: u32 = 1 << KX | 1 << KY | 1 << KZ | 1 << KI | 1 << KJ | 1 << KK | 1 << KF;
const XYZ_WORDS: u32 = 1 << KX | 1 << KY | 1 << KZ;
const IJK_WORDS: u32 = 1 << KI | 1 << KJ | 1 << KK;

#[cfg(test)]
thread_local! {
    /// Tests: every block takes the general path (to compare the two).
    pub(crate) static GENERAL_PATH_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

impl State {
    /// Runs `blk` if it is a plain motion block that succeeds, and returns `true`; returns
    /// `false` without having changed anything otherwise.
    pub(super) fn exec_plain(&mut self, blk: &Block, out: &mut Out<'_>) -> bool {
        #[cfg(test)]
        if GENERAL_PATH_ONLY.with(|g| g.get()) {
            return false;
        }
        if blk.nm != 0 || blk.ng > 1 || blk.present & !PLAIN_WORDS != 0 {
            return false;
        }
        if self.dialect != Dialect::LinuxCnc
            || self.feed_mode != FeedMode::PerMinute
            || self.rotation_deg != 0.0
            || self.readback_from.is_some()
            || self.arc_tail.is_some()
            || !self.comp_idle()
            || !self.abc.iter().all(|x| x.is_finite())
        {
            return false;
        }
        // The motion mode: the block's G0–G3 (group 1: `exec_motion`), else the modal one.
        let block_motion = if blk.ng == 1 {
            Some(match blk.gs[0].0 {
                0 => Motion::Rapid,
                10 => Motion::Linear,
                20 => Motion::Arc(Some(false)),
                30 => Motion::Arc(Some(true)),
                _ => return false,
            })
        } else {
            None
        };
        let (rapid, ccw) = match block_motion.or(self.motion) {
            Some(Motion::Rapid) => (true, None),
            Some(Motion::Linear) => (false, None),
            Some(Motion::Arc(Some(ccw))) => (false, Some(ccw)),
            _ => return false,
        };
        let is_arc = ccw.is_some();
        // F (`exec_feed`, LinuxCNC `set_feed_word` in G94).
        let feed_word = blk.get(KF);
        let feed_mm_min = match feed_word {
            Some(f) if f < 0.0 => return false,
            Some(f) => Some(f * if self.feed_inch { MM_PER_INCH } else { 1.0 }),
            None => self.feed_mm_min,
        };
        // `motion_words`: a block that asks for no move, a centre word without an arc, an
        // arc right after G40.
        let centre_words = blk.present & IJK_WORDS != 0;
        if blk.present & XYZ_WORDS == 0 && !(is_arc && centre_words) {
            return false;
        }
        if (!is_arc && centre_words) || self.comp_arc_refused(is_arc) {
            return false;
        }
        // `move_feed` in G94.
        let feed = if rapid {
            None
        } else {
            match feed_mm_min {
                Some(f) if f > 0.0 => Some(f),
                _ => return false,
            }
        };
        // `move_end` without G53 or polar words.
        let start = self.pos;
        let mut end = start;
        for (i, &k) in XYZ.iter().enumerate() {
            end[i] = self.linear_target(blk, k, i);
        }
        let path = match ccw {
            None => {
                if (end - start).norm() < arc::SAME_POINT_MM {
                    // A zero-length line moves nothing (`motion_inner`).
                    self.commit_plain(block_motion, feed_word);
                    self.polar_last = None;
                    self.comp_end_idle_block(out);
                    return true;
                }
                Path::Line(Line { start, end })
            }
            Some(ccw) => {
                // `arc_path` for a centre-format arc without P, in LinuxCNC.
                let plane = self.plane;
                let (u, v, w) = plane.axes();
                if blk.has(IJK[w]) {
                    return false;
                }
                let has_centre = blk.has(IJK[u]) || blk.has(IJK[v]);
                let Ok(centre) = self.arc_centre(blk, start, false, has_centre, false, 0) else {
                    return false;
                };
                let tol = self.arc_tolerance();
                let Ok(a) = arc::arc_from_center(start, end, centre, plane, ccw, 0, tol) else {
                    return false;
                };
                if arc::end_on_start_ray(&start, &end, centre, plane) {
                    return false;
                }
                Path::Arc(a)
            }
        };
        if !path_is_finite(&path) {
            return false;
        }
        self.commit_plain(block_motion, feed_word);
        out.items.push(Item::Move(Move {
            line: out.line,
            rapid,
            path,
            feed_mm_min: feed,
            abc_deg: if self.abc_used {
                Some((self.abc, self.abc))
            } else {
                None
            },
            corner: self.corner,
        }));
        self.pos = path.end();
        self.polar_last = None;
        if let Some(ccw) = ccw {
            self.last_ccw = Some(ccw);
        }
        // `exec` after a move.
        self.tool_offset_at_move = self.tool_offset;
        self.comp_end_idle_block(out);
        true
    }

    /// The state changes of a plain block before its move, as the general path's stages
    /// make them: the cycle's plane, M19, F, the motion mode, the arc-after-G40 rule.
    fn commit_plain(&mut self, block_motion: Option<Motion>, feed_word: Option<f64>) {
        self.cycles.block_plane = self.plane;
        self.m19_in_block = false;
        if let Some(f) = feed_word {
            self.set_feed_word(f);
        }
        if let Some(m) = block_motion {
            self.cycle_forget();
            self.motion = Some(m);
        }
        self.comp_arc_clear();
    }
}
