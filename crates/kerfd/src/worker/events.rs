//! What the program's non-motion events mean to the motion.

use super::*;

/// What a non-motion event of the program means to the motion and the machine, on its
/// own, without the program's modal state (see [`kerf_pipeline::ProgramActions`], which
/// the planning threads run): an S while the spindle stands and M6 without a T are read
/// as they would be at the start of a program.
pub fn input_of_event(e: &kerf_geom::Event) -> Option<Input> {
    ProgramActions::new().event(e)
}
