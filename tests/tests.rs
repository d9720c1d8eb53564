//! Workspace tests: one binary, a module per area.

mod gcode;
