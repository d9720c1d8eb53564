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

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_geom::{Move, Path, Vec3};

use super::{BlockError, Out, State, fail};
use crate::arc::{self, Plane};
use crate::{Item, codes::Comp};

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

    /// Checks the arc-after-G40 rule; a straight move clears it.
    pub(super) fn comp_check_arc(&mut self, is_arc: bool, col: u32) -> Result<(), BlockError> {
        if is_arc && self.crc.arc_not_allowed {
            return fail(
                col,
                "The move just after exiting cutter compensation mode must be straight, not an arc",
            );
        }
        self.crc.arc_not_allowed = false;
        Ok(())
    }

    /// A programmed move (its path from the programmed point, or from the current point
    /// for the entry move) while compensation is active: computes and holds the
    /// compensated moves.
    pub(super) fn comp_move(
        &mut self,
        mut mv: Move,
        col: u32,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        self.crc.col = col;
        let (u, v, w) = self.uv_axes();
        let side = self.crc.side.unwrap_or(Comp::Left);
        let left = side == Comp::Left;
        let r = self.crc.radius_mm;
        let cur = self.pos;
        let c = (cur[u], cur[v]);
        match mv.path {
            Path::Line(line) => {
                let p = (line.end[u], line.end[v]);
                let pz = line.end[w];
                if self.crc.first {
                    let dist = arc::len2(p.0 - c.0, p.1 - c.1);
                    if not_greater_than_radius(dist, r) {
                        return fail(
                            col,
                            "Length of cutter compensation entry move is not greater than the tool radius",
                        );
                    }
                    let alpha =
                        angle((p.0 - c.0, p.1 - c.1)) + if left { FRAC_PI_2 } else { -FRAC_PI_2 };
                    let e = (p.0 + r * alpha.cos(), p.1 + r * alpha.sin());
                    self.crc.endpoint = Some(c);
                    let end = self.point(e, pz);
                    self.hold_line(&mv, end, (alpha.cos(), alpha.sin()), out)?;
                    self.crc.first = false;
                } else {
                    let op = (self.crc.programmed[u], self.crc.programmed[v]);
                    if p == op {
                        let end = self.point(c, pz);
                        self.hold_line(&mv, end, (0.0, 0.0), out)?;
                    } else {
                        let mut theta = angle((c.0 - op.0, c.1 - op.1));
                        let mut alpha = angle((p.0 - op.0, p.1 - op.1));
                        let (beta, gamma) = if left {
                            if theta < alpha {
                                theta += TAU;
                            }
                            (theta - alpha - FRAC_PI_2, FRAC_PI_2)
                        } else {
                            if alpha < theta {
                                alpha += TAU;
                            }
                            (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
                        };
                        let n = (alpha + gamma).cos();
                        let m = (alpha + gamma).sin();
                        let e = (p.0 + r * n, p.1 + r * m);
                        let mid = (op.0 + r * n, op.1 + r * m);
                        let front_arc = self.front_arc();
                        let concave = !(-SMALL_RAD..=PI + SMALL_RAD).contains(&beta)
                            || (beta > PI - SMALL_RAD
                                && self
                                    .held_front_arc()
                                    .is_some_and(|(_, _, t)| (t > 0) != left));
                        if !concave && beta > SMALL_RAD {
                            self.move_endpoint_and_flush(c, out)?;
                            let corner_end = self.point(mid, cur[w]);
                            if mv.rapid {
                                let mut corner = mv;
                                corner.path = Path::Line(kerf_geom::Line {
                                    start: self.crc.tip,
                                    end: corner_end,
                                });
                                self.hold(
                                    out,
                                    Held {
                                        item: Item::Move(corner),
                                        dir: (0.0, 0.0),
                                        sweep_rad: 0.0,
                                        turn: 0,
                                    },
                                )?;
                            } else {
                                let turn = if left { -1 } else { 1 };
                                let sweep = find_turn(c, op, turn, mid);
                                let a =
                                    arc::make_arc(self.crc.tip, corner_end, op, self.plane, sweep);
                                let mut corner = mv;
                                corner.path = Path::Arc(a);
                                self.hold(
                                    out,
                                    Held {
                                        item: Item::Move(corner),
                                        dir: (0.0, 0.0),
                                        sweep_rad: 0.0,
                                        turn,
                                    },
                                )?;
                            }
                            self.comp_flush(out);
                            self.crc.endpoint = Some(mid);
                            mv.abc_deg = mv.abc_deg.map(|(_, e)| (e, e));
                        } else if concave {
                            match front_arc {
                                None => {
                                    let half = (beta + PI) / 2.0;
                                    if half == 0.0 {
                                        return fail(
                                            col,
                                            "Zero degree inside corner is invalid for cutter compensation",
                                        );
                                    }
                                    let retreat = r / half.tan();
                                    let q = (
                                        c.0 + retreat * (theta + gamma).cos(),
                                        c.1 + retreat * (theta + gamma).sin(),
                                    );
                                    self.move_endpoint_and_flush(q, out)?;
                                }
                                Some((pc, pe, pturn)) => {
                                    let oldrad = arc::len2(pe.0 - pc.0, pe.1 - pc.1);
                                    let base = angle((p.0 - op.0, p.1 - op.1));
                                    let th = if pturn > 0 {
                                        base + FRAC_PI_2
                                    } else {
                                        base - FRAC_PI_2
                                    };
                                    let phi = angle((pc.0 - op.0, pc.1 - op.1));
                                    let inside = (pturn > 0) == left;
                                    let uncomp = if inside { oldrad + r } else { oldrad - r };
                                    let d = uncomp * (th - phi).cos();
                                    let d2 = if inside { d - r } else { d + r };
                                    let l = d2 / oldrad;
                                    if !(-1.0..=1.0).contains(&l) {
                                        return fail(
                                            col,
                                            "Arc to straight motion makes a corner the compensated tool can't fit in without gouging",
                                        );
                                    }
                                    let ang = match (inside, pturn > 0) {
                                        (true, true) | (false, false) => -l.acos() + th + PI,
                                        _ => l.acos() + th + PI,
                                    };
                                    let q = (pc.0 + oldrad * ang.cos(), pc.1 + oldrad * ang.sin());
                                    self.move_endpoint_and_flush(q, out)?;
                                }
                            }
                        } else {
                            self.comp_flush(out);
                            self.crc.endpoint = Some(c);
                        }
                        let end = self.point(e, pz);
                        self.hold_line(&mv, end, (p.0 - op.0, p.1 - op.1), out)?;
                    }
                }
                self.crc.programmed = line.end;
            }
            Path::Arc(a) => {
                let pe = (a.end[u], a.end[v]);
                let pz = a.end[w];
                let center = (a.center[u], a.center[v]);
                let turns = ((a.sweep_rad.abs() / TAU) - 1e-9).ceil().max(1.0) as i32;
                let turn = if a.sweep_rad > 0.0 { turns } else { -turns };
                let ccw = turn > 0;
                let inside = ccw == left;
                let arc_radius = arc::len2(center.0 - pe.0, center.1 - pe.1);
                if self.crc.first {
                    if not_greater_than_radius(arc::len2(pe.0 - c.0, pe.1 - c.1), r) {
                        return fail(
                            col,
                            "Radius of cutter compensation entry arc is not greater than the tool radius",
                        );
                    }
                    let start_radius = arc::len2(center.0 - c.0, center.1 - c.1);
                    if not_greater_than_radius(start_radius, r) && inside {
                        return fail(col, "Tool radius not less than arc radius with comp");
                    }
                    let gamma = if inside {
                        angle((center.0 - pe.0, center.1 - pe.1))
                    } else {
                        angle((pe.0 - center.0, pe.1 - center.1))
                    };
                    let e = (pe.0 + r * gamma.cos(), pe.1 + r * gamma.sin());
                    let b_len = arc::len2(c.0 - e.0, c.1 - e.1) / 2.0;
                    let ab = angle((center.0 - e.0, center.1 - e.1));
                    let a_ang = angle((c.0 - e.0, c.1 - e.1)) - ab;
                    if a_ang.cos().abs() < TOLERANCE_EQUAL {
                        return fail(col, "Tool radius not less than arc radius with comp");
                    }
                    let c_len = b_len / a_ang.cos();
                    let nc = (e.0 + c_len * ab.cos(), e.1 + c_len * ab.sin());
                    self.crc.first = false;
                    let sweep = find_turn(c, nc, turn, e);
                    let end = self.point(e, pz);
                    let start = self.crc.tip;
                    let mut m = mv;
                    m.path = Path::Arc(arc::make_arc(start, end, nc, self.plane, sweep));
                    self.hold(
                        out,
                        Held {
                            item: Item::Move(m),
                            dir: (0.0, 0.0),
                            sweep_rad: sweep,
                            turn,
                        },
                    )?;
                } else {
                    let op = (self.crc.programmed[u], self.crc.programmed[v]);
                    let mut theta = angle((c.0 - op.0, c.1 - op.1));
                    theta = if left {
                        theta - FRAC_PI_2
                    } else {
                        theta + FRAC_PI_2
                    };
                    let mut delta = angle((center.0 - op.0, center.1 - op.1));
                    let alpha = if ccw {
                        delta - FRAC_PI_2
                    } else {
                        delta + FRAC_PI_2
                    };
                    let mut beta = if left { theta - alpha } else { alpha - theta };
                    if beta > 1.5 * PI {
                        beta -= TAU;
                    } else if beta < -FRAC_PI_2 {
                        beta += TAU;
                    }
                    let gamma = if inside {
                        if not_greater_than_radius(arc_radius, r) {
                            return fail(col, "Tool radius not less than arc radius with comp");
                        }
                        angle((center.0 - pe.0, center.1 - pe.1))
                    } else {
                        delta += PI;
                        angle((pe.0 - center.0, pe.1 - center.1))
                    };
                    let e = (pe.0 + r * gamma.cos(), pe.1 + r * gamma.sin());
                    let programmed_sweep = find_turn(op, center, turn, pe);
                    if !(-SMALL_RAD..=PI + SMALL_RAD).contains(&beta)
                        || ((beta - PI).abs() < SMALL_RAD && !inside)
                    {
                        match self.front_arc() {
                            None => {
                                let cy = arc_radius * (beta - FRAC_PI_2).sin();
                                let (dist, ang) = if inside {
                                    let dist = arc_radius - r;
                                    let l = (cy + r) / dist;
                                    if !(-1.0..=1.0).contains(&l) {
                                        return fail(
                                            col,
                                            "Arc move in concave corner cannot be reached by the tool without gouging",
                                        );
                                    }
                                    (
                                        dist,
                                        if ccw {
                                            theta + l.asin()
                                        } else {
                                            theta - l.asin()
                                        },
                                    )
                                } else {
                                    let dist = arc_radius + r;
                                    let l = (cy - r) / dist;
                                    if !(-1.0..=1.0).contains(&l) {
                                        return fail(
                                            col,
                                            "Arc move in concave corner cannot be reached by the tool without gouging",
                                        );
                                    }
                                    (
                                        dist,
                                        if ccw {
                                            theta + PI - l.asin()
                                        } else {
                                            theta + PI + l.asin()
                                        },
                                    )
                                };
                                let q = (center.0 + dist * ang.cos(), center.1 + dist * ang.sin());
                                self.move_endpoint_and_flush(q, out)?;
                            }
                            Some((pc, pend, pturn)) => {
                                let oldrad = arc::len2(pend.0 - pc.0, pend.1 - pc.1);
                                let newrad = if inside {
                                    arc_radius - r
                                } else {
                                    arc_radius + r
                                };
                                let cc = arc::len2(pc.0 - center.0, pc.1 - center.1);
                                if oldrad == 0.0 || cc == 0.0 {
                                    return fail(
                                        col,
                                        "Arc to arc motion is invalid because the arcs have the same center",
                                    );
                                }
                                let k = (oldrad * oldrad + cc * cc - newrad * newrad)
                                    / (2.0 * oldrad * cc);
                                if !(-1.0..=1.0).contains(&k) {
                                    return fail(
                                        col,
                                        "Arc to arc motion makes a corner the compensated tool can't fit in without gouging",
                                    );
                                }
                                let pullback = k.acos();
                                let cc_dir = angle((center.0 - pc.0, center.1 - pc.1));
                                let prev_inside = (pturn > 0) == left;
                                let dir = if prev_inside == ccw {
                                    cc_dir + pullback
                                } else {
                                    cc_dir - pullback
                                };
                                let q = (pc.0 + oldrad * dir.cos(), pc.1 + oldrad * dir.sin());
                                self.move_endpoint_and_flush(q, out)?;
                            }
                        }
                    } else if beta > SMALL_RAD {
                        let mid = (op.0 + r * delta.cos(), op.1 + r * delta.sin());
                        self.comp_flush(out);
                        let cturn = if left { -1 } else { 1 };
                        let sweep = find_turn(c, op, cturn, mid);
                        let corner_end = self.point(mid, cur[w]);
                        let mut corner = mv;
                        corner.path = Path::Arc(arc::make_arc(
                            self.crc.tip,
                            corner_end,
                            op,
                            self.plane,
                            sweep,
                        ));
                        self.hold(
                            out,
                            Held {
                                item: Item::Move(corner),
                                dir: (0.0, 0.0),
                                sweep_rad: 0.0,
                                turn: cturn,
                            },
                        )?;
                        self.comp_flush(out);
                        self.crc.endpoint = Some(mid);
                        mv.abc_deg = mv.abc_deg.map(|(_, e)| (e, e));
                    } else {
                        self.comp_flush(out);
                        self.crc.endpoint = Some(c);
                    }
                    let start = self.crc.tip;
                    let s = (start[u], start[v]);
                    let sweep = find_turn(s, center, turn, e);
                    let end = self.point(e, pz);
                    let mut m = mv;
                    m.path = Path::Arc(arc::make_arc(start, end, center, self.plane, sweep));
                    self.hold(
                        out,
                        Held {
                            item: Item::Move(m),
                            dir: (0.0, 0.0),
                            sweep_rad: programmed_sweep,
                            turn,
                        },
                    )?;
                }
                self.crc.programmed = a.end;
            }
        }
        self.pos = self.crc.tip;
        Ok(())
    }

    /// The plane point `p` with `w` along the normal, as a machine point.
    fn point(&self, p: (f64, f64), w_val: f64) -> Vec3 {
        let (u, v, w) = self.uv_axes();
        let mut q = Vec3::zeros();
        q[u] = p.0;
        q[v] = p.1;
        q[w] = w_val;
        q
    }

    /// LinuxCNC's queue front when it is an arc: the first held move, or with nothing
    /// held the first move of the last released group.
    fn front_arc(&self) -> Option<FrontArc> {
        if self.crc.held.is_empty() {
            self.crc.stale_front
        } else {
            self.held_front_arc()
        }
    }

    /// The first held move when it is an arc: centre, end and turn direction.
    fn held_front_arc(&self) -> Option<FrontArc> {
        let (u, v, _) = self.uv_axes();
        match self.crc.held.first() {
            Some(Held {
                item:
                    Item::Move(Move {
                        path: Path::Arc(a), ..
                    }),
                turn,
                ..
            }) => Some(((a.center[u], a.center[v]), (a.end[u], a.end[v]), *turn)),
            _ => None,
        }
    }

    fn hold_line(
        &mut self,
        mv: &Move,
        end: Vec3,
        dir: (f64, f64),
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let mut m = *mv;
        m.path = Path::Line(kerf_geom::Line {
            start: self.crc.tip,
            end,
        });
        self.hold(
            out,
            Held {
                item: Item::Move(m),
                dir,
                sweep_rad: 0.0,
                turn: 0,
            },
        )
    }
}

impl State {
    /// The G40/G41/G42/G41.1/G42.1 step of a LinuxCNC block, and the D and L words.
    pub(super) fn linuxcnc_comp(
        &mut self,
        blk: &super::Block,
        slot: Option<(super::G, u32)>,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        use super::G;
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
                        let n = super::tool_number(rounded);
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
    pub(super) fn comp_before_stops(
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

/// Whether a length `dist_mm` (an entry move, an inside arc's radius) is not greater than
/// the tool radius `r_mm`, as rs274 refuses it. A tie passes there: LinuxCNC's
/// useful-subroutines.ngc mills a 1/8" hole with a 1/8" end mill (tool radius = arc
/// radius) entered from one radius away, and rs274 accepts it, its unit conversions of the
/// tool diameter leaving the radius a rounding error below. Kerf computes in mm with other
/// roundings, so a tie within 1e-12 of the radius counts as greater.
fn not_greater_than_radius(dist_mm: f64, r_mm: f64) -> bool {
    dist_mm <= r_mm * (1.0 - 1e-12)
}
