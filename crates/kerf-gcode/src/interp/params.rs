//! LinuxCNC numbered parameters #1–#5602: one flat table, owned by the interpreter state,
//! read and written by the expression language and by the codes whose data the manual
//! places in parameters (G10, G28.1, G30.1, G92, tool data, current position).

//! Kerf's machine unit is the millimetre: the offsets and positions held here (G28/G30
//! positions, G92 offsets, G54–G59.3 offsets, tool offsets) are mm, and degrees for A, B,
//! C and the XY rotation R, whatever G20/G21 the program uses. LinuxCNC keeps them in its
//! machine unit, which is what a LinuxCNC machine configured in mm shows.

// The expression language reads and writes the table through `get`/`set`.
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
/// The result of the last M66 wait (the input's value, -1 on a timeout): #5399.
pub(crate) const INPUT_RESULT: usize = 5399;
/// Tool number in the spindle: #5400.
pub(crate) const TOOL_NUMBER: usize = 5400;
/// Tool offsets X..W: #5401–#5409; diameter #5410; front angle #5411, back angle #5412,
/// orientation #5413.
pub(crate) const TOOL_OFFSET: usize = 5401;
/// Current position X..W in the program's coordinates and units: #5420–#5428.
pub(crate) const CURRENT_POSITION: usize = 5420;

/// The first parameter of coordinate system `n` (1 = G54 … 9 = G59.3): X at +0, Y +1,
/// Z +2, A +3, B +4, C +5, U V W +6..+8, the XY rotation R (degrees) at +9.
pub(crate) fn coord_base(n: usize) -> usize {
    G54_OFFSET + COORD_STRIDE * (n - 1)
}

/// True for the numbers LinuxCNC keeps in its parameter file between runs: the G28 and
/// G30 positions (#5161–#5169, #5181–#5189), the G52/G92 offset and its flag
/// (#5210–#5219, which G92.3 restores in a later program), the active coordinate system
/// (#5220) and the G54–G59.3 offsets and rotations (#5221–#5390, ten of each twenty).
pub(crate) fn is_persistent(n: usize) -> bool {
    match n {
        5161..=5169 | 5181..=5189 | 5210..=5220 => true,
        5221..=5390 => (n - G54_OFFSET) % COORD_STRIDE < 10,
        _ => false,
    }
}

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

    /// `#n` for a number known to be in range (the constants above).
    pub(crate) fn at(&self, n: usize) -> f64 {
        self.values.get(n).copied().unwrap_or(0.0)
    }

    /// The persistent parameters with their values, in ascending order.
    pub(crate) fn persistent(&self) -> Vec<(u32, f64)> {
        (5161..=5390)
            .filter(|&n| is_persistent(n))
            .map(|n| (n as u32, self.at(n)))
            .collect()
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
