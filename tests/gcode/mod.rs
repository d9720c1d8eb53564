//! Acceptance tests for issue 2, the G-code front end (`kerf-gcode`).
//!
//! They are written from the control manuals (`../shared/seeds/`, the dialect table and notes
//! in DESIGN.md, and the controls' public manuals), not from the implementation: every
//! expected coordinate is computed by hand in the test. Where a manual is silent and a test
//! has to guess, the guess is written next to it and the test prefers properties (equal
//! radii, exact end points) over exact numbers.

mod api;
mod codes;
mod comp;
mod cross_dialect;
mod cycles;
mod errors;
mod fagor;
mod fuzz;
mod fuzz_language;
mod grammar;
mod heidenhain;
mod language;
mod linuxcnc;
mod modal;
mod offsets;
mod reference;
mod rockwell;
mod rs274;
mod sinumerik;
mod syntax;
