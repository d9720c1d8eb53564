//! Read-only views of the modal state for LinuxCNC's predefined named parameters
//! (`#<_x>`, `#<_metric>`, …) and the computed numbered ones (#5420–#5428).

use super::{Comp, MM_PER_INCH, Motion, State};
use crate::arc::Plane;
use kerf_geom::PerAxis;

impl State {
    /// The current position in program coordinates and units: X, Y, Z (without the work
    /// offset, G92 and tool length), A, B, C (degrees).
    pub(crate) fn q_program_pos(&self) -> PerAxis<f64> {
        let s = if self.inch { MM_PER_INCH } else { 1.0 };
        [
            (self.pos[0] - self.origin[0]) / s,
            (self.pos[1] - self.origin[1]) / s,
            (self.pos[2] - self.origin[2]) / s,
            self.abc[0],
            self.abc[1],
            self.abc[2],
        ]
    }

    /// The current position in machine coordinates, program units (`#<_abs_x>` …).
    pub(crate) fn q_machine_pos(&self) -> PerAxis<f64> {
        let s = if self.inch { MM_PER_INCH } else { 1.0 };
        [
            self.pos[0] / s,
            self.pos[1] / s,
            self.pos[2] / s,
            self.abc[0],
            self.abc[1],
            self.abc[2],
        ]
    }

    pub(crate) fn q_inch(&self) -> bool {
        self.inch
    }

    pub(crate) fn q_absolute(&self) -> bool {
        self.absolute
    }

    pub(crate) fn q_arc_absolute(&self) -> bool {
        self.arc_absolute
    }

    /// `#<_motion_mode>`: the G code of the motion mode times ten (G80, none, is 800).
    pub(crate) fn q_motion_mode(&self) -> f64 {
        match self.motion {
            Some(Motion::Rapid) => 0.0,
            Some(Motion::Linear) => 10.0,
            Some(Motion::Arc(Some(true))) => 30.0,
            Some(Motion::Arc(_)) => 20.0,
            _ => 800.0,
        }
    }

    /// `#<_plane>`: 170, 180 or 190.
    pub(crate) fn q_plane(&self) -> f64 {
        match self.plane {
            Plane::Xy => 170.0,
            Plane::Zx => 180.0,
            Plane::Yz => 190.0,
        }
    }

    /// `#<_ccomp>`: 400, 410 or 420.
    pub(crate) fn q_ccomp(&self) -> f64 {
        match self.comp {
            Comp::Off => 400.0,
            Comp::Left => 410.0,
            Comp::Right => 420.0,
        }
    }

    /// `#<_coord_system>`: 540 … 590, 591, 592, 593.
    pub(crate) fn q_coord_system(&self) -> f64 {
        match self.coord_system.unwrap_or(0) {
            i @ 0..=5 => 540.0 + 10.0 * i as f64,
            i => 585.0 + i as f64,
        }
    }

    /// `#<_feed>`: F in the program's feed unit (0 before any F).
    pub(crate) fn q_feed(&self) -> f64 {
        let s = if self.feed_inch { MM_PER_INCH } else { 1.0 };
        self.feed_mm_min.map_or(0.0, |f| f / s)
    }

    /// `#<_rpm>`: the last S (0 before any S).
    pub(crate) fn q_rpm(&self) -> f64 {
        self.spindle_rpm.unwrap_or(0.0)
    }

    /// `#<_current_tool>` / #5400: the tool loaded by M6 (0 for none).
    pub(crate) fn q_current_tool(&self) -> f64 {
        self.tool_loaded.map_or(0.0, f64::from)
    }

    /// `#<_selected_tool>`: the last T (0 before any, as rs274 prints it; the manual says
    /// -1).
    pub(crate) fn q_selected_tool(&self) -> f64 {
        self.tool_selected.map_or(0.0, f64::from)
    }

    pub(crate) fn q_feed_mode_inverse_time(&self) -> f64 {
        f64::from(u8::from(self.feed_mode == super::FeedMode::InverseTime))
    }

    pub(crate) fn q_feed_mode_per_minute(&self) -> f64 {
        f64::from(u8::from(self.feed_mode == super::FeedMode::PerMinute))
    }

    pub(crate) fn q_feed_mode_per_rev(&self) -> f64 {
        f64::from(u8::from(self.feed_mode == super::FeedMode::PerRev))
    }

    pub(crate) fn q_retract_old_z(&self) -> bool {
        !self.retract_r
    }

    pub(crate) fn q_spindle_on(&self) -> bool {
        self.spindle != super::Spindle::Off
    }

    pub(crate) fn q_spindle_cw(&self) -> bool {
        self.spindle == super::Spindle::Cw
    }

    pub(crate) fn q_mist(&self) -> bool {
        self.mist
    }

    pub(crate) fn q_flood(&self) -> bool {
        self.flood
    }

    /// `#<_tool_offset>`: 1 while a tool length offset is applied.
    pub(crate) fn q_tool_offset(&self) -> bool {
        self.tool_length_on
    }
}
