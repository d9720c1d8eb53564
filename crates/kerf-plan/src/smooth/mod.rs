//! Smoothing of dense polylines: runs of short, nearly collinear lines (CAM output that
//! approximates a curve) become a chain of curvature-continuous quintic pieces whose knots
//! lie at vertices of the polyline (or, where the vertices are coarsely rounded, within
//! half the band of them) and that stay within the path tolerance of it.
//!
//! Why: a polyline that approximates a circle has vertices rounded to the program's
//! decimals. Following the vertices (or circular blends at each of them) turns that
//! rounding into curvature noise, and every curvature jump is an acceleration step that the
//! junction caps must slow down for: a 3,600-line circle of radius 10 mm written with four
//! decimals crawled at a quarter of its feed. Fitting a smooth curve within the tolerance is
//! what serious controls do with such code (a "compressor").
//!
//! How:
//! - **Runs.** Consecutive feed lines join a run while they have the same tolerance (feeds
//!   may differ: a piece runs at the lowest feed of the moves it covers), blend mode, an
//!   XYZ length up to [`MAX_SEGMENT_MM`], and at every vertex a turn of at most
//!   [`MAX_TURN_RAD`] whose sag `L·θ/8` (how far a smooth curve through the vertices lies
//!   from the longer adjacent line) is at most [`SAG_TOL_SHARE`] of the tolerance. Coarse
//!   polygons fail that test and keep their corner blends. Runs of fewer than
//!   [`MIN_RUN_MOVES`] moves are left alone.
//! - **Rotary axes** that move along the lines (4- and 5-axis CAM code) are smoothed with
//!   them: A, B, C are fitted against the XYZ arc length in the same windows, carried by
//!   each piece as quintics in its parameter, curvature-continuous across knots, and held
//!   within the tolerance — the same number, in degrees — of the programmed linear
//!   interpolation; the rate change at a vertex must sag within the same share of it. (No
//!   control's manual sets a rotary tolerance for blending; LinuxCNC's `G64 P` is in
//!   length units. A degree per millimetre of tolerance is the choice made here.)
//! - **Knots** are at vertices of the polyline, every [`WINDOW_MM`] or less of chord length
//!   and every [`MAX_PIECE_MOVES`] vertices or fewer. Where the vertices are coarsely
//!   rounded ([`POSITION_NOISE_SHARE`]), a knot inside a run lies where a quadratic fitted
//!   over [`POSITION_WINDOW_MM`] each side puts its vertex (within half the band of it),
//!   not on the rounded vertex itself: the band, not the vertices, holds the curve, so
//!   rounding does not bend it between knots. At a knot the unit tangent and the curvature
//!   vector come from a weighted least-squares quartic (a cubic in windows of fewer than
//!   [`QUARTIC_MIN_VERTICES`] vertices besides the knot's own) fitted to the vertices
//!   within a window around it (biweight weights in chord length, uniform for the one-sided
//!   window at a run end; at least two vertices each side) with a free constant (held
//!   through the vertex only at a run end), so that the vertex's own rounding does not tilt
//!   the tangent: rounding noise averages out over the window. The window halves (down to
//!   two vertices each side) until the fit explains every vertex in it within
//!   [`RESIDUAL_TOL_SHARE`] of the tolerance, so that it does not reach across a change of
//!   shape.
//! - **Pieces** between consecutive knots are quintic Hermite curves
//!   ([`kerf_geom::Transition`]) matching position, tangent and curvature at both knots, so
//!   the chain is curvature-continuous and the joints cost no speed. Their parameter scale
//!   is the polyline's length between the knots (the arc length, to the rounding), so a
//!   smooth curve is reproduced to sixth order and its third derivative, which the axes'
//!   jerk must follow, is the curve's and not an artefact of the fit. Each piece is sampled
//!   against the polyline it replaces (every setpoint must lie within the tolerance of the
//!   programmed path) and halved until it fits within [`crate::TRANSITION_TOL_SHARE`] of the
//!   tolerance. A single line whose piece does not fit is kept as a line from its start
//!   knot (which may lie off its vertex, within half the band) to its end vertex.
//! - **Pieces follow the curve's third derivative.** A piece is also halved where its
//!   halves, each at the highest speed its geometry allows at constant speed within the
//!   axis limits (capped a little above the feed), would take at most
//!   [`RATE_SPLIT_GAIN`] of its time ([`Run::rate_split`]): over a wave of 3 mm a 2 mm
//!   quintic overshoots the wave's third derivative by up to half, and a piece runs at the
//!   lowest speed its whole length allows. The halves end on the whole piece's knots, so
//!   every other knot stays where it was, and the knot windows keep their width, so the
//!   halves average the rounding as the whole did. A piece at the feed, and the first and
//!   last pieces of a run (whose ramp budgets serve a stop), are never split.
//! - **Run ends** are exact vertices. Where the move before or after the run is a feed
//!   move it joins within [`MAX_TURN_RAD`], the end knot takes that move's tangent and
//!   curvature, so a line or arc leading into dense code is joined without a kink or a
//!   curvature step; where the next move starts another run (a tolerance change), the run
//!   ends on its fitted frame and the next one starts on it; otherwise the end knot comes
//!   from a one-sided fit (and the joint is a corner).
//! - **Streaming.** Pieces are emitted once the data their knots depend on has arrived and
//!   [`DESIGN_RUN_MM`] of the run is known (or the run is finished), and vertices behind
//!   the current knot are dropped, so memory is bounded by the window and that distance,
//!   not by the program.
//! - **Design run.** Each piece carries the distance its design speed is chosen for (see
//!   [`crate::segment_limits`]): its run's length where the run is shorter than
//!   [`DESIGN_RUN_MM`], else that; once the run is finished, also the rest of the run
//!   from the piece's start, to which the planner adds the corner-free path before the
//!   piece (as for programmed arcs), at most [`DESIGN_RUN_MM`]. Geometry only, so that
//!   the choice never depends on the limits; and no longer than the run, as a piece of a
//!   short run between two stops designed for a longer distance would choose a higher
//!   design speed when a limit is raised, whose ramps cost more than it saves.
//!
//! A piece replaces several programmed moves: its [`PlannedSegment`](crate::PlannedSegment)
//! names the first one (`line`, `move_index`) and how many it covers (`move_count`).

mod knot_fit;
mod piece;
mod rate_split;
#[cfg(test)]
mod tests;

use crate::DESIGN_RUN_MM;
use kerf_geom::{Transition, Vec3};

/// Longest line that may join a run, mm.
pub const MAX_SEGMENT_MM: f64 = 10.0;
/// Largest turn at a vertex inside a run, radians (45°).
pub const MAX_TURN_RAD: f64 = std::f64::consts::FRAC_PI_4;
/// Largest sag `L·θ/8` at a vertex inside a run, as a share of the tolerance.
pub const SAG_TOL_SHARE: f64 = 0.5;
/// Fewest moves in a run that is smoothed.
pub const MIN_RUN_MOVES: usize = 8;
/// Half-width of the widest fitting window, and the longest piece, mm of chord.
pub const WINDOW_MM: f64 = 2.0;
/// Most programmed moves one piece stands for: a piece ends after this many vertices even
/// short of `WINDOW_MM` (only code with steps under 2 µm reaches it). The daemon's cycle
/// tracks the moves of the segments it holds, in room for the running piece and the next
/// one at least (`kerf_pipeline::TRACKED_MOVES_EXTRA`); a longer piece would leave the
/// next one waiting until the running one ended, and the motion would stop between them.
pub const MAX_PIECE_MOVES: u64 = 1024;
/// Largest residual of the window's fit, as a share of the tolerance: the fit may leave a
/// vertex by up to 70 % of the band, so that rounding noise up to that size is averaged
/// over the whole window instead of shrinking it (the pieces themselves are still checked
/// against the polyline within [`crate::TRANSITION_TOL_SHARE`]). A much smaller share
/// shrinks every window of coarsely rounded code (2 decimals at a 0.01 mm tolerance) to a
/// few vertices, whose curvature is noise.
pub const RESIDUAL_TOL_SHARE: f64 = 0.7;
/// A piece is halved where its halves' time at constant speed within the axis limits is
/// at most this share of its own (see `Run::rate_split`): a split must save at least 5 %
/// of the piece's time.
pub const RATE_SPLIT_GAIN: f64 = 0.95;
/// The feed cap of that time, as a multiple of the programmed feed: a curved piece's
/// design speed is about nine tenths of its constant-speed limit, so a piece whose limit
/// is a little above the feed still runs under it.
const RATE_SPLIT_FEED_MARGIN: f64 = 1.1;
/// Fewest vertices in each half of a piece halved for its third derivative.
const RATE_SPLIT_MIN_VERTICES: u64 = 6;
/// Half the shortest piece halved for its third derivative, mm: a piece must be at least
/// twice this long. The halves split at its middle vertex by count, not by length, so
/// with uneven vertex spacing one half can be shorter than this.
const RATE_SPLIT_MIN_MM: f64 = 0.5;
/// Half-width of the window whose quadratic places a knot inside a run, mm of chord:
/// wide enough to average rounding over a dozen or more vertices of CAM code, narrow
/// enough that a curve's fourth derivative hardly moves the knot (see
/// `Run::position_offset`).
const POSITION_WINDOW_MM: f64 = 0.4;
/// A knot is moved off its vertex only where the vertices within [`POSITION_WINDOW_MM`]
/// leave a quartic fitted to them by this share of the tolerance or more (2 µm at
/// 0.01 mm): rounding to 2 decimals (up to 7 µm off in X and Z together), not to 3
/// (0.7 µm). On precise vertices the fit's own bias would move knots off the curve by as
/// much as the rounding it takes out, so they stay where they are; a smaller share lets
/// 3-decimal rounding cross it at some knots.
const POSITION_NOISE_SHARE: f64 = 0.2;
/// A knot is moved off its vertex only where the curve turns by at most this much over
/// [`POSITION_WINDOW_MM`], half the window (`κ·w`, radians): the fits follow a tighter
/// turn, the start of an Archimedean spiral of 0.01 mm pitch say, only by leaving its
/// vertices, and would move its knots off the curve.
const POSITION_MAX_TURN_RAD: f64 = 0.5;
/// Largest distance of a knot from its vertex, as a share of the tolerance.
const POSITION_TOL_SHARE: f64 = 0.5;
/// Fewest vertices in a fitting window (besides the knot's own) for the quartic fit;
/// smaller windows get a cubic.
const QUARTIC_MIN_VERTICES: usize = 16;
/// Growth of the buffer between tries to drop the vertices behind the current knot.
const DROP_ABOVE: usize = 4096;

/// A vertex of the run. Segment `k` runs from vertex `k` to vertex `k + 1` and belongs to
/// the move recorded at vertex `k + 1`.
#[derive(Clone, Copy, Debug)]
struct Vertex {
    p: Vec3,
    /// Chord length from the run start, mm.
    sigma: f64,
    /// Source line of the move ending here.
    line: u32,
    /// Index of the move ending here.
    move_index: u64,
    /// Programmed feed of the move ending here, mm/s.
    feed: f64,
    /// A, B, C here, degrees.
    abc: [f64; 3],
}

/// Position, unit tangent and curvature vector at a knot.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Knot {
    /// Absolute vertex number.
    idx: u64,
    p: Vec3,
    t: Vec3,
    k: Vec3,
    /// A, B, C (degrees) and their first and second derivatives with respect to the XYZ
    /// arc length.
    a: [f64; 3],
    da: [f64; 3],
    dda: [f64; 3],
}

/// Tangent and curvature a run end must match (from the neighbouring move).
#[derive(Clone, Copy, Debug)]
pub(crate) struct EndFrame {
    pub tangent: Vec3,
    pub curvature: Vec3,
    /// First and second derivatives of A, B, C with respect to the XYZ arc length.
    pub abc_d: [f64; 3],
    pub abc_dd: [f64; 3],
}

/// A piece's quintic, with the rotary axes' quintics in its parameter when the run moves
/// a rotary axis.
type PieceCurves = (Transition, Option<[[f64; 6]; 3]>);

/// One output piece of a run, between two knots. Pieces are moved straight into
/// segments, which hold the curve by value anyway.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
pub(crate) enum Piece {
    /// A smooth quintic.
    Curve(Transition),
    /// A line kept as programmed (its piece did not fit).
    Line(Vec3, Vec3),
}

/// A piece with the moves it covers.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Emitted {
    pub piece: Piece,
    /// A, B, C at the piece's ends, degrees.
    pub abc_start: [f64; 3],
    pub abc_end: [f64; 3],
    /// A, B, C along a curved piece, as quintics in its parameter (when the run moves a
    /// rotary axis).
    pub abc_poly: Option<[[f64; 6]; 3]>,
    pub line: u32,
    pub move_index: u64,
    pub move_count: u32,
    /// The lowest programmed feed of those moves, mm/s.
    pub feed: f64,
    /// The distance the piece's design speed is chosen for at the least, mm: the whole
    /// run where it is shorter than [`DESIGN_RUN_MM`] (a run is emitted only once that
    /// much of it is known, or it is finished), else [`DESIGN_RUN_MM`]. Geometry only.
    pub design_run_mm: f64,
    /// Chord length from the piece's start to the end of the run when the run is
    /// finished, mm; infinite while it goes on.
    pub rest_mm: f64,
}

/// The vertices of the current run and the knot the next piece starts from.
#[derive(Debug)]
pub(crate) struct Run {
    verts: Vec<Vertex>,
    /// Absolute number of `verts[0]`.
    base: u64,
    /// Knot the next piece starts from (`None` until the start has been decided).
    knot: Option<Knot>,
    /// Frame the run start must match, if any.
    start_frame: Option<EndFrame>,
    tol: f64,
    /// Buffer length at which the next drop is tried.
    drop_at: usize,
    /// Some vertex has different A, B, C from the first: the pieces carry rotary quintics.
    rotary: bool,
    /// Velocity, acceleration and jerk limits of X, Y, Z (infinite where the machine has
    /// no such axis), for [`Run::rate_split`].
    xyz_limits: [[f64; 3]; 3],
}

impl Run {
    /// An empty run starting at `p`; `start_frame` is the tangent and curvature its start
    /// must match, if any.
    pub fn new(
        p: Vec3,
        abc: [f64; 3],
        start_frame: Option<EndFrame>,
        tol: f64,
        xyz_limits: [[f64; 3]; 3],
    ) -> Run {
        Run {
            verts: vec![Vertex {
                p,
                sigma: 0.0,
                line: 0,
                move_index: 0,
                feed: f64::INFINITY,
                abc,
            }],
            base: 0,
            knot: None,
            start_frame,
            tol,
            drop_at: DROP_ABOVE,
            rotary: false,
            xyz_limits,
        }
    }

    /// A, B, C at the last vertex.
    pub fn end_abc(&self) -> [f64; 3] {
        self.verts[self.verts.len() - 1].abc
    }

    /// Rate of A, B, C along the last segment, degrees per mm.
    pub fn last_abc_rate(&self) -> [f64; 3] {
        let n = self.verts.len();
        if n < 2 {
            return [0.0; 3];
        }
        let (a, b) = (&self.verts[n - 2], &self.verts[n - 1]);
        let len = b.sigma - a.sigma;
        std::array::from_fn(|i| (b.abc[i] - a.abc[i]) / len)
    }

    /// The last vertex.
    pub fn end(&self) -> Vec3 {
        self.verts[self.verts.len() - 1].p
    }

    /// Direction of the last segment.
    pub fn last_dir(&self) -> Option<Vec3> {
        let n = self.verts.len();
        (n >= 2).then(|| (self.verts[n - 1].p - self.verts[n - 2].p).normalize())
    }

    /// Length of the last segment.
    pub fn last_len(&self) -> f64 {
        let n = self.verts.len();
        if n >= 2 {
            self.verts[n - 1].sigma - self.verts[n - 2].sigma
        } else {
            0.0
        }
    }

    /// Appends the segment to `q` (A, B, C at `abc`) of move (`line`, `move_index`) at
    /// `feed` (mm/s).
    pub fn push(&mut self, q: Vec3, abc: [f64; 3], line: u32, move_index: u64, feed: f64) {
        let last = self.verts[self.verts.len() - 1];
        self.rotary |= abc != self.verts[0].abc;
        self.verts.push(Vertex {
            p: q,
            sigma: last.sigma + (q - last.p).norm(),
            line,
            move_index,
            feed,
            abc,
        });
    }

    fn v(&self, idx: u64) -> &Vertex {
        &self.verts[(idx - self.base) as usize]
    }

    fn last_idx(&self) -> u64 {
        self.base + self.verts.len() as u64 - 1
    }

    /// Emits the pieces whose knots no longer depend on data still to come; with `finish`
    /// the run is complete and everything is emitted, the last knot matching `end_frame`
    /// if given.
    pub fn emit(&mut self, finish: bool, end_frame: Option<EndFrame>, out: &mut Vec<Emitted>) {
        // Nothing is emitted before [`DESIGN_RUN_MM`] of the run is known (or the run is
        // finished), so that each piece knows the run it is designed for.
        let s_end = self.v(self.last_idx()).sigma;
        if !finish && s_end < DESIGN_RUN_MM {
            return;
        }
        let design_run_mm = s_end.min(DESIGN_RUN_MM);
        let first_new = out.len();
        if self.knot.is_none() {
            let data = self.verts[self.verts.len() - 1].sigma - self.verts[0].sigma;
            if !finish && (data < 2.0 * WINDOW_MM + 1e-9 || self.verts.len() < 7) {
                return;
            }
            self.knot = Some(self.start_knot());
        }
        loop {
            let ka = self.knot.expect("start knot set above");
            let last = self.last_idx();
            if ka.idx >= last {
                break;
            }
            let sa = self.v(ka.idx).sigma;
            let s_last = self.v(last).sigma;
            if !finish && (s_last - sa < 2.0 * WINDOW_MM + 1e-9 || last < ka.idx + 6) {
                break;
            }
            // Furthest vertex within the window (at least the next one, at most
            // [`MAX_PIECE_MOVES`] on); a short rest of the run is taken whole rather than
            // left as a sliver.
            let mut ib = ka.idx + 1;
            let cap = ka.idx + MAX_PIECE_MOVES;
            while ib < last.min(cap) && self.v(ib + 1).sigma - sa <= WINDOW_MM {
                ib += 1;
            }
            if finish
                && s_last - self.v(ib).sigma < 0.5 * WINDOW_MM
                && s_last - sa <= 1.5 * WINDOW_MM
                && last <= cap
            {
                ib = last;
            }
            let kb = self.fit(ka, ib, finish, end_frame, out);
            self.knot = Some(kb);
        }
        for e in &mut out[first_new..] {
            e.design_run_mm = design_run_mm;
            if !finish {
                e.rest_mm = f64::INFINITY;
            }
        }
        self.drop_behind();
    }

    /// The knot at vertex `idx`: the run's end knots are fixed by the neighbours where they
    /// match, otherwise fitted.
    fn knot_at(&self, idx: u64, finish: bool, end_frame: Option<EndFrame>) -> Knot {
        if finish
            && idx == self.last_idx()
            && let Some(f) = end_frame
        {
            return self.frame_knot(idx, &f);
        }
        self.fit_knot(idx)
    }

    fn start_knot(&self) -> Knot {
        match self.start_frame {
            Some(f) => self.frame_knot(self.base, &f),
            None => self.fit_knot(self.base),
        }
    }

    /// The knot at vertex `idx` with the tangent and curvature of a neighbouring move.
    fn frame_knot(&self, idx: u64, f: &EndFrame) -> Knot {
        let v = self.v(idx);
        Knot {
            idx,
            p: v.p,
            t: f.tangent,
            k: f.curvature,
            a: v.abc,
            da: f.abc_d,
            dda: f.abc_dd,
        }
    }

    /// The piece from knot `ka` towards vertex `ib`, halved until it fits, appended to
    /// `out` (as two halves where [`Run::rate_split`] says so); returns its end knot.
    fn fit(
        &self,
        ka: Knot,
        mut ib: u64,
        finish: bool,
        end_frame: Option<EndFrame>,
        out: &mut Vec<Emitted>,
    ) -> Knot {
        loop {
            let kb = self.knot_at(ib, finish, end_frame);
            if let Some((tr, poly)) = self.piece(&ka, &kb) {
                // The halves end on the same knot, so the knots after them are those an
                // unsplit piece would have had.
                match self.rate_split(&ka, &kb, &tr, finish, end_frame) {
                    Some((km, (tr1, poly1), (tr2, poly2))) => {
                        out.push(self.emitted(ka.idx, km.idx, Piece::Curve(tr1), poly1));
                        out.push(self.emitted(km.idx, ib, Piece::Curve(tr2), poly2));
                    }
                    None => out.push(self.emitted(ka.idx, ib, Piece::Curve(tr), poly)),
                }
                return kb;
            }
            if ib == ka.idx + 1 {
                // Keep the line (from the knot, which is within half the band of its
                // vertex); the next piece starts on it with its direction.
                let (va, vb) = (self.v(ka.idx), self.v(ib));
                let (p, q) = (ka.p, vb.p);
                let len = (q - p).norm();
                let line_knot = Knot {
                    idx: ib,
                    p: q,
                    t: (q - p) / len,
                    k: Vec3::zeros(),
                    a: vb.abc,
                    da: std::array::from_fn(|i| (vb.abc[i] - va.abc[i]) / len),
                    dda: [0.0; 3],
                };
                out.push(self.emitted(ka.idx, ib, Piece::Line(p, q), None));
                return line_knot;
            }
            ib = ka.idx + (ib - ka.idx) / 2;
        }
    }

    /// The lowest feed of the moves between vertices `ia` and `ib`.
    fn min_feed(&self, ia: u64, ib: u64) -> f64 {
        (ia + 1..=ib)
            .map(|k| self.v(k).feed)
            .fold(f64::INFINITY, f64::min)
    }

    fn emitted(&self, ia: u64, ib: u64, piece: Piece, abc_poly: Option<[[f64; 6]; 3]>) -> Emitted {
        let first = self.v(ia + 1);
        let feed = self.min_feed(ia, ib);
        Emitted {
            piece,
            abc_start: self.v(ia).abc,
            abc_end: self.v(ib).abc,
            abc_poly,
            line: first.line,
            move_index: first.move_index,
            move_count: (ib - ia).min(u32::MAX as u64) as u32,
            feed,
            design_run_mm: DESIGN_RUN_MM,
            rest_mm: self.v(self.last_idx()).sigma - self.v(ia).sigma,
        }
    }

    /// The tangent and curvature the run ended with (after the final [`Run::emit`]).
    pub fn end_frame(&self) -> Option<EndFrame> {
        self.knot.map(|k| EndFrame {
            tangent: k.t,
            curvature: k.k,
            abc_d: k.da,
            abc_dd: k.dda,
        })
    }

    /// Drops vertices no future knot window can reach, once the buffer has grown by
    /// [`DROP_ABOVE`] since the last drop (so the work is amortised over the pushes).
    fn drop_behind(&mut self) {
        let Some(knot) = self.knot else { return };
        if self.verts.len() <= self.drop_at {
            return;
        }
        let s_knot = self.v(knot.idx).sigma;
        let mut keep_from = knot.idx.saturating_sub(2).max(self.base);
        while keep_from > self.base && s_knot - self.v(keep_from).sigma <= 2.0 * WINDOW_MM {
            keep_from -= 1;
        }
        let n = (keep_from - self.base) as usize;
        if n > 0 {
            self.verts.drain(..n);
            self.base = keep_from;
        }
        self.drop_at = self.verts.len() + DROP_ABOVE;
    }
}
