//! The plot of `kerf sim --plot FILE.svg|FILE.png`: what a person looks at to understand a
//! slow or rough program.
//!
//! Drawn with `plotters`, as SVG or PNG ([`PlotFormat`], chosen by the file's extension):
//!
//! - the toolpath seen from above (XY, equal scales) and from the front (XZ) and the side
//!   (YZ), rapids and feed moves in different colours, so that drilling and 3D surfaces show;
//! - the path feed over time (s), rapids and feed moves in the same colours;
//! - for every axis its velocity, acceleration and jerk over time (finite differences of the
//!   setpoints at the period, as the limit monitor measures them) with the limit lines.
//!
//! Every time series is an envelope: for each column of time it draws the minimum and the
//! maximum of the samples in it (and shades between them), so a dip of the feed to zero or a
//! one-period spike of jerk is never hidden however long the program.
//!
//! The recorder ([`PlotRecorder`]) aggregates while the simulation runs, in memory that
//! does not grow with the program's time: at most [`BUCKETS`] columns of time (each a
//! power-of-two number of periods; when the time outgrows them, neighbours are merged and
//! the width doubles), and a toolpath thinned to a distance that doubles whenever it holds
//! more than `MAX_PATH_POINTS` points.

use kerf_geom::PerAxis;
use std::io::{self, Write};
use std::path::Path;

use kerf_motion::{MachineLimits, Setpoint};
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

mod draw;
mod path;

use path::{Thinner, Trace};

/// The image format of a plot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlotFormat {
    /// Scalable vector graphics (text stays text).
    Svg,
    /// A PNG image, 8-bit RGB.
    Png,
}

/// A plot file name that ends in neither `.svg` nor `.png`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the plot format is chosen by the file name, which must end in .svg or .png")]
pub struct PlotFormatError;

impl PlotFormat {
    /// The format of `path` by its extension (`.svg` or `.png`, any case); `-` (standard
    /// output) is SVG.
    pub fn of_path(path: &Path) -> Result<PlotFormat, PlotFormatError> {
        if path.as_os_str() == "-" {
            return Ok(PlotFormat::Svg);
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("svg") => Ok(PlotFormat::Svg),
            Some("png") => Ok(PlotFormat::Png),
            _ => Err(PlotFormatError),
        }
    }
}

/// Where a plot goes and in which format.
pub struct PlotOutput<'a> {
    /// The image format.
    pub format: PlotFormat,
    /// The output.
    pub out: &'a mut dyn Write,
    /// What the title names (the program).
    pub title: String,
}

/// Columns of time at most: more than the widest panel has pixels.
pub const BUCKETS: usize = 2048;

/// Points of the thinned toolpath at most before it is thinned further.
pub(crate) const MAX_PATH_POINTS: usize = 100_000;

/// Series of a bucket: the path feed, then per axis (X … C) velocity, acceleration, jerk.
const CHANNELS: usize = 1 + 6 * 3;

/// The channel of the path feed.
const FEED: usize = 0;

/// The channel of `quantity` (0 velocity, 1 acceleration, 2 jerk) of `axis`.
const fn channel(axis: usize, quantity: usize) -> usize {
    1 + axis * 3 + quantity
}

/// Minimum and maximum of every series over some consecutive periods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bucket {
    lo: [f64; CHANNELS],
    hi: [f64; CHANNELS],
    /// A sample of a rapid move is in it.
    pub rapid: bool,
    /// A sample of a feed move is in it.
    pub cut: bool,
}

impl Bucket {
    fn empty() -> Self {
        Bucket {
            lo: [f64::INFINITY; CHANNELS],
            hi: [f64::NEG_INFINITY; CHANNELS],
            rapid: false,
            cut: false,
        }
    }

    fn merge(&mut self, other: &Bucket) {
        for c in 0..CHANNELS {
            self.lo[c] = self.lo[c].min(other.lo[c]);
            self.hi[c] = self.hi[c].max(other.hi[c]);
        }
        self.rapid |= other.rapid;
        self.cut |= other.cut;
    }

    /// The smallest and the largest path feed in it, mm/s.
    pub fn feed_mm_s(&self) -> (f64, f64) {
        (self.lo[FEED], self.hi[FEED])
    }

    /// The smallest and the largest of `quantity` (0 velocity, 1 acceleration, 2 jerk) of
    /// `axis` (0 = X … 5 = C) in it, in mm (degrees) per s, s², s³.
    pub fn axis(&self, axis: usize, quantity: usize) -> (f64, f64) {
        let c = channel(axis, quantity);
        (self.lo[c], self.hi[c])
    }
}

/// Whether each move is a rapid, by program index: the indices where that changes.
#[derive(Debug, Default)]
pub struct RapidIndex {
    /// Move indices at which the kind flips (starting from "feed" before move 0).
    flips: Vec<u64>,
    /// Moves seen so far, and whether the last was a rapid.
    moves: u64,
    last: bool,
}

impl RapidIndex {
    /// Notes the next move of the program, in program order.
    pub fn push(&mut self, rapid: bool) {
        if let Some(at) = self.next_flip(rapid) {
            self.flips.push(at);
        }
    }

    /// Counts the next move of the program, in program order, without keeping it, and
    /// returns its index when its kind differs from the move before (the flip to hand to
    /// the recorder of a run fed on another thread).
    pub(crate) fn next_flip(&mut self, rapid: bool) -> Option<u64> {
        let at = (rapid != self.last).then_some(self.moves);
        self.last = rapid;
        self.moves += 1;
        at
    }

    /// Notes a flip at `index` (from [`RapidIndex::push`] on another thread).
    fn flip_at(&mut self, index: u64) {
        self.flips.push(index);
    }

    /// Whether move `index` is a rapid.
    pub fn is_rapid(&self, index: u64) -> bool {
        self.flips.partition_point(|&f| f <= index) % 2 == 1
    }
}

/// Collects what the plot shows while the simulation runs.
#[derive(Debug)]
pub struct PlotRecorder {
    limits: MachineLimits,
    /// The last four positions, newest first (at rest at the origin before the first).
    hist: [PerAxis<f64>; 4],
    /// Samples seen.
    samples: u64,
    /// Periods per bucket (a power of two).
    per_bucket: u64,
    buckets: Vec<Bucket>,
    trace: Trace,
    rapids: RapidIndex,
    /// Flips of the rapid index sent by the thread that reads the moves.
    flips: Option<std::sync::mpsc::Receiver<u64>>,
    rotary_used: bool,
}

impl PlotRecorder {
    /// A recorder for a run on `limits` whose moves are rapids as `rapids` says (filled
    /// now, or later through `PlotRecorder::flips_from`).
    pub fn new(limits: &MachineLimits, rapids: RapidIndex) -> Self {
        PlotRecorder {
            limits: *limits,
            hist: [[0.0; 6]; 4],
            samples: 0,
            per_bucket: 1,
            buckets: Vec::with_capacity(BUCKETS),
            trace: Trace::new(),
            rapids,
            flips: None,
            rotary_used: false,
        }
    }

    /// Takes the flips of the rapid index from `rx` as they come (the moves are read on
    /// another thread, always before their setpoints).
    pub(crate) fn flips_from(&mut self, rx: std::sync::mpsc::Receiver<u64>) {
        self.flips = Some(rx);
    }

    /// Records the setpoint of the next period (the first at t = 0).
    pub fn push(&mut self, sp: &Setpoint) {
        if let Some(rx) = &self.flips {
            for f in rx.try_iter() {
                self.rapids.flip_at(f);
            }
        }
        let rapid = self.rapids.is_rapid(sp.move_index);
        self.hist.rotate_right(1);
        self.hist[0] = sp.position;
        let dt = self.limits.period_s;
        let mut b = Bucket::empty();
        b.rapid = rapid;
        b.cut = !rapid;
        b.lo[FEED] = sp.feed_mm_s;
        b.hi[FEED] = sp.feed_mm_s;
        for i in 0..6 {
            if self.limits.axes[i].is_none() {
                continue;
            }
            let h = |k: usize| self.hist[k][i];
            let q = [
                (h(0) - h(1)) / dt,
                (h(0) - 2.0 * h(1) + h(2)) / (dt * dt),
                (h(0) - 3.0 * h(1) + 3.0 * h(2) - h(3)) / (dt * dt * dt),
            ];
            for (k, v) in q.into_iter().enumerate() {
                b.lo[channel(i, k)] = v;
                b.hi[channel(i, k)] = v;
            }
            if i >= 3 && sp.position[i] != 0.0 {
                self.rotary_used = true;
            }
        }
        let mut index = self.samples / self.per_bucket;
        while index as usize >= BUCKETS {
            self.halve();
            index = self.samples / self.per_bucket;
        }
        let index = index as usize;
        if index == self.buckets.len() {
            self.buckets.push(b);
        } else {
            self.buckets[index].merge(&b);
        }
        self.samples += 1;
        let p = sp.position;
        self.trace.push([p[0], p[1], p[2]], rapid);
    }

    /// Merges neighbouring buckets: twice the periods each.
    fn halve(&mut self) {
        let merged: Vec<Bucket> = self
            .buckets
            .chunks(2)
            .map(|pair| {
                let mut b = pair[0];
                if let Some(second) = pair.get(1) {
                    b.merge(second);
                }
                b
            })
            .collect();
        self.buckets = merged;
        self.per_bucket *= 2;
    }

    /// The columns of time, each of the same number of periods, from t = 0
    /// (the last may hold fewer).
    pub fn buckets(&self) -> &[Bucket] {
        &self.buckets
    }

    /// Periods in each bucket.
    #[cfg(test)]
    pub(crate) fn periods_per_bucket(&self) -> u64 {
        self.per_bucket
    }
}

#[cfg(test)]
mod tests;
