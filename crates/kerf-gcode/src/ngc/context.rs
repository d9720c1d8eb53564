//! The parameters an expression reads on a LinuxCNC line: numbered, named (local, global,
//! predefined) and the call level, through [`Ctx`].

use super::*;

/// Parameter access for the expression reader.
pub(super) struct Ctx<'a> {
    ngc: &'a Ngc,
    state: &'a State,
    line: u32,
    /// Named parameters assigned earlier on the line: rs274 reads one of them that was
    /// never set as 0 instead of refusing it (`#<a>=1 #<a>=[#<a>+1]` sets 1).
    pub(super) assigned: std::cell::RefCell<Vec<String>>,
}

impl Ctx<'_> {
    pub(super) fn predefined(&self, name: &str) -> Option<f64> {
        let s = self.state;
        let b = |c: bool| if c { 1.0 } else { 0.0 };
        let axis = |n: &str| ["x", "y", "z", "a", "b", "c"].iter().position(|a| *a == n);
        let rest = name.strip_prefix('_')?;
        if let Some(i) = axis(rest) {
            return Some(s.q_program_pos()[i]);
        }
        if let Some(i) = rest.strip_prefix("abs_").and_then(axis) {
            return Some(s.q_machine_pos()[i]);
        }
        Some(match rest {
            "u" | "v" | "w" => 0.0,
            "vmajor" => 2.9,
            "vminor" => 0.0,
            "line" => f64::from(self.line),
            "motion_mode" => s.q_motion_mode(),
            "plane" => s.q_plane(),
            "ccomp" => s.q_ccomp(),
            "metric" => b(!s.q_inch()),
            "imperial" => b(s.q_inch()),
            "absolute" => b(s.q_absolute()),
            "incremental" => b(!s.q_absolute()),
            "inverse_time" => s.q_feed_mode_inverse_time(),
            "units_per_minute" => s.q_feed_mode_per_minute(),
            "units_per_rev" => s.q_feed_mode_per_rev(),
            "coord_system" => s.q_coord_system(),
            "tool_offset" => b(s.q_tool_offset()),
            "retract_r_plane" => b(!s.q_retract_old_z()),
            "retract_old_z" => b(s.q_retract_old_z()),
            "spindle_rpm_mode" => 1.0,
            "spindle_css_mode" => 0.0,
            "ijk_absolute_mode" => b(s.q_arc_absolute()),
            // rs274 (a mill configuration) reads radius mode on and diameter mode off.
            "lathe_diameter_mode" => 0.0,
            "lathe_radius_mode" => 1.0,
            "spindle_on" => b(s.q_spindle_on()),
            "spindle_cw" => b(s.q_spindle_cw()),
            "mist" => b(s.q_mist()),
            "flood" => b(s.q_flood()),
            "speed_override" | "feed_override" => 1.0,
            "adaptive_feed" => 0.0,
            // The feed hold switch is enabled at start, as rs274 reads it.
            "feed_hold" => 1.0,
            "feed" => s.q_feed(),
            "rpm" => s.q_rpm(),
            "current_tool" => s.q_current_tool(),
            "current_pocket" => -1.0,
            "selected_tool" => s.q_selected_tool(),
            "selected_pocket" => -1.0,
            "value" => self.ngc.value,
            "value_returned" => b(self.ngc.value_returned),
            "task" => 0.0,
            "call_level" => self.ngc.call_level() as f64,
            "remap_level" => 0.0,
            _ => return None,
        })
    }
}

impl expr::Params for Ctx<'_> {
    fn numbered(&self, n: f64, col: u32) -> Result<f64, BlockError> {
        let i = param_index(n, col)?;
        if (params::CURRENT_POSITION..params::CURRENT_POSITION + 9).contains(&i) {
            let k = i - params::CURRENT_POSITION;
            return Ok(self.state.q_program_pos().get(k).copied().unwrap_or(0.0));
        }
        if i == params::TOOL_NUMBER {
            return Ok(self.state.q_current_tool());
        }
        if i == params::INPUT_RESULT {
            // After an M66, the read that waits for the machine's answer.
            return self.state.read_input_result(col);
        }
        match self.state.params.get(i) {
            Some(v) => Ok(v),
            None => fail(col, "Parameter number out of range"),
        }
    }

    fn named(&self, name: &str, col: u32) -> Result<f64, BlockError> {
        let found = if name.starts_with('_') {
            self.predefined(name)
                .or_else(|| self.ngc.globals.get(name).copied())
        } else {
            self.ngc.locals.last().and_then(|m| m.get(name).copied())
        };
        match found {
            Some(v) => Ok(v),
            None if self.assigned.borrow().iter().any(|n| n == name) => Ok(0.0),
            None => fail(col, format!("Named parameter #<{name}> not defined")),
        }
    }

    fn numbered_exists(&self, n: f64, col: u32) -> bool {
        param_index(n, col).is_ok()
    }

    fn exists(&self, name: &str) -> bool {
        if name.starts_with('_') {
            self.predefined(name).is_some() || self.ngc.globals.contains_key(name)
        } else {
            self.ngc.locals.last().is_some_and(|m| m.contains_key(name))
        }
    }
}

/// The index of a numbered parameter: an integer (within LinuxCNC's tolerance) from 1 to
/// 5601.
pub(super) fn param_index(n: f64, col: u32) -> Result<usize, BlockError> {
    let r = n.round();
    if (n - r).abs() > 0.0001 {
        return fail(col, "Non integer value for integer");
    }
    if !(1.0..params::MAX_NUMBERED as f64).contains(&r) {
        return fail(col, "Parameter number out of range");
    }
    Ok(r as usize)
}

impl Ngc {
    pub(super) fn call_level(&self) -> usize {
        self.frames.iter().filter(|f| f.call.is_some()).count()
    }

    pub(super) fn ctx<'a>(&'a self, state: &'a State, line: u32) -> Ctx<'a> {
        Ctx {
            ngc: self,
            state,
            line,
            assigned: std::cell::RefCell::new(Vec::new()),
        }
    }
}
