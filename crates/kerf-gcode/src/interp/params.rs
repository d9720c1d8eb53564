//! LinuxCNC numbered parameters #1–#5602: one flat table, owned by the interpreter state,
//! read and written by the expression language and by the codes whose data the manual
//! places in parameters (G10, G28.1, G30.1, G92, tool data, current position).

// The helpers of the codes that keep their data in parameters land one by one.
#![allow(dead_code)]

/// The highest numbered parameter (LinuxCNC's RS274NGC_MAX_PARAMETERS − 1).
pub(crate) const MAX_NUMBERED: usize = 5602;

/// G28 stored position X, Y, Z, A, B, C, U, V, W: #5161–#5169 (machine units).
pub(crate) const G28_HOME: usize = 5161;
/// G30 stored position X..W: #5181–#5189.
pub(crate) const G30_HOME: usize = 5181;
/// G92 offset applied (1) or not (0): #5210.
pub(crate) const G92_ENABLED: usize = 5210;
/// G92 offset X..W: #5211–#5219.
pub(crate) const G92_OFFSET: usize = 5211;
/// Active coordinate system 1–9 (G54–G59.3): #5220.
pub(crate) const COORD_SYSTEM: usize = 5220;
/// G54 offset X..W at #5221–#5229 and its XY rotation R at #5230; G55 at #5241, …, G59.3
/// at #5381: 20 parameters apart.
pub(crate) const G54_OFFSET: usize = 5221;
/// The distance between two coordinate systems' parameter blocks.
pub(crate) const COORD_STRIDE: usize = 20;
/// Tool number in the spindle: #5400.
pub(crate) const TOOL_NUMBER: usize = 5400;
/// Tool offsets X..W: #5401–#5409; diameter #5410; front angle #5411, back angle #5412,
/// orientation #5413.
pub(crate) const TOOL_OFFSET: usize = 5401;
/// Current position X..W in the program's coordinates and units: #5420–#5428.
pub(crate) const CURRENT_POSITION: usize = 5420;

/// The numbered parameter table. `#0` always reads 0 and cannot be set.
#[derive(Clone, Debug)]
pub(crate) struct Params {
    values: Box<[f64]>,
}

impl Params {
    pub(crate) fn new() -> Self {
        Params {
            values: vec![0.0; MAX_NUMBERED + 1].into_boxed_slice(),
        }
    }

    /// `#n`, or `None` when `n` is out of range.
    pub(crate) fn get(&self, n: usize) -> Option<f64> {
        self.values.get(n).copied()
    }

    /// Sets `#n`; `false` when `n` is 0 or out of range.
    pub(crate) fn set(&mut self, n: usize, value: f64) -> bool {
        match self.values.get_mut(n) {
            Some(slot) if n != 0 => {
                *slot = value;
                true
            }
            _ => false,
        }
    }
}
