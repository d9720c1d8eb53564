//! Running a canned cycle block: its words, feed and levels, the holes it drills and the
//! moves and events of each hole, as rs274's convert_cycle computes them.

use kerf_geom::{CornerMode, Line, Move, Path, Vec3};

use super::*;
use crate::interp::modal::MoveFeed;
use crate::interp::{Block, BlockError, FeedMode, Out, State, fail};
use crate::lex::{K_AT, K_CARET};
use crate::{EventCode, Item};

/// The value of a coordinate computed back from machine millimetres, with the rounding
/// error of the conversion removed when it sits that close to a value with at most six
/// decimals (as the program wrote it), so that comparisons with R come out as in rs274,
/// which keeps the programmed value.
fn snap(x: f64) -> f64 {
    let r = (x * 1e6).round() / 1e6;
    if (x - r).abs() <= 1e-12 * x.abs().max(1.0) {
        r
    } else {
        x
    }
}

/// Converts points of a cycle (program coordinates in the plane's axes) to machine mm.
struct Frame {
    u: usize,
    v: usize,
    w: usize,
    scale: f64,
    origin: Vec3,
    /// The current position in program coordinates and in machine mm: a coordinate equal
    /// to the current one maps to the current machine value exactly.
    cur_prog: [f64; 3],
    cur_mm: Vec3,
}

impl Frame {
    fn machine(&self, a: f64, b: f64, c: f64) -> Vec3 {
        let mut p = [0.0; 3];
        p[self.u] = a;
        p[self.v] = b;
        p[self.w] = c;
        let mut m = Vec3::zeros();
        for i in 0..3 {
            m[i] = if p[i] == self.cur_prog[i] {
                self.cur_mm[i]
            } else {
                p[i] * self.scale + self.origin[i]
            };
        }
        m
    }
}

/// What one repeat of a cycle needs.
struct Hole {
    a: f64,
    b: f64,
    r: f64,
    clear: f64,
    bottom: f64,
}

/// Where the holes of a cycle block are, in program coordinates (see
/// `State::cycle_positions`).
struct Positions {
    a: f64,
    b: f64,
    a_inc: f64,
    b_inc: f64,
    r: f64,
    bottom: f64,
    radius_inc: f64,
    theta_inc: f64,
}

/// What every hole of one cycle block shares.
#[derive(Clone, Copy)]
struct Pass {
    kind: CycleKind,
    first_col: u32,
    feed_mm_min: f64,
    p: f64,
    q: f64,
    ijk: [f64; 3],
    /// G87: the level of the back bore's feed move.
    middle: f64,
    /// G73: the retract between pecks.
    delta: f64,
    /// The spindle code that restarts the spindle after a stop in the cycle.
    restart: EventCode,
    /// `out`'s length before the block, for the item cap.
    start_items: usize,
}

/// Steps the hole (`a`, `b`) by `radius_inc` and then `theta_inc` (incremental polar
/// words); `false` when a step is needed at the origin, where it is indeterminate.
fn polar_step(a: &mut f64, b: &mut f64, radius_inc: f64, theta_inc: f64) -> bool {
    for (d_radius, d_theta) in [(radius_inc, 0.0), (0.0, theta_inc)] {
        if d_radius == 0.0 && d_theta == 0.0 {
            continue;
        }
        if *a == 0.0 && *b == 0.0 {
            return false;
        }
        let theta = b.atan2(*a) + d_theta;
        let radius = b.hypot(*a) + d_radius;
        *a = radius * theta.cos();
        *b = radius * theta.sin();
    }
    true
}

impl State {
    /// Runs a block in canned-cycle motion mode `kind`. `explicit` is the column of the
    /// block's cycle code, when the block has one.
    pub(in crate::interp) fn cycle(
        &mut self,
        blk: &Block,
        out: &mut Out<'_>,
        kind: CycleKind,
        explicit: Option<u32>,
    ) -> Result<(), BlockError> {
        let start_items = out.items.len();
        let first_col = explicit.unwrap_or(blk.first_col);
        let Some((l, polar)) = self.cycle_block_words(blk, kind, explicit)? else {
            return Ok(());
        };

        // convert_cycle's checks, in its order.
        let feed_mm_min = self.cycle_feed(blk, first_col)?;
        if self.comp != Comp::Off {
            return fail(
                first_col,
                "Cannot use canned cycles with cutter compensation on",
            );
        }
        let same = self.cycles.last == Some(kind);
        let r_word = match blk.get(KR) {
            Some(r) => r,
            None if same => self.cycles.r,
            None => return fail(first_col, "R clearance plane unspecified in cycle"),
        };
        if l == 0 {
            return fail(blk.col(KL), "Cannot do zero repeats of cycle");
        }

        let (u, v, w) = self.plane.axes();
        let (w_name, plane_name) = match w {
            0 => ("x", "yz"),
            1 => ("y", "xz"),
            _ => ("z", "xy"),
        };
        let bottom_word = match blk.get(XYZ[w]) {
            Some(z) => z,
            None if same => self.cycles.bottom,
            None => {
                return fail(
                    first_col,
                    format!(
                        "{} value unspecified in {plane_name} plane canned cycle",
                        w_name.to_ascii_uppercase()
                    ),
                );
            }
        };
        let frame = self.cycle_frame(u, v, w);
        let cur_prog = frame.cur_prog;
        let current_w = cur_prog[w];
        let initial_level = self.cycles.initial_level.unwrap_or(current_w);
        let mut old_w = initial_level;
        let Positions {
            mut a,
            mut b,
            a_inc,
            b_inc,
            r,
            bottom,
            radius_inc,
            theta_inc,
        } = self.cycle_positions(blk, polar, r_word, bottom_word, old_w, &frame);
        if r < bottom {
            return fail(
                first_col,
                format!("R less than {w_name} in cycle in {plane_name} plane"),
            );
        }

        // The words of the cycle itself.
        let (p, q, ijk) = self.cycle_parameters(blk, kind, same, first_col)?;
        let spindle = self.cycles.spindle;
        if matches!(kind, CycleKind::G86 | CycleKind::G87 | CycleKind::G88)
            && spindle == Spindle::Stopped
        {
            return fail(first_col, format!("Spindle not turning in {}", kind.name()));
        }

        // Preliminary motion: up to R when the initial level is below it (in the mode of
        // the block: rs274 switches to exact path only after it).
        let mut current_w = current_w;
        if old_w < r {
            let to = frame.machine(cur_prog[u], cur_prog[v], r);
            self.cycle_line(out, first_col, to, None, self.corner)?;
            old_w = r;
            current_w = r;
        }
        let clear = if self.retract_r { r } else { old_w };
        let middle = if self.absolute {
            ijk[w]
        } else {
            bottom + ijk[w]
        };
        let delta = if self.inch { 0.010 } else { 0.254 };
        let restart = if spindle == Spindle::Ccw {
            EventCode::M4
        } else {
            EventCode::M3
        };
        let exact = CornerMode::ExactStop;
        let pass = Pass {
            kind,
            first_col,
            feed_mm_min,
            p,
            q,
            ijk,
            middle,
            delta,
            restart,
            start_items,
        };
        for repeat in 0..l {
            a += a_inc;
            b += b_inc;
            if !polar_step(&mut a, &mut b, radius_inc, theta_inc) {
                return fail(
                    blk.first_of(&[K_AT, K_CARET])
                        .map_or(first_col, |k| blk.col(k)),
                    "Incremental motion with polar coordinates is indeterminate when at the origin",
                );
            }
            if repeat == 0 && current_w > r {
                self.cycle_line(out, first_col, frame.machine(a, b, current_w), None, exact)?;
                self.cycle_line(out, first_col, frame.machine(a, b, r), None, exact)?;
            } else {
                self.cycle_line(out, first_col, frame.machine(a, b, clear), None, exact)?;
                if clear > r {
                    self.cycle_line(out, first_col, frame.machine(a, b, r), None, exact)?;
                }
            }
            let h = Hole {
                a,
                b,
                r,
                clear,
                bottom,
            };
            self.drill(out, &frame, &h, &pass)?;
            if out.items.len() - start_items > MAX_CYCLE_ITEMS {
                return self.too_many(first_col);
            }
        }

        self.remember_cycle(&pass, initial_level, r_word, bottom_word);
        Ok(())
    }

    /// The plane's axes and the current point of a cycle block.
    fn cycle_frame(&self, u: usize, v: usize, w: usize) -> Frame {
        let scale = self.scale();
        let mut cur_prog = [0.0; 3];
        for (i, c) in cur_prog.iter_mut().enumerate() {
            *c = snap((self.pos[i] - self.origin[i]) / scale);
        }
        Frame {
            u,
            v,
            w,
            scale,
            origin: self.origin,
            cur_prog,
            cur_mm: self.pos,
        }
    }

    /// Keeps what a following block of the same cycle reuses when it omits the words.
    fn remember_cycle(&mut self, s: &Pass, initial_level: f64, r_word: f64, bottom_word: f64) {
        let kind = s.kind;
        self.cycles.last = Some(kind);
        self.cycles.initial_level = Some(initial_level);
        self.cycles.r = r_word;
        self.cycles.bottom = bottom_word;
        if kind.uses_p() {
            self.cycles.p = s.p;
        }
        if kind.uses_q() {
            self.cycles.q = s.q;
        }
        if kind == CycleKind::G87 {
            self.cycles.ijk = s.ijk;
        }
    }

    /// The words that are errors in a cycle block whatever else it holds, the polar words
    /// and the L repeat count. Returns the count and whether the hole is given in polar
    /// words, or `None` for a block without axis words, which does nothing.
    fn cycle_block_words(
        &self,
        blk: &Block,
        kind: CycleKind,
        explicit: Option<u32>,
    ) -> Result<Option<(u32, bool)>, BlockError> {
        // Words that are errors in a cycle, whatever else the block holds.
        if let Some(k) = blk.first_of(&ABC) {
            return fail(
                blk.col(k),
                format!(
                    "Cannot put an {} in canned cycle",
                    key_name(k).to_ascii_lowercase()
                ),
            );
        }
        if kind != CycleKind::G87
            && let Some(k) = blk.first_of(&IJK)
        {
            return fail(blk.col(k), unused_word_message(k));
        }
        let polar = blk.has(K_AT) || blk.has(K_CARET);
        if let Some(k) = blk.first_of(&[K_AT, K_CARET]) {
            if let Some(xy) = blk.first_of(&[KX, KY]) {
                return fail(
                    blk.col(xy),
                    format!(
                        "Cannot specify both polar coordinate and {} word",
                        key_name(xy)
                    ),
                );
            }
            // rs274 checks the plane before the block's own plane code takes effect.
            if self.plane != crate::arc::Plane::Xy || self.cycles.block_plane != self.plane {
                return fail(
                    blk.col(k),
                    "Cannot use polar coordinate except in G17 plane",
                );
            }
        }
        let l = match blk.get(KL) {
            None => 1u32,
            Some(l) if l < 0.0 => return fail(blk.col(KL), "Negative l word used"),
            Some(l) if l.fract() != 0.0 => {
                return fail(blk.col(KL), "Non integer value for integer");
            }
            Some(l) if l > MAX_CYCLE_ITEMS as f64 => {
                return fail(
                    blk.col(KL),
                    format!("L word above {MAX_CYCLE_ITEMS}: too many repeats of a cycle"),
                );
            }
            Some(l) => l as u32,
        };
        if !blk.any(&XYZ) && !polar {
            // A block in cycle mode without axis words does nothing, unless it names the
            // cycle: then it is rs274's error. Its cycle words then have no use: errors.
            if let Some(col) = explicit {
                return fail(col, "All axes missing with motion code");
            }
            if let Some(k) = blk.first_of(&[KL, KP, KQ, KR, KI, KJ, KK]) {
                return fail(blk.col(k), unused_word_message(k));
            }
            return Ok(None);
        }
        Ok(Some((l, polar)))
    }

    /// The feed of a cycle's feed moves, mm/min.
    fn cycle_feed(&self, blk: &Block, first_col: u32) -> Result<f64, BlockError> {
        // The feed: per minute, or per revolution at the commanded speed (G95); inverse
        // time has no meaning for a cycle's several moves (rs274's error).
        if self.feed_mode == FeedMode::InverseTime {
            return fail(first_col, "Cannot use inverse time feed with canned cycles");
        }
        let feed_mm_min = match self.feed_mode {
            FeedMode::PerRev => match self.move_feed(blk, false, first_col)? {
                MoveFeed::MmMin(f) => f,
                MoveFeed::InverseTime(_) => {
                    return fail(first_col, "Cannot use inverse time feed with canned cycles");
                }
            },
            _ => match self.feed_mm_min {
                Some(f) if f > 0.0 => f,
                _ => return fail(first_col, "Cannot feed with zero feed rate"),
            },
        };
        Ok(feed_mm_min)
    }

    /// The first hole and the R and bottom levels in program coordinates, and the step
    /// from hole to hole (incremental mode) in the plane and in polar words.
    fn cycle_positions(
        &self,
        blk: &Block,
        polar: bool,
        r_word: f64,
        bottom_word: f64,
        old_w: f64,
        frame: &Frame,
    ) -> Positions {
        let (mut a, mut b, a_inc, b_inc, r, bottom);
        let (mut radius_inc, mut theta_inc) = (0.0, 0.0);
        if self.absolute {
            r = r_word;
            bottom = bottom_word;
            a = blk.get(XYZ[frame.u]).unwrap_or(frame.cur_prog[frame.u]);
            b = blk.get(XYZ[frame.v]).unwrap_or(frame.cur_prog[frame.v]);
            if polar {
                // G17 only (checked above): about the program's XY zero; a missing word
                // keeps the current point's radius or angle.
                let radius = blk
                    .get(K_AT)
                    .unwrap_or(frame.cur_prog[0].hypot(frame.cur_prog[1]));
                let theta = match blk.get(K_CARET) {
                    Some(t) => t.to_radians(),
                    None => frame.cur_prog[1].atan2(frame.cur_prog[0]),
                };
                a = radius * theta.cos();
                b = radius * theta.sin();
            }
            a_inc = 0.0;
            b_inc = 0.0;
        } else {
            if polar {
                radius_inc = blk.get(K_AT).unwrap_or(0.0);
                theta_inc = blk.get(K_CARET).unwrap_or(0.0).to_radians();
            }
            r = r_word + old_w;
            bottom = r + bottom_word;
            a = frame.cur_prog[frame.u];
            b = frame.cur_prog[frame.v];
            a_inc = blk.get(XYZ[frame.u]).unwrap_or(0.0);
            b_inc = blk.get(XYZ[frame.v]).unwrap_or(0.0);
        }
        Positions {
            a,
            b,
            a_inc,
            b_inc,
            r,
            bottom,
            radius_inc,
            theta_inc,
        }
    }

    /// The P (dwell), Q (peck) and G87 I, J, K words of the cycle, or the last cycle's
    /// when the block repeats it without them.
    fn cycle_parameters(
        &self,
        blk: &Block,
        kind: CycleKind,
        same: bool,
        first_col: u32,
    ) -> Result<(f64, f64, [f64; 3]), BlockError> {
        let mut p = 0.0;
        if kind.uses_p() {
            // rs274 takes P-1 for "no P word".
            p = match blk.get(KP).filter(|&p| p != -1.0) {
                Some(p) => p,
                None if same => self.cycles.p,
                None => {
                    return fail(
                        first_col,
                        format!("Dwell time p word missing with {}", kind.name()),
                    );
                }
            };
            if p < 0.0 {
                return fail(blk.col(KP), "Negative P word used");
            }
            if p > MAX_DWELL_S {
                return fail(
                    blk.col(KP),
                    format!("dwell time P must be at most 1000000, found {p}"),
                );
            }
        }
        let mut q = 0.0;
        if kind.uses_q() {
            // rs274 takes Q-1 for "no Q word".
            q = match blk.get(KQ).filter(|&q| q != -1.0) {
                Some(q) => q,
                None if same => self.cycles.q,
                None => {
                    return fail(first_col, format!("Q word missing with {}", kind.name()));
                }
            };
            if q <= 0.0 {
                let col = if blk.has(KQ) { blk.col(KQ) } else { first_col };
                return fail(col, "Negative or zero q value used");
            }
        }
        let mut ijk = self.cycles.ijk;
        if kind == CycleKind::G87 {
            for (i, &k) in IJK.iter().enumerate() {
                match blk.get(k) {
                    Some(x) => ijk[i] = x,
                    None if same => {}
                    None => {
                        return fail(first_col, format!("{} word missing with g87", key_name(k)));
                    }
                }
            }
        }
        Ok((p, q, ijk))
    }

    /// The moves and events of one hole of the cycle, after the approach to its R level.
    fn drill(
        &mut self,
        out: &mut Out<'_>,
        frame: &Frame,
        h: &Hole,
        s: &Pass,
    ) -> Result<(), BlockError> {
        let Pass {
            kind,
            first_col,
            feed_mm_min,
            p,
            q,
            ijk,
            middle,
            delta,
            restart,
            start_items,
        } = *s;
        let (u, v) = (frame.u, frame.v);
        let exact = CornerMode::ExactStop;
        let feed = Some(feed_mm_min);
        let at = |c: f64| frame.machine(h.a, h.b, c);
        match kind {
            CycleKind::G81 => {
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
            }
            CycleKind::G82 => {
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                out.event(EventCode::G4, Some(p));
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
            }
            CycleKind::G73 | CycleKind::G83 => {
                let mut depth = h.r - q;
                while depth > h.bottom {
                    self.cycle_line(out, first_col, at(depth), feed, exact)?;
                    if kind == CycleKind::G83 {
                        self.cycle_line(out, first_col, at(h.r), None, exact)?;
                    }
                    self.cycle_line(out, first_col, at(depth + delta), None, exact)?;
                    if out.items.len() - start_items > MAX_CYCLE_ITEMS {
                        return self.too_many(first_col);
                    }
                    depth -= q;
                }
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
            }
            CycleKind::G85 => {
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                self.cycle_line(out, first_col, at(h.r), feed, exact)?;
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
            }
            CycleKind::G86 => {
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                out.event(EventCode::G4, Some(p));
                out.event(EventCode::M5, None);
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
                out.event(restart, None);
            }
            CycleKind::G87 => {
                let (oa, ob) = (h.a + ijk[u], h.b + ijk[v]);
                self.cycle_line(out, first_col, frame.machine(oa, ob, h.r), None, exact)?;
                out.event(EventCode::M5, None);
                out.event(EventCode::M19, Some(0.0));
                self.cycle_line(out, first_col, frame.machine(oa, ob, h.bottom), None, exact)?;
                self.cycle_line(out, first_col, at(h.bottom), None, exact)?;
                out.event(restart, None);
                self.cycle_line(out, first_col, at(middle), feed, exact)?;
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                out.event(EventCode::M5, None);
                out.event(EventCode::M19, Some(0.0));
                self.cycle_line(out, first_col, frame.machine(oa, ob, h.bottom), None, exact)?;
                self.cycle_line(out, first_col, frame.machine(oa, ob, h.clear), None, exact)?;
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
                out.event(restart, None);
            }
            CycleKind::G88 => {
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                out.event(EventCode::G4, Some(p));
                out.event(EventCode::M5, None);
                out.event(EventCode::M0, None);
                // The operator retracts the spindle by hand during the stop; rs274
                // then takes the tool to be at the clearance level. Kerf's moves are
                // continuous, so that retract is this rapid.
                self.cycle_line(out, first_col, at(h.clear), None, exact)?;
                out.event(restart, None);
            }
            CycleKind::G89 => {
                self.cycle_line(out, first_col, at(h.bottom), feed, exact)?;
                out.event(EventCode::G4, Some(p));
                self.cycle_line(out, first_col, at(h.clear), feed, exact)?;
            }
        }
        Ok(())
    }

    fn too_many<T>(&self, col: u32) -> Result<T, BlockError> {
        fail(
            col,
            format!("canned cycle makes more than {MAX_CYCLE_ITEMS} moves and events in one block"),
        )
    }

    /// One straight move of a cycle from the current position to `to` (machine mm): a
    /// rapid when `feed_mm_min` is `None`. A move of zero length is not emitted.
    fn cycle_line(
        &mut self,
        out: &mut Out<'_>,
        col: u32,
        to: Vec3,
        feed_mm_min: Option<f64>,
        corner: CornerMode,
    ) -> Result<(), BlockError> {
        if !to.iter().all(|x| x.is_finite()) {
            return fail(col, "coordinate out of range");
        }
        let start = self.pos;
        if (to - start).norm() < crate::arc::SAME_POINT_MM {
            return Ok(());
        }
        out.items.push(Item::Move(Move {
            line: out.line,
            rapid: feed_mm_min.is_none(),
            path: Path::Line(Line { start, end: to }),
            feed_mm_min,
            abc_deg: if self.abc_used {
                Some((self.abc, self.abc))
            } else {
                None
            },
            corner,
        }));
        self.pos = to;
        Ok(())
    }
}
