//! The compensated moves: each programmed move while compensation is on becomes the
//! tool-centre moves LinuxCNC computes (corners, entry and exit, arcs), held until the
//! next move decides the corner.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_geom::{Move, Path, Vec3};

use super::*;
use crate::arc;
use crate::interp::{BlockError, Out, State, fail};
use crate::{Item, codes::Comp};

/// What every step of one compensated move reads, fixed when the move starts: the
/// plane's axes, the side and radius of compensation, the current point and the
/// block's column for errors.
#[derive(Clone, Copy)]
struct Frame {
    /// The plane's first axis.
    u: usize,
    /// The plane's second axis.
    v: usize,
    /// The axis normal to the plane.
    w: usize,
    /// Compensation to the left of the path (G41).
    left: bool,
    /// The tool radius in mm.
    r: f64,
    /// The current (tool-centre) point.
    cur: Vec3,
    /// The current point in the plane.
    c: (f64, f64),
    /// The block's column, for errors.
    col: u32,
}

/// A programmed arc as the compensation of an arc move sees it, in the plane.
#[derive(Clone, Copy)]
struct ArcTarget {
    /// The programmed end in the plane.
    pe: (f64, f64),
    /// The programmed end along the plane's normal.
    pz: f64,
    /// The centre in the plane.
    center: (f64, f64),
    /// Signed number of turns: positive counter-clockwise.
    turn: i32,
    /// Whether the arc turns counter-clockwise.
    ccw: bool,
    /// Whether the tool is on the inside of the arc.
    inside: bool,
    /// The programmed arc's radius.
    arc_radius: f64,
}

impl State {
    /// A programmed move (its path from the programmed point, or from the current point
    /// for the entry move) while compensation is active: computes and holds the
    /// compensated moves.
    pub(in crate::interp) fn comp_move(
        &mut self,
        mv: Move,
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
        let f = Frame {
            u,
            v,
            w,
            left,
            r,
            cur,
            c,
            col,
        };
        match mv.path {
            Path::Line(line) => {
                let p = (line.end[u], line.end[v]);
                let pz = line.end[w];
                if self.crc.first {
                    self.comp_line_entry(f, &mv, p, pz, out)?;
                } else {
                    self.comp_line_next(f, mv, p, pz, out)?;
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
                let g = ArcTarget {
                    pe,
                    pz,
                    center,
                    turn,
                    ccw,
                    inside,
                    arc_radius,
                };
                if self.crc.first {
                    self.comp_arc_entry(f, g, mv, out)?;
                } else {
                    self.comp_arc_next(f, g, mv, out)?;
                }
                self.crc.programmed = a.end;
            }
        }
        self.pos = self.crc.tip;
        Ok(())
    }

    /// The entry move as a line to the programmed point `p` (`pz` along the normal):
    /// a line from the current point to one tool radius beside `p`, square to the move.
    fn comp_line_entry(
        &mut self,
        f: Frame,
        mv: &Move,
        p: (f64, f64),
        pz: f64,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Frame {
            left, r, c, col, ..
        } = f;
        let dist = arc::len2(p.0 - c.0, p.1 - c.1);
        if not_greater_than_radius(dist, r) {
            return fail(
                col,
                "Length of cutter compensation entry move is not greater than the tool radius",
            );
        }
        let alpha = angle((p.0 - c.0, p.1 - c.1)) + if left { FRAC_PI_2 } else { -FRAC_PI_2 };
        let e = (p.0 + r * alpha.cos(), p.1 + r * alpha.sin());
        self.crc.endpoint = Some(c);
        let end = self.point(e, pz);
        self.hold_line(mv, end, (alpha.cos(), alpha.sin()), out)?;
        self.crc.first = false;
        Ok(())
    }

    /// A line to the programmed point `p` (`pz` along the normal) after the entry move:
    /// decides the corner with the previous move (a corner arc or rapid outside, the
    /// previous move shortened inside) and holds the offset line.
    fn comp_line_next(
        &mut self,
        f: Frame,
        mut mv: Move,
        p: (f64, f64),
        pz: f64,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Frame {
            u,
            v,
            left,
            r,
            c,
            col,
            ..
        } = f;
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
                self.comp_line_corner(f, &mv, op, mid, out)?;
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
        Ok(())
    }

    /// The outside corner before a line, from the previous move's offset end to `mid`,
    /// one tool radius from the programmed corner `op`: flushes the held moves up to the
    /// current point and holds a rapid line (for a rapid) or an arc about `op`.
    fn comp_line_corner(
        &mut self,
        f: Frame,
        mv: &Move,
        op: (f64, f64),
        mid: (f64, f64),
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Frame {
            w, left, cur, c, ..
        } = f;
        self.move_endpoint_and_flush(c, out)?;
        let corner_end = self.point(mid, cur[w]);
        if mv.rapid {
            let mut corner = *mv;
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
            let a = arc::make_arc(self.crc.tip, corner_end, op, self.plane, sweep);
            let mut corner = *mv;
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
        Ok(())
    }

    /// The entry move as an arc `g`: an arc from the current point to one tool radius
    /// beside the programmed end, about the centre that makes it tangent there.
    fn comp_arc_entry(
        &mut self,
        f: Frame,
        g: ArcTarget,
        mv: Move,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Frame { r, c, col, .. } = f;
        let ArcTarget {
            pe,
            pz,
            center,
            turn,
            inside,
            ..
        } = g;
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
        )
    }

    /// An arc `g` after the entry move: decides the corner with the previous move (a
    /// corner arc outside, the previous move shortened inside) and holds the offset arc.
    fn comp_arc_next(
        &mut self,
        f: Frame,
        g: ArcTarget,
        mut mv: Move,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Frame {
            u,
            v,
            w,
            left,
            r,
            cur,
            c,
            col,
        } = f;
        let ArcTarget {
            pe,
            pz,
            center,
            turn,
            ccw,
            inside,
            arc_radius,
        } = g;
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
            self.comp_arc_concave(f, g, beta, theta, out)?;
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
        )
    }

    /// The concave corner before the arc `g` (the corner angle `beta`, the previous
    /// move's offset direction `theta`): shortens the previous move, a line or an arc,
    /// to where the tool meets the offset arc.
    fn comp_arc_concave(
        &mut self,
        f: Frame,
        g: ArcTarget,
        beta: f64,
        theta: f64,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let Frame { left, r, col, .. } = f;
        let ArcTarget {
            center,
            ccw,
            inside,
            arc_radius,
            ..
        } = g;
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
                let k = (oldrad * oldrad + cc * cc - newrad * newrad) / (2.0 * oldrad * cc);
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
        Ok(())
    }

    /// The plane point `p` with `w` along the normal, as a machine point.
    pub(super) fn point(&self, p: (f64, f64), w_val: f64) -> Vec3 {
        let (u, v, w) = self.uv_axes();
        let mut q = Vec3::zeros();
        q[u] = p.0;
        q[v] = p.1;
        q[w] = w_val;
        q
    }

    /// LinuxCNC's queue front when it is an arc: the first held move, or with nothing
    /// held the first move of the last released group.
    pub(super) fn front_arc(&self) -> Option<FrontArc> {
        if self.crc.held.is_empty() {
            self.crc.stale_front
        } else {
            self.held_front_arc()
        }
    }

    /// The first held move when it is an arc: centre, end and turn direction.
    pub(super) fn held_front_arc(&self) -> Option<FrontArc> {
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

    pub(super) fn hold_line(
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

/// Whether a length `dist_mm` (an entry move, an inside arc's radius) is not greater than
/// the tool radius `r_mm`, as rs274 refuses it. A tie passes there: LinuxCNC's
/// useful-subroutines.ngc mills a 1/8" hole with a 1/8" end mill (tool radius = arc
/// radius) entered from one radius away, and rs274 accepts it, its unit conversions of the
/// tool diameter leaving the radius a rounding error below. Kerf computes in mm with other
/// roundings, so a tie within 1e-12 of the radius counts as greater.
fn not_greater_than_radius(dist_mm: f64, r_mm: f64) -> bool {
    dist_mm <= r_mm * (1.0 - 1e-12)
}
