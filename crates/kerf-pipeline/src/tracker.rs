//! The programmed moves around the setpoints ([`Tracker`]): the move each setpoint is
//! passing and its distance from the programmed path.

use std::collections::VecDeque;

use kerf_geom::{Curve, Helix, Move, Path, Vec3, line_distance};
use kerf_motion::Setpoint;

/// The programmed moves around the setpoints, allocation-free once its capacity is
/// reserved: finds the move a setpoint is passing (on a smoothed piece, which stands for
/// many moves, the one of them nearest to the setpoint) and its distance from the
/// programmed path. `kerf sim` and the daemon both run it on every setpoint, so that the
/// `line` of their setpoints agrees on smoothed curves too.
#[derive(Default)]
pub struct Tracker {
    /// The programmed moves not yet passed (compact: no transition variant). Moves before
    /// the segment being run are dropped, so this holds about the moves of the queued
    /// segments, whatever the program's length.
    curves: VecDeque<Programmed>,
    /// Source line of every move in `curves`.
    lines: VecDeque<u32>,
    /// A box around each block of [`BLOCK_MOVES`] moves (program indices
    /// `b·BLOCK_MOVES ..`, from block `block_base` on) that holds all of their points: the
    /// search for the nearest move of a piece skips a block whose box is farther from the
    /// setpoint than the nearest move found so far.
    blocks: VecDeque<Bounds>,
    /// Program index of `curves[0]`.
    base: usize,
    /// Block number of `blocks[0]`.
    block_base: usize,
    /// The move named for the last setpoint on a smoothed piece: where the search starts
    /// (the setpoints advance, so it is usually near), never a limit on it.
    cursor: usize,
}

/// What a cycle does with the next programmed move ([`Tracker::taking`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Taking {
    /// Add it to the tracker.
    Track,
    /// Pass it without tracking it.
    Untracked,
    /// Leave it (and the segment that needs it) for a later cycle: the tracker is full.
    Wait,
}

/// Moves kept before the first move of the segment being run, for the deviation check
/// (it looks one back; the rest is a margin).
pub(crate) const MOVES_KEPT_BEHIND: usize = 16;

/// Programmed moves per block of the tracker's search.
const BLOCK_MOVES: usize = 16;

/// An axis-aligned box that holds every point of a few programmed moves.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    lo: Vec3,
    hi: Vec3,
}

impl Bounds {
    /// Grows the box to hold `other`.
    fn merge(&mut self, other: &Bounds) {
        self.lo = self.lo.inf(&other.lo);
        self.hi = self.hi.sup(&other.hi);
    }

    /// The square of the distance from `p` to the nearest point of the box.
    fn gap2(&self, p: &Vec3) -> f64 {
        let mut gap2 = 0.0;
        for i in 0..3 {
            let g = (self.lo[i] - p[i]).max(p[i] - self.hi[i]).max(0.0);
            gap2 += g * g;
        }
        gap2
    }
}

impl Tracker {
    /// A tracker that holds `moves` moves without allocating.
    pub fn with_capacity(moves: usize) -> Tracker {
        Tracker {
            curves: VecDeque::with_capacity(moves),
            lines: VecDeque::with_capacity(moves),
            // The moves `base ..` span at most this many blocks.
            blocks: VecDeque::with_capacity(moves / BLOCK_MOVES + 2),
            base: 0,
            block_base: 0,
            cursor: 0,
        }
    }

    /// `true` while it holds no move.
    pub fn is_empty(&self) -> bool {
        self.curves.is_empty()
    }

    /// `true` when one more move would make it allocate.
    pub fn is_full(&self) -> bool {
        self.curves.len() >= self.curves.capacity()
            || self.lines.len() >= self.lines.capacity()
            || self.blocks.len() >= self.blocks.capacity()
    }

    /// What a cycle does with the next programmed move before the planned items that
    /// need it: the one rule of the daemon's cycle and the offline runs, so that both
    /// name the same lines. `queue_empty`: no segment queued, not even a running one;
    /// `aborted`: the program was aborted (nothing more runs, so no more moves are
    /// needed once the tracker holds one).
    pub fn taking(&self, queue_empty: bool, aborted: bool) -> Taking {
        if self.is_full() {
            // Full, the queue counts as full: the motion runs on, and the tracker empties
            // as it passes the moves. With nothing queued it would never empty; the
            // planner's pieces never fill it so (see `TRACKED_MOVES_EXTRA`), and should
            // anything else, the move is passed untracked rather than hold the motion.
            if queue_empty {
                Taking::Untracked
            } else {
                Taking::Wait
            }
        } else if aborted && !self.is_empty() {
            Taking::Untracked
        } else {
            Taking::Track
        }
    }

    /// Forgets every move (a new program; the capacity stays).
    pub fn clear(&mut self) {
        self.curves.clear();
        self.lines.clear();
        self.blocks.clear();
        self.base = 0;
        self.block_base = 0;
        self.cursor = 0;
    }

    /// Appends the next programmed move (program order).
    pub fn add(&mut self, mv: &Move) {
        let curve = Programmed::new(&mv.path);
        let bounds = curve.bounds();
        let block = (self.base + self.curves.len()) / BLOCK_MOVES;
        if self.blocks.is_empty() {
            self.block_base = block;
        }
        let open = block < self.block_base + self.blocks.len();
        match self.blocks.back_mut() {
            Some(b) if open => b.merge(&bounds),
            _ => self.blocks.push_back(bounds),
        }
        self.curves.push_back(curve);
        self.lines.push_back(mv.line);
    }

    /// For a setpoint on a smoothed piece, sets its line and move to the programmed move
    /// of the piece nearest to it (the earlier one of equally near moves); returns the
    /// setpoint's distance from the programmed moves (`None` while no move is known).
    /// Drops the moves before the segment being run.
    pub fn track(&mut self, sp: &mut Setpoint) -> Option<f64> {
        if self.curves.is_empty() {
            return None;
        }
        let p = Vec3::new(sp.position[0], sp.position[1], sp.position[2]);
        let first = sp.move_index as usize;
        let (d, k) = self.nearest_move(&p, sp.move_index, sp.move_count);
        if sp.move_count > 1 {
            // A smoothed piece stands for several moves: report the one being passed.
            sp.line = self.lines[k - self.base];
            sp.move_index = k as u64;
            sp.move_count = 1;
        }
        // The segments run in program order: the moves before this one's are never looked
        // at again.
        let keep_from = first.saturating_sub(1 + MOVES_KEPT_BEHIND);
        while self.base < keep_from && self.curves.len() > 1 {
            self.curves.pop_front();
            self.lines.pop_front();
            self.base += 1;
            if (self.block_base + 1) * BLOCK_MOVES <= self.base {
                self.blocks.pop_front();
                self.block_base += 1;
            }
        }
        Some(d)
    }

    /// Distance from `p` to the moves `move_index - 1 ..= move_index + count` (the segment's
    /// own moves and its neighbours, whose corners a blend may cut), and the move the
    /// setpoint is passing: the segment's move, or on a smoothed piece (`count` > 1) the
    /// nearest of its own moves `move_index .. move_index + count`, the earliest of equally
    /// near ones. That search is exact: it starts from the move named last (a close
    /// candidate) and skips only the blocks of moves that lie wholly farther away than the
    /// nearest found, wherever the moves go (a polyline may turn back towards the setpoint:
    /// trochoidal loops, hairpins). The distance is a minimum over moves of the program,
    /// so it is never less than the true distance.
    fn nearest_move(&mut self, p: &Vec3, move_index: u64, count: u32) -> (f64, usize) {
        // Program indices; `curves` holds `base ..= last`.
        let last = self.base + self.curves.len() - 1;
        let i = (move_index as usize).clamp(self.base, last);
        let lo = i.saturating_sub(1).max(self.base);
        let hi = (i + count.max(1) as usize).min(last);
        let curve = |k: usize| &self.curves[k - self.base];
        if count <= 1 {
            let mut best = f64::INFINITY;
            for k in lo..=(i + 1).min(hi) {
                best = best.min(curve(k).distance_to(p));
            }
            return (best, i);
        }
        // A piece: its own moves `i ..= end`, then its neighbours for the distance. The
        // move named last is a close candidate to start from; a block or move whose box
        // lies farther away than the nearest so far is passed over. The slack covers the
        // rounding of the boxes' distances and of the moves' own, far below any distance
        // that matters, so no move as near as the nearest is ever passed over.
        let end = (i + count as usize - 1).min(last);
        let slack = 1e-9 + 1e-14 * (p.x.abs() + p.y.abs() + p.z.abs());
        let beyond = |b: &Bounds, d: f64| b.gap2(p) > (d + slack) * (d + slack);
        let mut best = (f64::INFINITY, i);
        if (i..=end).contains(&self.cursor) {
            best = (curve(self.cursor).distance_to(p), self.cursor);
        }
        // `blocks` starts at or before the block of `base`, and holds that of `last`.
        let blocks = (i / BLOCK_MOVES - self.block_base)..=(end / BLOCK_MOVES - self.block_base);
        for (b, bounds) in self.blocks.range(blocks).enumerate() {
            if beyond(bounds, best.0) {
                continue;
            }
            let block = i / BLOCK_MOVES + b;
            for k in (block * BLOCK_MOVES).max(i)..=((block + 1) * BLOCK_MOVES - 1).min(end) {
                let c = curve(k);
                if beyond(&c.bounds(), best.0) {
                    continue;
                }
                let d = c.distance_to(p);
                if d < best.0 || (d == best.0 && k < best.1) {
                    best = (d, k);
                }
            }
        }
        self.cursor = best.1;
        let mut d = best.0.min(curve(lo).distance_to(p));
        if hi > end {
            d = d.min(curve(hi).distance_to(p));
        }
        (d, best.1)
    }
}

/// A programmed move's path as the deviation check needs it (no transition variant, and a
/// line without its derived direction and length). Not boxed: the daemon's tracker must
/// not allocate.
#[allow(clippy::large_enum_variant)]
enum Programmed {
    /// Start and end; the direction and length are derived as in [`Curve::line`].
    Line(Vec3, Vec3),
    Helix(Helix),
}

impl Programmed {
    fn new(path: &Path) -> Programmed {
        match Curve::from_path(path) {
            Curve::Helix(h) => Programmed::Helix(h),
            Curve::Line { start, end, .. } => Programmed::Line(start, end),
            Curve::Transition(_) => unreachable!("a programmed path is a line or an arc"),
        }
    }

    /// A box that holds every point of the move: a line's ends, the points within a
    /// helix's length of its start.
    fn bounds(&self) -> Bounds {
        match self {
            Programmed::Line(start, end) => Bounds {
                lo: start.inf(end),
                hi: start.sup(end),
            },
            Programmed::Helix(h) => {
                let r = Vec3::repeat(h.length_mm);
                Bounds {
                    lo: h.start - r,
                    hi: h.start + r,
                }
            }
        }
    }

    fn distance_to(&self, p: &Vec3) -> f64 {
        match self {
            Programmed::Line(start, end) => {
                // Exactly as `Curve::line` derives them.
                let delta = end - start;
                let length = delta.norm();
                let dir = if length > 0.0 {
                    delta / length
                } else {
                    Vec3::zeros()
                };
                line_distance(start, end, &dir, length, p)
            }
            Programmed::Helix(h) => h.distance_to(p),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tracker holding the lines through `points`, move `k` on source line `k + 1`.
    fn tracker_of(points: &[[f64; 2]]) -> Tracker {
        let mut t = Tracker::with_capacity(64);
        for (k, w) in points.windows(2).enumerate() {
            t.add(&line_move(k, w[0], w[1]));
        }
        t
    }

    /// Move `k` (on source line `k + 1`), the line from `a` to `b`.
    fn line_move(k: usize, a: [f64; 2], b: [f64; 2]) -> Move {
        Move {
            line: k as u32 + 1,
            rapid: false,
            path: Path::Line(kerf_geom::Line {
                start: Vec3::new(a[0], a[1], 0.0),
                end: Vec3::new(b[0], b[1], 0.0),
            }),
            feed_mm_min: Some(600.0),
            abc_deg: None,
            corner: kerf_geom::CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        }
    }

    /// Tracks a setpoint at `(x, y)` on a smoothed piece of `count` moves from `first`:
    /// the line named and the distance.
    fn track_at(t: &mut Tracker, x: f64, y: f64, first: u64, count: u32) -> (u32, f64) {
        let mut sp = Setpoint {
            position: [x, y, 0.0, 0.0, 0.0, 0.0],
            line: first as u32 + 1,
            move_index: first,
            move_count: count,
            feed_mm_s: 1.0,
            rapid: false,
        };
        let d = t.track(&mut sp).unwrap();
        assert_eq!((sp.move_index, sp.move_count), (u64::from(sp.line) - 1, 1));
        (sp.line, d)
    }

    /// The taking rule: moves are tracked until the tracker is full; full, they wait while
    /// a segment is queued (the motion runs on and frees room) and pass untracked with
    /// nothing queued (room would never come); after an abort one move is enough.
    #[test]
    fn moves_are_tracked_until_full_then_wait_for_the_motion_unless_nothing_is_queued() {
        let empty = Tracker::with_capacity(64);
        assert_eq!(empty.taking(false, false), Taking::Track);
        assert_eq!(empty.taking(true, false), Taking::Track);
        assert_eq!(
            empty.taking(false, true),
            Taking::Track,
            "one move after an abort"
        );
        let points: Vec<[f64; 2]> = (0..200).map(|k| [f64::from(k), 0.0]).collect();
        let mut t = tracker_of(&points[..3]);
        assert_eq!(t.curves.len(), 2);
        assert_eq!(t.taking(false, false), Taking::Track);
        assert_eq!(
            t.taking(true, true),
            Taking::Untracked,
            "not needed after an abort"
        );
        // Filled move by move to its capacity (at least the 64 asked for).
        let mut added = 0;
        while t.taking(false, false) == Taking::Track {
            t.add(&line_move(added, points[added], points[added + 1]));
            added += 1;
            assert!(added < 199, "never full");
        }
        assert!(t.is_full() && t.curves.len() >= 64, "{added}");
        assert_eq!(t.taking(false, false), Taking::Wait);
        assert_eq!(t.taking(true, false), Taking::Untracked);
        assert_eq!(t.taking(false, true), Taking::Wait);
    }

    #[test]
    fn the_tracker_names_the_nearest_move_of_the_piece_the_earlier_of_equal_ones() {
        // A meander, move k on line k + 1: 0 (0,0)→(1,0), 1 →(1,1), 2 →(0,1), 3 →(0,2),
        // 4 →(1,2), 5 →(1,3), 6 →(0,3).
        let pts = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 2.0]];
        let pts = [&pts[..], &[[1.0, 2.0], [1.0, 3.0], [0.0, 3.0]]].concat();
        let mut t = tracker_of(&pts);
        // A piece from move 1 standing for moves 1 to 3. (0.5, 0.5) is 0.5 mm from moves 1
        // and 2, and from move 0 before the piece (never named): the earlier, move 1.
        // (0.5, 1.5) is 0.5 mm from moves 2 and 3, and from move 4 after it: move 2.
        assert_eq!(track_at(&mut t, 0.5, 0.5, 1, 3), (2, 0.5));
        assert_eq!(track_at(&mut t, 0.5, 1.5, 1, 3), (3, 0.5));
        // Nearer to move 4, the next piece's, than to any of its own: its own nearest is
        // named; the distance counts the neighbour.
        assert_eq!(track_at(&mut t, 0.25, 1.875, 1, 3), (4, 0.125));
        // Back towards an earlier move of the piece than the one named last.
        assert_eq!(track_at(&mut t, 0.875, 0.5, 1, 3), (2, 0.125));
        // A piece of six moves from move 1: the nearest of all six, wherever the last one
        // named was.
        assert_eq!(track_at(&mut t, 0.5, 2.875, 1, 6), (7, 0.125));
        assert_eq!(track_at(&mut t, 0.5, 0.875, 1, 6), (3, 0.125));
    }

    #[test]
    fn the_tracker_search_is_exact_over_many_blocks() {
        // A spiral of 400 short moves turning back past itself: every setpoint on a piece
        // of all of them is named after its nearest move, found by brute force.
        let pts: Vec<[f64; 2]> = (0..=400)
            .map(|k| {
                let a = k as f64 * 0.05;
                let r = 1.0 + 0.002 * k as f64;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let mut t = tracker_of(&pts);
        let distance = |k: usize, p: Vec3| {
            let (a, b) = (pts[k], pts[k + 1]);
            Curve::line(Vec3::new(a[0], a[1], 0.0), Vec3::new(b[0], b[1], 0.0)).distance_to(&p)
        };
        for n in 0..2000 {
            let a = n as f64 * 0.01;
            let (x, y) = (1.1 * a.cos() + 0.3, 1.1 * a.sin());
            let p = Vec3::new(x, y, 0.0);
            let (line, d) = track_at(&mut t, x, y, 1, 399);
            let (k, dk) = (1..400)
                .map(|k| (k, distance(k, p)))
                .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
            assert_eq!(line as usize, k + 1, "setpoint {n}");
            assert!(d <= dk, "setpoint {n}");
        }
    }
}
