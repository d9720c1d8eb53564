//! Helpers shared by the CAM benchmark's tests (`cam.rs`, `jerk.rs`): pieces of path
//! and a relative comparison.

use kerf_benches::bound::Piece;

/// A line from `start` to `end` at `feed_mm_s`.
pub fn line(start: [f64; 3], end: [f64; 3], feed_mm_s: f64) -> Piece {
    kerf_benches::swept::line(start, end, feed_mm_s)
}

/// A circle in XY of radius `r` about (r, 0, 0), from the origin, `turns` times round.
pub fn circle(r: f64, turns: f64, feed_mm_s: f64) -> Piece {
    kerf_benches::cam::circle_piece(r, turns, feed_mm_s)
}

/// `got` within `rel` of `want`, relative.
pub fn assert_rel(got: f64, want: f64, rel: f64, what: &str) {
    assert!(
        (got - want).abs() <= rel * want.abs(),
        "{what}: got {got}, expected {want} (±{rel:.1e} relative)"
    );
}
