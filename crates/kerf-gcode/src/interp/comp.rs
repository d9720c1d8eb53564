//! LinuxCNC cutter radius compensation: G41/G42 (radius from the tool table), G41.1/G42.1
//! (diameter in the block) and G40, computed as LinuxCNC's interpreter computes it.
//!
//! The compensated path is built move by move in plane coordinates (u, v) of the active
//! plane (G17 XY, G18 ZX), as LinuxCNC does:
//!
//! - The first move after G41/G42 (the entry) ends one tool radius from its programmed end
//!   point, on the normal to the entry direction (lines), or on the arc's normal at its end
//!   (arcs, whose centre is moved so that the arc still starts at the current point).
//! - Later moves end one tool radius from their programmed end, on the normal of the
//!   programmed path at that point. At an outside (convex) corner an arc about the
//!   programmed corner joins the two offset paths (a straight traverse for G0); at an
//!   inside (concave) corner the previous move is shortened to the intersection of the two
//!   offset paths.
//! - The last move is held back until the next move shows its corner (LinuxCNC's
//!   interpreter queue). Events that LinuxCNC queues behind it (spindle, coolant, dwell)
//!   stay behind it. The held moves are released by G40, M0, M1, M60, M2, M30 and the end
//!   of the program. After an error nothing more is produced, held moves included (LinuxCNC
//!   does not run them either).

use std::f64::consts::TAU;

use kerf_geom::{Path, Vec3};

use super::{BlockError, Out, State, fail};
use crate::arc::{self, Plane};
use crate::{Item, codes::Comp};

mod codes;
mod moves;

/// LinuxCNC's angle threshold for corners, radians (TOLERANCE_CONCAVE_CORNER).
const SMALL_RAD: f64 = 0.05;
/// LinuxCNC's equality tolerance (TOLERANCE_EQUAL).
const TOLERANCE_EQUAL: f64 = 0.0001;
/// The largest relative difference between the start and end radii of a compensated arc:
/// LinuxCNC starts an arc off its circle by up to r·(1 − cos 0.05) = 0.00125·r at a corner
/// within its tolerance. Beyond that it would cut a spiral.
const SPIRAL_REL: f64 = 0.0015;
/// The most items held back behind a compensated move (events of blocks without motion):
/// a bound on memory whatever the program does.
const MAX_HELD: usize = 100_000;

/// One held-back item and what LinuxCNC keeps to check it when its end point moves.
struct Held {
    item: Item,
    /// Lines: the direction the move was programmed with; the move may not reverse it.
    dir: (f64, f64),
    /// Arcs: the programmed sweep (0 for the arcs inserted at corners, never checked).
    sweep_rad: f64,
    /// Arcs: +1 counter-clockwise, −1 clockwise.
    turn: i32,
}

/// Cutter radius compensation state (LinuxCNC dialect).
pub(crate) struct Crc {
    /// `None` = G40.
    side: Option<Comp>,
    /// Tool radius, mm (0: compensation on but without effect).
    radius_mm: f64,
    /// The next move is the entry move.
    first: bool,
    /// The programmed (uncompensated) end of the last move, machine mm.
    programmed: Vec3,
    /// The compensated tool position after the held moves (where the next one starts).
    tip: Vec3,
    /// The held-back items.
    held: Vec<Held>,
    /// LinuxCNC's queue start point (its `endpoint`), when valid.
    endpoint: Option<(f64, f64)>,
    /// The first output item of the current block not yet ordered behind the held ones.
    mark: usize,
    /// The move after G40 must be straight.
    arc_not_allowed: bool,
    /// During a compensated motion block: the current (compensated) position, while the
    /// block's end point is resolved from the programmed point.
    pub(super) actual: Option<Vec3>,
    /// The column errors of the current move point at.
    col: u32,
    /// After G40: the programmed point, which LinuxCNC takes as the current point until
    /// the next move (that move still starts where the tool is).
    pub(super) exit_ref: Option<Vec3>,
    /// During the move after G40: where the tool is (the move's start).
    pub(super) exit_actual: Option<Vec3>,
    /// The first move of the last released group, when it was an arc. LinuxCNC reads the
    /// front of its (then empty) queue at some corners; the stale entry it finds there is
    /// this one, and it decides which error checks apply.
    stale_front: Option<FrontArc>,
}

impl Crc {
    pub(crate) fn new() -> Self {
        Crc {
            side: None,
            radius_mm: 0.0,
            first: false,
            programmed: Vec3::zeros(),
            tip: Vec3::zeros(),
            held: Vec::new(),
            endpoint: None,
            mark: 0,
            arc_not_allowed: false,
            actual: None,
            col: 1,
            exit_ref: None,
            exit_actual: None,
            stale_front: None,
        }
    }

    /// Compensation is on (G41/G42, any radius).
    pub(crate) fn on(&self) -> bool {
        self.side.is_some()
    }
}

/// The first held move when it is an arc: its centre, its end and its turn (plane
/// coordinates).
type FrontArc = ((f64, f64), (f64, f64), i32);

fn angle(v: (f64, f64)) -> f64 {
    v.1.atan2(v.0)
}

/// LinuxCNC's swept angle from `s` to `e` about `c` for `turn` (±1 per turn).
fn find_turn(s: (f64, f64), c: (f64, f64), turn: i32, e: (f64, f64)) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut a = angle((s.0 - c.0, s.1 - c.1));
    let mut b = angle((e.0 - c.0, e.1 - c.1));
    if turn > 0 {
        if b <= a {
            b += TAU;
        }
        b - a + f64::from(turn - 1) * TAU
    } else {
        if a <= b {
            a += TAU;
        }
        b - a + f64::from(turn + 1) * TAU
    }
}

/// A held item as it is released. LinuxCNC's compensated arcs keep the programmed centre
/// even where the start point is not exactly on their circle (a corner within its 0.05 rad
/// tolerance, an end point moved within 0.01 mm); it then spirals. Kerf's arcs are exact:
/// the centre moves onto the perpendicular bisector of the chord, to the point closest to
/// LinuxCNC's centre (by less than the radius difference), as for programmed arcs.
fn released(h: Held, plane: Plane) -> Item {
    let Item::Move(mut m) = h.item else {
        return h.item;
    };
    let Path::Arc(a) = m.path else {
        return Item::Move(m);
    };
    let (u, v, _) = plane.axes();
    let s = (a.start[u], a.start[v]);
    let e = (a.end[u], a.end[v]);
    let c = (a.center[u], a.center[v]);
    let d = (e.0 - s.0, e.1 - s.1);
    let len = arc::len2(d.0, d.1);
    if len < arc::SAME_POINT_MM {
        return Item::Move(m);
    }
    let n = (-d.1 / len, d.0 / len);
    let mid = ((s.0 + e.0) / 2.0, (s.1 + e.1) / 2.0);
    let k = (c.0 - mid.0) * n.0 + (c.1 - mid.1) * n.1;
    let exact = (mid.0 + k * n.0, mid.1 + k * n.1);
    let turn = if h.turn == 0 {
        if a.sweep_rad >= 0.0 { 1 } else { -1 }
    } else {
        h.turn
    };
    let sweep = find_turn(s, exact, turn, e);
    m.path = Path::Arc(arc::make_arc(a.start, a.end, exact, plane, sweep));
    Item::Move(m)
}

impl State {
    fn uv_axes(&self) -> (usize, usize, usize) {
        self.plane.axes()
    }

    /// Called at the start of every block: output before this point is in order.
    pub(super) fn comp_begin_block(&mut self, out: &Out<'_>) {
        self.crc.mark = out.items.len();
    }

    /// Called at the end of every block: while moves are held, this block's output goes
    /// behind them.
    pub(super) fn comp_end_block(&mut self, out: &mut Out<'_>) -> Result<(), BlockError> {
        self.hold_block_output(out)
    }

    fn hold_block_output(&mut self, out: &mut Out<'_>) -> Result<(), BlockError> {
        if self.crc.held.is_empty() {
            self.crc.mark = out.items.len();
            return Ok(());
        }
        let mark = self.crc.mark.min(out.items.len());
        if self.crc.held.len() + (out.items.len() - mark) > MAX_HELD {
            return fail(
                1,
                format!("more than {MAX_HELD} items held behind a compensated move"),
            );
        }
        for item in out.items.drain(mark..) {
            self.crc.held.push(Held {
                item,
                dir: (0.0, 0.0),
                sweep_rad: 0.0,
                turn: 0,
            });
        }
        self.crc.mark = out.items.len();
        Ok(())
    }

    /// Releases the held items (LinuxCNC's dequeue).
    pub(super) fn comp_flush(&mut self, out: &mut Out<'_>) {
        self.crc.endpoint = None;
        if self.crc.held.is_empty() {
            return;
        }
        self.crc.stale_front = self.held_front_arc();
        let mark = self.crc.mark.min(out.items.len());
        let plane = self.plane;
        out.items.splice(
            mark..mark,
            self.crc.held.drain(..).map(|h| released(h, plane)),
        );
        self.crc.mark = out.items.len();
    }

    /// End of the program without M2/M30: the held moves run.
    pub(crate) fn comp_finish(&mut self, items: &mut Vec<Item>) {
        let plane = self.plane;
        items.extend(self.crc.held.drain(..).map(|h| released(h, plane)));
    }

    fn hold(&mut self, out: &mut Out<'_>, held: Held) -> Result<(), BlockError> {
        self.hold_block_output(out)?;
        if let Item::Move(m) = &held.item {
            let finite = |p: &Vec3| p.iter().all(|x| x.is_finite());
            let ok = match &m.path {
                Path::Line(l) => finite(&l.start) && finite(&l.end),
                Path::Arc(a) => {
                    finite(&a.start)
                        && finite(&a.end)
                        && finite(&a.center)
                        && a.sweep_rad.is_finite()
                }
            };
            if !ok {
                return fail(self.crc.col, "coordinate out of range");
            }
            if let Path::Arc(a) = &m.path
                && held.turn != 0
            {
                let (u, v, _) = self.uv_axes();
                let r_start = arc::len2(a.start[u] - a.center[u], a.start[v] - a.center[v]);
                let r_end = arc::len2(a.end[u] - a.center[u], a.end[v] - a.center[v]);
                if (r_start - r_end).abs() > SPIRAL_REL * r_end + 1e-6 {
                    return fail(
                        self.crc.col,
                        format!(
                            "cutter compensation: this arc starts {:.4} mm off its circle (after M0, M1 or M60 released the held moves at an inside corner); LinuxCNC cuts a spiral here, which Kerf does not support",
                            (r_start - r_end).abs()
                        ),
                    );
                }
            }
            self.crc.tip = m.path.end();
        }
        self.crc.held.push(held);
        Ok(())
    }

    /// LinuxCNC's move_endpoint_and_flush: every held move now ends at `p` (plane
    /// coordinates), then the held items are released.
    fn move_endpoint_and_flush(
        &mut self,
        p: (f64, f64),
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if self.crc.held.is_empty() {
            return Ok(());
        }
        let (u, v, _) = self.uv_axes();
        let plane = self.plane;
        let endpoint = self.crc.endpoint;
        let col = self.crc.col;
        let inch = self.inch;
        let mut first_move = true;
        for h in self.crc.held.iter_mut() {
            let Item::Move(m) = &mut h.item else {
                continue;
            };
            match &mut m.path {
                Path::Line(l) => {
                    let new = (
                        p.0 - endpoint.map_or(0.0, |e| e.0),
                        p.1 - endpoint.map_or(0.0, |e| e.1),
                    );
                    let dot = h.dir.0 * new.0 + h.dir.1 * new.1;
                    if endpoint.is_some() && dot < 0.0 {
                        let what = if m.rapid {
                            "Straight traverse"
                        } else {
                            "Straight feed"
                        };
                        return fail(
                            col,
                            format!(
                                "{what} in concave corner cannot be reached by the tool without gouging"
                            ),
                        );
                    }
                    if !first_move {
                        l.start[u] = p.0;
                        l.start[v] = p.1;
                    }
                    l.end[u] = p.0;
                    l.end[v] = p.1;
                }
                Path::Arc(a) => {
                    let c = (a.center[u], a.center[v]);
                    let r1 = arc::len2(a.end[u] - c.0, a.end[v] - c.1);
                    let r2 = arc::len2(p.0 - c.0, p.1 - c.1);
                    if (r1 - r2).abs() > 0.01 {
                        return fail(
                            col,
                            format!(
                                "BUG: cutter compensation has generated an invalid arc with mismatched radii r1 {r1:.6} r2 {r2:.6}"
                            ),
                        );
                    }
                    if let Some(e) = endpoint {
                        let l2 = find_turn(e, c, h.turn, p);
                        // LinuxCNC's slack, radians, depends on the program's unit.
                        let slack_rad = if inch { 0.001 } else { 0.0254 };
                        if h.sweep_rad != 0.0 && l2.abs() > h.sweep_rad.abs() + slack_rad {
                            return fail(
                                col,
                                "Arc move in concave corner cannot be reached by the tool without gouging",
                            );
                        }
                    }
                    if !first_move {
                        a.start[u] = p.0;
                        a.start[v] = p.1;
                    }
                    a.end[u] = p.0;
                    a.end[v] = p.1;
                    let s = (a.start[u], a.start[v]);
                    let sweep = find_turn(s, c, h.turn, p);
                    *a = arc::make_arc(a.start, a.end, c, plane, sweep);
                }
            }
            first_move = false;
        }
        self.crc.tip[u] = p.0;
        self.crc.tip[v] = p.1;
        self.comp_flush(out);
        self.crc.endpoint = Some(p);
        Ok(())
    }

    /// G41/G42/G41.1/G42.1/G40 of a LinuxCNC block. `radius_mm` is the signed radius
    /// (negative swaps the side), `None` for G40.
    pub(super) fn comp_set(
        &mut self,
        side: Comp,
        radius_mm: f64,
        col: u32,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if side == Comp::Off {
            if self.comp_active() && !self.crc.first {
                // LinuxCNC releases the held moves with their ends where they are (which
                // still checks them for reversal), then takes the programmed point as the
                // current point: the next move's missing and incremental words refer to it.
                let (u, v, _) = self.uv_axes();
                self.crc.col = col;
                self.move_endpoint_and_flush((self.pos[u], self.pos[v]), out)?;
                self.comp_flush(out);
                self.crc.exit_ref = Some(self.crc.programmed);
                self.crc.arc_not_allowed = true;
            }
            self.comp_flush(out);
            self.crc.side = None;
            self.crc.radius_mm = 0.0;
            self.crc.first = true;
            self.comp = Comp::Off;
            return Ok(());
        }
        if self.crc.on() {
            return fail(col, "Cannot turn cutter radius comp on when on");
        }
        if !matches!(self.plane, Plane::Xy | Plane::Zx) {
            return fail(
                col,
                "Cutter radius compensation allowed only in XY, XZ planes",
            );
        }
        let side = if radius_mm < 0.0 {
            if side == Comp::Left {
                Comp::Right
            } else {
                Comp::Left
            }
        } else {
            side
        };
        self.crc.side = Some(side);
        // The modal state (G40/G41/G42) that M70 saves and the other codes check.
        self.comp = side;
        self.crc.radius_mm = radius_mm.abs();
        self.crc.first = true;
        self.crc.programmed = self.pos;
        self.crc.tip = self.pos;
        Ok(())
    }

    /// Errors for codes LinuxCNC refuses while compensation is on.
    pub(super) fn comp_refuse(&self, col: u32, message: &str) -> Result<(), BlockError> {
        if self.crc.on() {
            return fail(col, message.to_string());
        }
        Ok(())
    }

    /// True when moves are compensated (on, with a radius).
    pub(super) fn comp_active(&self) -> bool {
        self.crc.on() && self.crc.radius_mm > 0.0
    }

    /// The point incremental and missing axis words refer to: the programmed point while
    /// compensating (after the entry move), else the current point.
    pub(super) fn comp_reference(&self) -> Option<Vec3> {
        if self.comp_active() && !self.crc.first {
            Some(self.crc.programmed)
        } else {
            None
        }
    }

    /// Cutter compensation has no part in the next block: it is off, holds nothing back,
    /// and no move after G40 starts away from the programmed point. (The plain-move fast
    /// path, `plain`, runs only then.)
    pub(super) fn comp_idle(&self) -> bool {
        let c = &self.crc;
        c.side.is_none()
            && c.held.is_empty()
            && c.exit_ref.is_none()
            && c.exit_actual.is_none()
            && c.actual.is_none()
    }

    /// The end of a block while nothing is held (`hold_block_output` then only marks the
    /// output as in order).
    pub(super) fn comp_end_idle_block(&mut self, out: &Out<'_>) {
        debug_assert!(self.crc.held.is_empty());
        self.crc.mark = out.items.len();
    }

    /// A move clears the arc-after-G40 rule (`comp_check_arc` without an arc).
    pub(super) fn comp_arc_clear(&mut self) {
        self.crc.arc_not_allowed = false;
    }

    /// Whether an arc now breaks the arc-after-G40 rule (`comp_check_arc`'s error).
    pub(super) fn comp_arc_refused(&self, is_arc: bool) -> bool {
        is_arc && self.crc.arc_not_allowed
    }

    /// Checks the arc-after-G40 rule; a straight move clears it.
    pub(super) fn comp_check_arc(&mut self, is_arc: bool, col: u32) -> Result<(), BlockError> {
        if self.comp_arc_refused(is_arc) {
            return fail(
                col,
                "The move just after exiting cutter compensation mode must be straight, not an arc",
            );
        }
        self.crc.arc_not_allowed = false;
        Ok(())
    }
}
