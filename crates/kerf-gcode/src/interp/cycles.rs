//! LinuxCNC canned cycles: G73, G81, G82, G83, G85, G86, G87, G88 and G89 with G98/G99,
//! R, L repeats and incremental mode, in the G17, G18 and G19 planes, resolved into the
//! moves and events LinuxCNC's interpreter (rs274, 2.9) produces for them.
//!
//! The cycle works in the active plane: `u`, `v` are the plane's axes (G17: X, Y; G18: Z,
//! X; G19: Y, Z) and `w` the drilling axis along its normal (G17: Z, G18: Y, G19: X). As in
//! rs274, the values are computed in program coordinates and program units and only the
//! resulting points are converted to machine millimetres, so that every decision (a peck
//! more or less, a preliminary move or not) is the one rs274 takes:
//!
//! - Absolute (G90): R and the `w` word are positions, the `u`/`v` words the hole position
//!   (a missing one keeps the current value). Incremental (G91): R is measured from the
//!   initial level, the `w` word from R, and the `u`/`v` words are added to the current
//!   position before each repeat (so L repeats step along a line).
//! - The initial level is the `w` position when the series of cycles started; it is kept
//!   while the motion mode stays a cycle (changing from one cycle to another keeps it) and
//!   is forgotten when G0, G1, G2, G3 or G80 is programmed (even without axis words).
//! - If the initial level is below R, a rapid along `w` to R comes first (once per block).
//!   The clearance level is R under G99, the initial level (raised to R) under G98.
//! - Before each repeat: on the first, when the current `w` is above R, a rapid in the
//!   plane at the current `w`, then a rapid down to R; otherwise a rapid to the hole at
//!   the clearance level, then down to R if that is above it. (rs274 does this even when
//!   the tool is below the clearance level, which makes a slanted rapid: Kerf does the same.)
//! - R, the `w` word, P, Q and G87's I J K are kept for the following blocks of the same
//!   cycle; a block with another cycle code needs them again. L is not kept.
//! - G73 and G83 peck by Q from R: `d = R − Q, R − 2Q, …` while `d` is above the bottom;
//!   G73 backs off 0.010 in (0.254 mm) after each peck, G83 goes back out to R and returns
//!   rapidly to 0.010 in (0.254 mm) above `d`.

use kerf_geom::{CornerMode, Line, Move, Path, Vec3};

use super::modal::MoveFeed;
use super::{Block, BlockError, FeedMode, Out, State, fail};
use crate::codes::*;
use crate::lex::{K_AT, K_CARET};
use crate::{EventCode, Item};

/// The most moves and events one canned-cycle block may produce (its L repeats and pecks
/// together). A block's items are held until the whole block is resolved, so this bounds
/// the memory a block can take; rs274 has no such limit.
pub(crate) const MAX_CYCLE_ITEMS: usize = 100_000;

/// The longest dwell accepted, seconds (as for G4).
const MAX_DWELL_S: f64 = 1e6;

/// rs274's message for a word no G code of the block uses (I, J, K, L, P, Q, R).
pub(crate) fn unused_word_message(k: u8) -> &'static str {
    match k {
        KI => "I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it",
        KJ => "J word with no G2, G3, G5, G5.1, G10, G76 or G87 to use it",
        KK => "K word with no G2, G3, G33, G33.1, G76, or G87 to use it",
        KL => {
            "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code"
        }
        KP => {
            "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it"
        }
        KQ => {
            "Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it"
        }
        _ => "R word with no g code that uses it",
    }
}

/// A canned cycle (LinuxCNC motion modes G73, G81–G83, G85–G89).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CycleKind {
    G73,
    G81,
    G82,
    G83,
    G85,
    G86,
    G87,
    G88,
    G89,
}

impl CycleKind {
    /// What the cycle does, in one line.
    pub(crate) fn describe(self) -> &'static str {
        match self {
            CycleKind::G73 => "drilling cycle with chip break",
            CycleKind::G81 => "drilling cycle",
            CycleKind::G82 => "drilling cycle with dwell",
            CycleKind::G83 => "peck drilling cycle",
            CycleKind::G85 => "boring cycle, feed out",
            CycleKind::G86 => "boring cycle, spindle stop, rapid out",
            CycleKind::G87 => "back boring cycle",
            CycleKind::G88 => "boring cycle, spindle stop, manual out",
            CycleKind::G89 => "boring cycle, dwell, feed out",
        }
    }

    /// The cycle of a G number times ten, if it is one.
    pub(crate) fn from_code10(code10: u16) -> Option<CycleKind> {
        Some(match code10 {
            730 => CycleKind::G73,
            810 => CycleKind::G81,
            820 => CycleKind::G82,
            830 => CycleKind::G83,
            850 => CycleKind::G85,
            860 => CycleKind::G86,
            870 => CycleKind::G87,
            880 => CycleKind::G88,
            890 => CycleKind::G89,
            _ => return None,
        })
    }

    /// The code as rs274 writes it in its messages.
    fn name(self) -> &'static str {
        match self {
            CycleKind::G73 => "g73",
            CycleKind::G81 => "g81",
            CycleKind::G82 => "g82",
            CycleKind::G83 => "g83",
            CycleKind::G85 => "g85",
            CycleKind::G86 => "g86",
            CycleKind::G87 => "g87",
            CycleKind::G88 => "g88",
            CycleKind::G89 => "g89",
        }
    }

    /// The cycles with a dwell P.
    fn uses_p(self) -> bool {
        matches!(
            self,
            CycleKind::G82 | CycleKind::G86 | CycleKind::G88 | CycleKind::G89
        )
    }

    /// The peck cycles, with a Q.
    fn uses_q(self) -> bool {
        matches!(self, CycleKind::G73 | CycleKind::G83)
    }
}

/// The spindle direction, as the cycles that stop and restart it need to know.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Spindle {
    Stopped,
    Cw,
    Ccw,
}

/// What the canned cycles keep from block to block (rs274's `cycle_*` settings).
pub(crate) struct CycleState {
    /// The cycle of the last cycle block executed while the motion mode stayed a cycle
    /// (rs274's motion mode, for the sticky words); `None` after G0–G3 or G80.
    last: Option<CycleKind>,
    /// The initial level along the drilling axis, program units (rs274's `cycle_il`).
    initial_level: Option<f64>,
    /// The last R word, as written (incremental R stays an increment).
    r: f64,
    /// The last word along the drilling axis, as written.
    bottom: f64,
    /// The last dwell P of G82/G86/G88/G89, seconds.
    p: f64,
    /// The last peck Q of G73/G83.
    q: f64,
    /// The last I, J, K of G87.
    ijk: [f64; 3],
    /// The spindle direction (M3, M4, M5).
    pub(crate) spindle: Spindle,
    /// The plane before the current block's plane code (rs274 checks polar words in a cycle
    /// against it).
    pub(crate) block_plane: crate::arc::Plane,
}

impl CycleState {
    pub(crate) fn new() -> Self {
        CycleState {
            last: None,
            initial_level: None,
            r: 0.0,
            bottom: 0.0,
            p: 0.0,
            q: 0.0,
            ijk: [0.0; 3],
            spindle: Spindle::Stopped,
            block_plane: crate::arc::Plane::Xy,
        }
    }

    /// Follows the spindle events of a block (M3, M4, M5).
    pub(crate) fn note_spindle(&mut self, ev: EventCode) {
        match ev {
            EventCode::M3 => self.spindle = Spindle::Cw,
            EventCode::M4 => self.spindle = Spindle::Ccw,
            EventCode::M5 | EventCode::M2 | EventCode::M30 => self.spindle = Spindle::Stopped,
            _ => {}
        }
    }
}

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

impl State {
    /// Called with the block's group-1 code before its motion: G80 with axis words is an
    /// error, and any motion code that is not a cycle ends the series of cycles.
    pub(super) fn cycle_motion_code(
        &mut self,
        blk: &Block,
        code: Option<(G, u32)>,
    ) -> Result<(), BlockError> {
        match code {
            Some((G::NoMotion, col)) => {
                if blk.any(&XYZ) || blk.any(&ABC) || blk.has(K_AT) || blk.has(K_CARET) {
                    return fail(col, "Cannot use axis values with g80");
                }
                self.cycles.last = None;
                self.cycles.initial_level = None;
            }
            Some((G::Motion(Motion::Cycle(_)), _)) => {}
            Some((G::Motion(_), _)) => {
                self.cycles.last = None;
                self.cycles.initial_level = None;
            }
            _ => {}
        }
        Ok(())
    }

    /// LinuxCNC: axis words without a motion mode, an error rs274 reports before the words
    /// no G code uses.
    pub(super) fn axes_without_motion(&self, blk: &Block) -> bool {
        self.motion.is_none()
            && (blk.any(&XYZ) || blk.any(&ABC) || blk.has(K_AT) || blk.has(K_CARET))
    }

    /// Whether the active motion mode is a cycle that uses P (G82, G86, G88, G89).
    pub(super) fn cycle_uses_p(&self) -> bool {
        matches!(self.motion, Some(Motion::Cycle(k)) if k.uses_p())
    }

    /// Whether the active motion mode is a peck cycle that uses Q (G73, G83).
    pub(super) fn cycle_uses_q(&self) -> bool {
        matches!(self.motion, Some(Motion::Cycle(k)) if k.uses_q())
    }

    /// LinuxCNC: an L word needs a canned cycle that moves (or G10, which is not supported
    /// yet). Axis words without a motion mode are reported first, as rs274 does.
    /// `explicit_cycle`: the block names a cycle (then a missing axis word is the error).
    pub(super) fn check_l_word(&self, blk: &Block, explicit_cycle: bool) -> Result<(), BlockError> {
        let cycle = matches!(self.motion, Some(Motion::Cycle(_)));
        let axes = blk.any(&XYZ) || blk.has(K_AT) || blk.has(K_CARET);
        let used = cycle && (explicit_cycle || axes);
        if blk.has(KL) && !used && !self.axes_without_motion(blk) {
            return fail(blk.col(KL), unused_word_message(KL));
        }
        Ok(())
    }

    /// Runs a block in canned-cycle motion mode `kind`. `explicit` is the column of the
    /// block's cycle code, when the block has one.
    pub(super) fn cycle(
        &mut self,
        blk: &Block,
        out: &mut Out<'_>,
        kind: CycleKind,
        explicit: Option<u32>,
    ) -> Result<(), BlockError> {
        let start_items = out.items.len();
        let first_col = explicit.unwrap_or(blk.first_col);
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
            return Ok(());
        }

        // convert_cycle's checks, in its order.
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
        let scale = self.scale();
        let mut cur_prog = [0.0; 3];
        for (i, c) in cur_prog.iter_mut().enumerate() {
            *c = snap((self.pos[i] - self.origin[i]) / scale);
        }
        let frame = Frame {
            u,
            v,
            w,
            scale,
            origin: self.origin,
            cur_prog,
            cur_mm: self.pos,
        };
        let current_w = cur_prog[w];
        let initial_level = self.cycles.initial_level.unwrap_or(current_w);
        let mut old_w = initial_level;
        let (mut a, mut b, a_inc, b_inc, r, bottom);
        let (mut radius_inc, mut theta_inc) = (0.0, 0.0);
        if self.absolute {
            r = r_word;
            bottom = bottom_word;
            a = blk.get(XYZ[u]).unwrap_or(cur_prog[u]);
            b = blk.get(XYZ[v]).unwrap_or(cur_prog[v]);
            if polar {
                // G17 only (checked above): about the program's XY zero; a missing word
                // keeps the current point's radius or angle.
                let radius = blk.get(K_AT).unwrap_or(cur_prog[0].hypot(cur_prog[1]));
                let theta = match blk.get(K_CARET) {
                    Some(t) => t.to_radians(),
                    None => cur_prog[1].atan2(cur_prog[0]),
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
            a = cur_prog[u];
            b = cur_prog[v];
            a_inc = blk.get(XYZ[u]).unwrap_or(0.0);
            b_inc = blk.get(XYZ[v]).unwrap_or(0.0);
        }
        if r < bottom {
            return fail(
                first_col,
                format!("R less than {w_name} in cycle in {plane_name} plane"),
            );
        }

        // The words of the cycle itself.
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
        for repeat in 0..l {
            a += a_inc;
            b += b_inc;
            for (d_radius, d_theta) in [(radius_inc, 0.0), (0.0, theta_inc)] {
                if d_radius == 0.0 && d_theta == 0.0 {
                    continue;
                }
                if a == 0.0 && b == 0.0 {
                    return fail(
                        blk.first_of(&[K_AT, K_CARET])
                            .map_or(first_col, |k| blk.col(k)),
                        "Incremental motion with polar coordinates is indeterminate when at the origin",
                    );
                }
                let theta = b.atan2(a) + d_theta;
                let radius = b.hypot(a) + d_radius;
                a = radius * theta.cos();
                b = radius * theta.sin();
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
            if out.items.len() - start_items > MAX_CYCLE_ITEMS {
                return self.too_many(first_col);
            }
        }

        self.cycles.last = Some(kind);
        self.cycles.initial_level = Some(initial_level);
        self.cycles.r = r_word;
        self.cycles.bottom = bottom_word;
        if kind.uses_p() {
            self.cycles.p = p;
        }
        if kind.uses_q() {
            self.cycles.q = q;
        }
        if kind == CycleKind::G87 {
            self.cycles.ijk = ijk;
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
