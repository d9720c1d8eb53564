//! The black box: a ring of the last seconds of cycles, and its CSV export.
//!
//! [`Recorder::new`] allocates the whole ring once (capacity = seconds / period, default
//! [`DEFAULT_SECONDS`]); [`Recorder::record`] is called in the real-time cycle and only
//! copies a [`CycleRecord`] into the ring, overwriting the oldest once it is full: it
//! never allocates, locks or blocks. [`Recorder::dump`] writes the ring as CSV; it
//! formats and does I/O, so it must run outside the real-time cycle (on a copy of the
//! ring, or while the cycle is stopped).

use crate::safety::SafetyState;
use crate::{MAX_AXES, PerAxis};
use kerf_geom::AXIS_NAMES;
use std::io::Write;

/// Default length of the ring, s.
pub const DEFAULT_SECONDS: f64 = 10.0;

/// One cycle as the black box keeps it. Lengths are mm for X, Y, Z and deg for A, B, C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleRecord {
    /// Cycle sequence number.
    pub sequence: u64,
    /// Time of the cycle, s (the cycle's clock, simulated or real).
    pub time_s: f64,
    /// Commanded position per axis.
    pub commanded: PerAxis<f64>,
    /// Actual position per axis.
    pub actual: PerAxis<f64>,
    /// Following error per axis (commanded − actual as the drive or safety layer saw it).
    pub following_error: PerAxis<f64>,
    /// CiA 402 controlword (0x6040) sent to each drive.
    pub controlword: PerAxis<u16>,
    /// CiA 402 statusword (0x6041) read from each drive.
    pub statusword: PerAxis<u16>,
    /// State of the safety layer.
    pub state: SafetyState,
}

impl Default for CycleRecord {
    fn default() -> Self {
        Self {
            sequence: 0,
            time_s: 0.0,
            commanded: [0.0; MAX_AXES],
            actual: [0.0; MAX_AXES],
            following_error: [0.0; MAX_AXES],
            controlword: [0; MAX_AXES],
            statusword: [0; MAX_AXES],
            state: SafetyState::Running,
        }
    }
}

/// A [`Recorder`] size that cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum RecorderError {
    /// Seconds or period not positive and finite, or a capacity of 0 cycles.
    #[error("recorder: {seconds} s at a period of {period_s} s is not a positive number of cycles")]
    Size {
        /// Requested length, s.
        seconds: f64,
        /// Cycle period, s.
        period_s: f64,
    },
}

/// The black-box ring. See the module documentation.
#[derive(Clone, Debug)]
pub struct Recorder {
    ring: Box<[CycleRecord]>,
    /// Index the next record goes to.
    next: usize,
    /// Records held (≤ capacity).
    len: usize,
    /// Axes written to the CSV (those the machine has).
    axes: PerAxis<bool>,
}

impl Recorder {
    /// A ring of `seconds / period_s` cycles (rounded to the nearest), for the axes marked
    /// in `axes`. Allocates the whole ring.
    pub fn new(seconds: f64, period_s: f64, axes: PerAxis<bool>) -> Result<Self, RecorderError> {
        let cycles = (seconds / period_s).round();
        if !(seconds > 0.0 && period_s > 0.0 && cycles.is_finite() && cycles >= 1.0) {
            return Err(RecorderError::Size { seconds, period_s });
        }
        // A finite, positive count of cycles; `as` saturates for absurd sizes, which the
        // allocation below then refuses.
        let capacity = cycles as usize;
        Ok(Self::with_capacity(capacity, axes))
    }

    /// A ring of exactly `capacity` (at least 1) cycles.
    pub fn with_capacity(capacity: usize, axes: PerAxis<bool>) -> Self {
        Self {
            ring: vec![CycleRecord::default(); capacity.max(1)].into_boxed_slice(),
            next: 0,
            len: 0,
            axes,
        }
    }

    /// Cycles the ring holds when full.
    pub fn capacity(&self) -> usize {
        self.ring.len()
    }

    /// Cycles held now.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing was recorded yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Keeps `record`, overwriting the oldest once full. Allocation-free (real-time cycle).
    pub fn record(&mut self, record: &CycleRecord) {
        self.ring[self.next] = *record;
        self.next = (self.next + 1) % self.ring.len();
        self.len = (self.len + 1).min(self.ring.len());
    }

    /// Forgets every record (keeps the allocation).
    pub fn clear(&mut self) {
        self.next = 0;
        self.len = 0;
    }

    /// The ring index of the oldest record held (for [`Recorder::copy_into`]).
    pub fn oldest_index(&self) -> usize {
        let cap = self.ring.len();
        (self.next + cap - self.len) % cap
    }

    /// Appends to `into` the `n` records at ring indices `from`, `from + 1`, … (modulo the
    /// capacity): a chunk of a copy of this ring started at [`Recorder::oldest_index`].
    /// Copies only; allocation-free (the real-time cycle copies the black box a chunk per
    /// cycle while it keeps recording).
    pub fn copy_into(&self, from: usize, n: usize, into: &mut Recorder) {
        let cap = self.ring.len();
        for k in 0..n {
            into.record(&self.ring[(from + k) % cap]);
        }
    }

    /// The records held, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &CycleRecord> {
        let cap = self.ring.len();
        let start = (self.next + cap - self.len) % cap;
        (0..self.len).map(move |k| &self.ring[(start + k) % cap])
    }

    /// The CSV header: `sequence,time_s,state`, then per axis the commanded and actual
    /// position, the following error, the controlword and the statusword, each column
    /// named with its axis and unit (e.g. `x_cmd_mm`, `a_ferror_deg`).
    pub fn header(&self) -> String {
        let mut h = String::from("sequence,time_s,state");
        for (i, name) in AXIS_NAMES.iter().enumerate() {
            if !self.axes[i] {
                continue;
            }
            let n = name.to_ascii_lowercase();
            let u = if i < 3 { "mm" } else { "deg" };
            h.push_str(&format!(
                ",{n}_cmd_{u},{n}_act_{u},{n}_ferror_{u},{n}_controlword,{n}_statusword"
            ));
        }
        h
    }

    /// Writes the header and every record, oldest first, as CSV. Positions are written in
    /// Rust's shortest round-trip form (reading them back gives the same `f64`), the
    /// words as `0x` and four hex digits. Formats and does I/O: never call it in the
    /// real-time cycle.
    pub fn dump<W: Write>(&self, mut out: W) -> std::io::Result<()> {
        writeln!(out, "{}", self.header())?;
        for r in self.iter() {
            write!(out, "{},{},{}", r.sequence, r.time_s, r.state.name())?;
            for i in (0..MAX_AXES).filter(|&i| self.axes[i]) {
                write!(
                    out,
                    ",{},{},{},0x{:04x},0x{:04x}",
                    r.commanded[i],
                    r.actual[i],
                    r.following_error[i],
                    r.controlword[i],
                    r.statusword[i]
                )?;
            }
            writeln!(out)?;
        }
        out.flush()
    }
}
