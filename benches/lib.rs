//! Shared helpers for the benchmarks: a generator of large, valid LinuxCNC programs.
//!
//! The generated program imitates dense CAM output: short G1 lines and quarter-circle
//! G2/G3 arcs in equal numbers, three decimals per coordinate, zig-zagging over a
//! 100 x 100 mm field. Every arc has its centre exactly one radius from both ends, so the
//! program is valid in any dialect tolerance, and the whole program is deterministic.
//! It is used by the criterion benches (in memory) and by the `gen_program` binary (for
//! the memory test on a program of a gigabyte, see docs/PERFORMANCE.md).
//!
//! The CAM benchmark of issue 11 lives in four modules: [`cam`] (the corpus of
//! generated CAM programs with their exact geometry), [`bound`] (the acceleration-limited
//! time-optimal lower bound), [`jerk`] (the jerk-limited one, issue 31) and [`measure`]
//! (Kerf's run, the feed time and the table the `cam_table` binary prints); [`pointwise`]
//! is a prototype of a motion core that checks each point of the path at its own speed,
//! [`swept`] the random machines and paths it is tested and measured on.
#![deny(missing_docs)]

#[path = "src/bound.rs"]
pub mod bound;
#[path = "src/cam.rs"]
pub mod cam;
#[path = "src/jerk.rs"]
pub mod jerk;
#[path = "src/measure.rs"]
pub mod measure;
#[path = "src/pointwise.rs"]
pub mod pointwise;
#[path = "src/swept.rs"]
pub mod swept;

use std::io::{self, Write};

/// Side of the square field the tool path covers, mm.
const FIELD_MM: i64 = 100;

/// A fixed fractional offset so that every coordinate is printed with decimals, as CAM
/// output is, while staying exactly representable in binary.
const OFFSET_MM: f64 = 0.125;

/// The writer's state: where the tool is (in whole millimetres before the offset) and
/// which way the current row runs.
struct Walker {
    x: i64,
    y: i64,
    forward: bool,
}

/// Writes a LinuxCNC program of exactly `blocks` blocks (lines) to `out`, or stops early
/// once `max_bytes` bytes have been written. Returns the number of blocks and bytes written.
///
/// Every block except the header, the row changes and the closing `M2` is a move: half G1
/// lines, half quarter-circle arcs of radius 1 mm. The last block is `M2` (a LinuxCNC
/// program ends with M2/M30); when `max_bytes` stops the program, the `M2` follows as one
/// block more.
pub fn write_program<W: Write>(out: &mut W, blocks: u64, max_bytes: u64) -> io::Result<(u64, u64)> {
    let mut w = Walker {
        x: 0,
        y: 0,
        forward: true,
    };
    let mut line = String::with_capacity(64);
    let mut written_blocks = 0u64;
    let mut written_bytes = 0u64;
    let mut phase = 0u32;
    while written_blocks < blocks && written_bytes < max_bytes {
        line.clear();
        if written_blocks == 0 {
            line.push_str("G21 G90 G17 G94 F1500\n");
        } else if written_blocks + 1 == blocks {
            line.push_str("M2\n");
        } else {
            phase = w.next_block(&mut line, phase);
        }
        out.write_all(line.as_bytes())?;
        written_blocks += 1;
        written_bytes += line.len() as u64;
    }
    if written_blocks < blocks {
        out.write_all(b"M2\n")?;
        written_blocks += 1;
        written_bytes += 3;
    }
    Ok((written_blocks, written_bytes))
}

/// A generated program of `blocks` blocks in memory.
pub fn program(blocks: u64) -> Vec<u8> {
    let mut buf = Vec::with_capacity(blocks as usize * 28);
    // Writing to a Vec cannot fail.
    let _ = write_program(&mut buf, blocks, u64::MAX);
    buf
}

fn coord(v: i64) -> f64 {
    v as f64 + OFFSET_MM
}

impl Walker {
    /// Appends the block for `phase` and returns the phase of the next block.
    ///
    /// A cycle of four blocks (line, arc up, line, arc down) advances the tool 4 mm along
    /// the row and brings it back to the row's Y. At the end of a row the tool steps 2 mm
    /// to the next row and turns round; when the field is covered a rapid returns it to
    /// the start.
    fn next_block(&mut self, line: &mut String, phase: u32) -> u32 {
        use std::fmt::Write as _;
        let d: i64 = if self.forward { 1 } else { -1 };
        if phase == 0 && !(0..=FIELD_MM).contains(&(self.x + 4 * d)) {
            if self.y + 2 > FIELD_MM {
                self.x = 0;
                self.y = 0;
                self.forward = true;
                let _ = writeln!(line, "G0 X{:.3} Y{:.3}", coord(self.x), coord(self.y));
            } else {
                self.y += 2;
                self.forward = !self.forward;
                let _ = writeln!(line, "G1 Y{:.3}", coord(self.y));
            }
            return 0;
        }
        // Which way the arcs turn depends on the direction of travel: seen from +Z, the
        // arc up from below its centre turns counter-clockwise when running towards +X.
        let (up, down) = if self.forward {
            ("G3", "G2")
        } else {
            ("G2", "G3")
        };
        match phase {
            0 | 2 => {
                self.x += d;
                let _ = writeln!(line, "G1 X{:.3} Y{:.3}", coord(self.x), coord(self.y));
            }
            1 => {
                // The centre is one millimetre above the start.
                self.x += d;
                self.y += 1;
                let _ = writeln!(
                    line,
                    "{up} X{:.3} Y{:.3} I0 J1",
                    coord(self.x),
                    coord(self.y)
                );
            }
            _ => {
                // The centre is one millimetre below the start.
                self.x += d;
                self.y -= 1;
                let _ = writeln!(
                    line,
                    "{down} X{:.3} Y{:.3} I0 J-1",
                    coord(self.x),
                    coord(self.y)
                );
            }
        }
        (phase + 1) % 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads the generated text back with a tiny independent parser and checks that every
    /// arc is a true quarter circle turning the way its G code says, and that the tool stays
    /// inside the field.
    #[test]
    fn generated_arcs_are_exact_quarter_circles() {
        let text = String::from_utf8(program(200_000)).unwrap();
        assert_eq!(text.lines().count(), 200_000);
        let (mut x, mut y) = (0.0f64, 0.0f64);
        let (mut arcs, mut lines) = (0u64, 0u64);
        for block in text.lines().skip(1).filter(|&b| b != "M2") {
            let word = |letter: char| {
                block
                    .split(' ')
                    .find(|w| w.starts_with(letter))
                    .map(|w| w[1..].parse::<f64>().unwrap())
            };
            let g = word('G').unwrap();
            let (nx, ny) = (word('X').unwrap_or(x), word('Y').unwrap_or(y));
            if g == 2.0 || g == 3.0 {
                arcs += 1;
                let (cx, cy) = (x + word('I').unwrap(), y + word('J').unwrap());
                let r_start = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
                let r_end = ((nx - cx).powi(2) + (ny - cy).powi(2)).sqrt();
                assert_eq!((r_start, r_end), (1.0, 1.0), "{block}");
                // The z component of (start - centre) x (end - centre) is +1 for a
                // counter-clockwise quarter (G3) and -1 for a clockwise one (G2).
                let cross = (x - cx) * (ny - cy) - (y - cy) * (nx - cx);
                assert_eq!(cross, if g == 3.0 { 1.0 } else { -1.0 }, "{block}");
            } else {
                lines += 1;
            }
            (x, y) = (nx, ny);
            assert!((0.0..=FIELD_MM as f64 + 2.0).contains(&x), "{block}");
            assert!((0.0..=FIELD_MM as f64 + 2.0).contains(&y), "{block}");
        }
        // About half the blocks are arcs; row changes and returns are lines.
        assert!(
            arcs * 100 / (arcs + lines) >= 45,
            "{arcs} arcs, {lines} lines"
        );
    }

    #[test]
    fn byte_limit_stops_the_program() {
        let mut buf = Vec::new();
        let (blocks, bytes) = write_program(&mut buf, u64::MAX, 10_000).unwrap();
        assert_eq!(bytes, buf.len() as u64);
        assert!((10_000..10_100).contains(&bytes));
        assert_eq!(blocks, buf.iter().filter(|&&b| b == b'\n').count() as u64);
    }
}
