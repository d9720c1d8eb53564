//! The drive side's latched fault in words, for the status (`StatusMsg::fault_text`) and
//! for `kerf status` alike.

use kerf_proto::StatusMsg;

/// The name of a safety check code (`SAFETY_*`), as `kerf_drive::safety::Check::name`.
pub fn check_name(code: u32) -> Option<&'static str> {
    kerf_drive::safety::Check::ALL
        .iter()
        .find(|c| c.code() == code)
        .map(|c| c.name())
}

/// The latched fault of the drive side in words, with units: the check, the axis, the
/// value against its limit, the program line and the cycle; `None` when none is latched.
pub fn safety_text(s: &StatusMsg) -> Option<String> {
    let name = check_name(s.safety_check)?;
    let axis = kerf_geom::AXIS_NAMES.get(s.safety_axis as usize);
    let unit = if s.safety_axis >= 3 { "deg" } else { "mm" };
    let on = axis.map_or(String::new(), |a| format!(" on axis {a}"));
    let (value, limit) = (s.safety_value, s.safety_limit);
    let what = match s.safety_check {
        kerf_proto::SAFETY_VELOCITY => {
            format!("setpoint step {value:.1} {unit}/s against the limit {limit:.1} {unit}/s")
        }
        kerf_proto::SAFETY_ACCELERATION => {
            format!("{value:.1} {unit}/s² against the limit {limit:.1} {unit}/s²")
        }
        kerf_proto::SAFETY_SOFT_LIMIT => {
            format!("setpoint {value:.4} {unit} beyond the soft limit {limit:.4} {unit}")
        }
        kerf_proto::SAFETY_FOLLOWING_ERROR => {
            format!("{value:.4} {unit} against the limit {limit:.4} {unit}")
        }
        kerf_proto::SAFETY_STREAM_STALL => {
            format!("{value} consecutive cycles without a setpoint (limit {limit})")
        }
        kerf_proto::SAFETY_DRIVE_FAULT => {
            format!("the drive reports error 0x{:04X}", s.drive_error_code)
        }
        kerf_proto::SAFETY_ENABLE_TIMEOUT => {
            format!("the drive did not enable within {limit} cycles")
        }
        kerf_proto::SAFETY_FIELDBUS => {
            format!("EtherCAT: {value} cycles in a row without a complete exchange (limit {limit})")
        }
        kerf_proto::SAFETY_SUBDEVICE_STATE => format!(
            "EtherCAT: the subdevice at position {value} left OP, AL status code {}",
            kerf_ethercat::al::al_code_text(limit as u16)
        ),
        kerf_proto::SAFETY_SPINDLE_AT_SPEED => {
            format!("the spindle did not reach {limit:.0} rpm in time (actual {value:.0} rpm)")
        }
        kerf_proto::SAFETY_SPINDLE_BAND => format!(
            "the spindle left its at-speed band while feeding: {value:.0} rpm against {limit:.0} rpm commanded"
        ),
        kerf_proto::SAFETY_SPINDLE_ORIENT => {
            format!("the spindle's orientation did not end within {limit} s")
        }
        kerf_proto::SAFETY_TOOL_CHANGE => {
            format!("the tool changer did not report tool T{value} changed within {limit} s")
        }
        kerf_proto::SAFETY_SPINDLE_DRIVE => match limit as u32 {
            0 => format!("the spindle drive reports error 0x{:04X}", value as u32),
            1 => format!("the spindle drive did not enable within {value} cycles"),
            _ => "the spindle drive left Operation enabled on its own".to_string(),
        },
        kerf_proto::SAFETY_HOME_SEARCH => format!(
            "homing: the home switch was not found within {limit:.3} {unit} (searched {value:.3} {unit})"
        ),
        kerf_proto::SAFETY_HOME_RELEASE => format!(
            "homing: the home switch did not release within {limit:.3} {unit} (moved {value:.3} {unit} off it)"
        ),
        kerf_proto::SAFETY_HOME_LATCH => format!(
            "homing: the home switch's latch edge was not found within {limit:.3} {unit} (moved {value:.3} {unit})"
        ),
        kerf_proto::SAFETY_DRIVE_HOMING => match s.drive_error_code {
            0 => "the drive's own homing ended in an error (or it did not take the homing mode)"
                .to_string(),
            code => format!("the drive's own homing ended in an error, 0x{code:04X}"),
        },
        kerf_proto::SAFETY_HARD_LIMIT => format!(
            "the {} hard limit switch is active; after `kerf reset`, jog the axis off it",
            if value < 0.0 { "lower" } else { "upper" }
        ),
        _ => "the drive left Operation enabled on its own".to_string(),
    };
    Some(format!(
        "{name}{on}: {what} (line {}, cycle {})",
        s.safety_line, s.safety_cycle
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_drive::safety::Check;

    #[test]
    fn safety_checks_go_on_the_wire_as_the_protocol_numbers_them() {
        // The daemon sends `Check::code()`; the client reads it against the protocol's
        // `SAFETY_*` numbers (docs/PROTOCOL.md). Both lists are written by hand: they must
        // agree check by check, and every check must have its name back.
        let wire = [
            (Check::Velocity, kerf_proto::SAFETY_VELOCITY),
            (Check::Acceleration, kerf_proto::SAFETY_ACCELERATION),
            (Check::SoftLimit, kerf_proto::SAFETY_SOFT_LIMIT),
            (Check::FollowingError, kerf_proto::SAFETY_FOLLOWING_ERROR),
            (Check::StreamStall, kerf_proto::SAFETY_STREAM_STALL),
            (Check::DriveFault, kerf_proto::SAFETY_DRIVE_FAULT),
            (Check::EnableTimeout, kerf_proto::SAFETY_ENABLE_TIMEOUT),
            (Check::DriveDisabled, kerf_proto::SAFETY_DRIVE_DISABLED),
            (Check::Fieldbus, kerf_proto::SAFETY_FIELDBUS),
            (Check::SubdeviceState, kerf_proto::SAFETY_SUBDEVICE_STATE),
            (Check::SpindleAtSpeed, kerf_proto::SAFETY_SPINDLE_AT_SPEED),
            (Check::SpindleBand, kerf_proto::SAFETY_SPINDLE_BAND),
            (Check::SpindleOrient, kerf_proto::SAFETY_SPINDLE_ORIENT),
            (Check::ToolChange, kerf_proto::SAFETY_TOOL_CHANGE),
            (Check::SpindleDrive, kerf_proto::SAFETY_SPINDLE_DRIVE),
            (Check::HomeSearch, kerf_proto::SAFETY_HOME_SEARCH),
            (Check::HomeRelease, kerf_proto::SAFETY_HOME_RELEASE),
            (Check::HomeLatch, kerf_proto::SAFETY_HOME_LATCH),
            (Check::HardLimit, kerf_proto::SAFETY_HARD_LIMIT),
            (Check::DriveHoming, kerf_proto::SAFETY_DRIVE_HOMING),
        ];
        assert_eq!(wire.len(), Check::ALL.len());
        for (check, code) in wire {
            assert!(Check::ALL.contains(&check), "{check:?}");
            assert_eq!(check.code(), code, "{check:?}");
            assert_eq!(check_name(code), Some(check.name()), "{check:?}");
        }
        assert_eq!(check_name(kerf_proto::SAFETY_NONE), None);
    }
}
