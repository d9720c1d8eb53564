//! The toolpath as the plot keeps it: thinned to a distance that doubles when it holds
//! too many points, and traced in the three views.

use super::*;

/// A point of the toolpath, and whether the move that reaches it is a rapid.
pub(super) type PathPoint = ([f64; 3], bool);

/// The directions from a vertex within which the polyline may go on straight: each point
/// since the vertex narrows them to those whose line passes within the tolerance of it
/// (a sleeve), and a point that comes back towards the vertex ends it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Sleeve {
    anchor: (f64, f64),
    /// Direction of the first point beyond the tolerance, and the allowed directions
    /// around it, radians.
    cone: Option<(f64, f64, f64)>,
    /// The farthest a point has been from the anchor.
    reach: f64,
}

impl Sleeve {
    pub(super) fn at(anchor: (f64, f64)) -> Self {
        Sleeve {
            anchor,
            cone: None,
            reach: 0.0,
        }
    }

    /// The sleeve narrowed by `q`, or `None` when the line from the anchor to `q` misses a
    /// point since the anchor by more than `tol`.
    pub(super) fn through(&self, q: (f64, f64), tol: f64) -> Option<Sleeve> {
        let (dx, dy) = (q.0 - self.anchor.0, q.1 - self.anchor.1);
        let d = dx.hypot(dy);
        if d < self.reach - tol {
            return None;
        }
        if d <= tol {
            return Some(*self);
        }
        let half = (tol / d).asin();
        let angle = dy.atan2(dx);
        let cone = match self.cone {
            None => (angle, -half, half),
            Some((axis, lo, hi)) => {
                let mut rel = angle - axis;
                if rel > std::f64::consts::PI {
                    rel -= std::f64::consts::TAU;
                } else if rel < -std::f64::consts::PI {
                    rel += std::f64::consts::TAU;
                }
                if rel < lo || rel > hi {
                    return None;
                }
                (axis, lo.max(rel - half), hi.min(rel + half))
            }
        };
        Some(Sleeve {
            anchor: self.anchor,
            cone: Some(cone),
            reach: self.reach.max(d),
        })
    }
}

/// Thins a polyline as its points come: a point is kept (a vertex) where the line from the
/// last vertex would pass farther than `tol` from a point in between, in any of the
/// `planes` (pairs of coordinates, each scaled), and where the kind of move changes.
#[derive(Debug)]
pub(super) struct Thinner<const N: usize> {
    pub(super) tol: f64,
    planes: [(usize, usize, f64, f64); N],
    sleeves: Option<[Sleeve; N]>,
    prev: Option<PathPoint>,
    out: Vec<PathPoint>,
}

impl<const N: usize> Thinner<N> {
    pub(super) fn new(tol: f64, planes: [(usize, usize, f64, f64); N]) -> Self {
        Thinner {
            tol,
            planes,
            sleeves: None,
            prev: None,
            out: Vec::new(),
        }
    }

    pub(super) fn project(&self, p: &[f64; 3], k: usize) -> (f64, f64) {
        let (h, v, sh, sv) = self.planes[k];
        (p[h] * sh, p[v] * sv)
    }

    pub(super) fn vertex(&mut self, p: PathPoint) {
        self.out.push(p);
        self.sleeves = Some(std::array::from_fn(|k| Sleeve::at(self.project(&p.0, k))));
    }

    pub(super) fn push(&mut self, p: PathPoint) {
        let Some(prev) = self.prev else {
            self.vertex(p);
            self.prev = Some(p);
            return;
        };
        if p.1 != prev.1 {
            if self.out.last() != Some(&prev) {
                self.vertex(prev);
            }
            self.vertex(p);
            self.prev = Some(p);
            return;
        }
        for attempt in 0..2 {
            let Some(sleeves) = self.sleeves else {
                break;
            };
            let mut next = sleeves;
            let mut fits = true;
            for (k, s) in sleeves.iter().enumerate() {
                match s.through(self.project(&p.0, k), self.tol) {
                    Some(n) => next[k] = n,
                    None => fits = false,
                }
            }
            if fits {
                self.sleeves = Some(next);
                break;
            }
            if attempt == 0 && self.out.last() != Some(&prev) {
                // The previous point is a corner: the sleeves start again there.
                self.vertex(prev);
            } else {
                self.vertex(p);
                break;
            }
        }
        self.prev = Some(p);
    }

    /// The vertices and the last point.
    pub(super) fn finish(mut self) -> Vec<PathPoint> {
        if let Some(p) = self.prev
            && self.out.last() != Some(&p)
        {
            self.out.push(p);
        }
        self.out
    }
}

/// The three views of the path, in mm.
pub(super) const VIEWS_MM: [(usize, usize, f64, f64); 3] =
    [(0, 1, 1.0, 1.0), (0, 2, 1.0, 1.0), (1, 2, 1.0, 1.0)];

/// The toolpath, thinned as it comes to `tol_mm` in the three views (the tolerance
/// doubles, and the points kept are thinned again, whenever more than
/// [`MAX_PATH_POINTS`] are kept).
#[derive(Debug)]
pub(super) struct Trace {
    pub(super) thinner: Thinner<3>,
}

impl Trace {
    pub(super) fn new() -> Self {
        Trace {
            thinner: Thinner::new(1e-3, VIEWS_MM),
        }
    }

    pub(super) fn push(&mut self, position: [f64; 3], rapid: bool) {
        self.thinner.push((position, rapid));
        while self.thinner.out.len() > MAX_PATH_POINTS {
            let tol = self.thinner.tol * 2.0;
            let mut again = Thinner::new(tol, VIEWS_MM);
            for p in &self.thinner.out {
                again.push(*p);
            }
            let mut kept = again.finish();
            // Thinning goes on from the last point seen.
            let prev = self.thinner.prev;
            if let Some(p) = prev
                && kept.last() == Some(&p)
            {
                kept.pop();
            }
            let mut next = Thinner::new(tol, VIEWS_MM);
            for p in kept {
                next.push(p);
            }
            if let Some(p) = prev {
                next.push(p);
            }
            self.thinner = next;
        }
    }

    /// The points kept and the last one.
    pub(super) fn all(&self) -> Vec<PathPoint> {
        let mut v = self.thinner.out.clone();
        if let Some(p) = self.thinner.prev
            && v.last() != Some(&p)
        {
            v.push(p);
        }
        v
    }

    /// Points kept.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.thinner.out.len()
    }
}
