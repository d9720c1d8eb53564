//! The answer to the emulator's `state` command: one line per subdevice, in ring order,
//! made for programs to parse. Each line is `subdevice P` followed by `key=value` fields
//! separated by single spaces; no value contains a space, and the fields of a kind always
//! come in the same order:
//!
//! ```text
//! subdevice 0 kind=drive al=OP al_error=0 al_code=0x0000 watchdog_trips=0 cia402=operation_enabled statusword=0x1237 error_code=0x0000 position_counts=123 velocity_counts_s=0 following_error_counts=0 stalled=0 stopped_ms=- mode=8 target_velocity_counts_s=0 home_switch=0 motor_counts=123
//! subdevice 3 kind=io al=SAFE-OP al_error=1 al_code=0x001B watchdog_trips=1 inputs=0xA5 outputs=0x00
//! ```
//!
//! Every subdevice:
//! - `kind`: `drive` or `io`;
//! - `al`: the AL state, `INIT`, `PRE-OP`, `BOOT`, `SAFE-OP` or `OP`;
//! - `al_error`: the AL status error indicator (0x0130 bit 4), `0` or `1`;
//! - `al_code`: the AL status code (0x0134), `0x` and 4 upper-case hex digits;
//! - `watchdog_trips`: how many times its process-data watchdog has expired (decimal).
//!
//! A drive, then:
//! - `cia402`: the power state, `not_ready_to_switch_on`, `switch_on_disabled`,
//!   `ready_to_switch_on`, `switched_on`, `operation_enabled`, `quick_stop_active`,
//!   `fault_reaction_active` or `fault`;
//! - `statusword` (0x6041) and `error_code` (0x603F): `0x` and 4 upper-case hex digits;
//! - `position_counts` (0x6064), `velocity_counts_s` (0x606C), `following_error_counts`
//!   (0x60F4): signed decimal, what the drive reports in its process data;
//! - `stalled`: `1` while the motor is jammed (`stall P`), else `0`;
//! - `stopped_ms`: the time from the last expiry of its process-data watchdog to its motor
//!   at rest by its own quick stop, in ms with 3 decimals (e.g. `20.000`), counted in the
//!   servo model's periods; `-` when the watchdog has not expired, or the motor is not at
//!   rest yet;
//! - `mode`: the mode of operation (0x6061), `6` homing, `8` cyclic synchronous position or
//!   `9` cyclic synchronous velocity (a spindle drive);
//! - `target_velocity_counts_s`: the target velocity (0x60FF) last written, signed decimal
//!   (what a drive in mode 9 follows);
//! - `home_switch`: `1` while its home switch is active (0x60FD bit 2; `--home-switch`),
//!   else `0`;
//! - `motor_counts`: where its motor is in the motor's own frame, counts from power-up
//!   (signed decimal): `position_counts` until a homing by the drive redefines the drive's
//!   coordinates, then `position_counts` less that shift.
//!
//! An I/O subdevice, then `inputs` and `outputs`: its bits (bit n is input or output n),
//! `0x` and one upper-case hex digit per 4 bits (2 for 8 bits); `outputs` are those last
//! written in OP (0 outside OP).

use core::fmt::{self, Write};

use kerf_drive::cia402::DriveState;

use crate::al::AlState;
use crate::esc::{AppSnapshot, Esc};
use crate::network::Network;

/// The AL state's name in the `state` line.
pub fn al_name(state: AlState) -> &'static str {
    match state {
        AlState::Init => "INIT",
        AlState::PreOp => "PRE-OP",
        AlState::Boot => "BOOT",
        AlState::SafeOp => "SAFE-OP",
        AlState::Op => "OP",
    }
}

/// The CiA 402 power state's name in the `state` line.
pub fn cia402_name(state: DriveState) -> &'static str {
    match state {
        DriveState::NotReadyToSwitchOn => "not_ready_to_switch_on",
        DriveState::SwitchOnDisabled => "switch_on_disabled",
        DriveState::ReadyToSwitchOn => "ready_to_switch_on",
        DriveState::SwitchedOn => "switched_on",
        DriveState::OperationEnabled => "operation_enabled",
        DriveState::QuickStopActive => "quick_stop_active",
        DriveState::FaultReactionActive => "fault_reaction_active",
        DriveState::Fault => "fault",
    }
}

/// Writes the `state` line (without the line end) of the subdevice at `position`.
pub fn write_line(out: &mut impl Write, position: usize, esc: &Esc) -> fmt::Result {
    let snapshot = esc.app().snapshot();
    let kind = match snapshot {
        AppSnapshot::Drive(_) => "drive",
        AppSnapshot::Io(_) => "io",
    };
    let al = esc.al();
    write!(
        out,
        "subdevice {position} kind={kind} al={} al_error={} al_code=0x{:04X} watchdog_trips={}",
        al_name(al.state()),
        u8::from(al.error()),
        al.code(),
        esc.watchdog_trips()
    )?;
    match snapshot {
        AppSnapshot::Drive(d) => {
            write!(
                out,
                " cia402={} statusword=0x{:04X} error_code=0x{:04X} position_counts={} \
                 velocity_counts_s={} following_error_counts={} stalled={} stopped_ms=",
                cia402_name(d.state),
                d.statusword,
                d.error_code,
                d.position_counts,
                d.velocity_counts_s,
                d.following_error_counts,
                u8::from(d.stalled)
            )?;
            match d.stopped_after_ns {
                Some(ns) => write!(out, "{}.{:03}", ns / 1_000_000, (ns / 1_000) % 1_000)?,
                None => out.write_char('-')?,
            }
            write!(
                out,
                " mode={} target_velocity_counts_s={} home_switch={} motor_counts={}",
                d.mode,
                d.target_velocity_counts_s,
                u8::from(d.home_switch),
                d.motor_counts
            )
        }
        AppSnapshot::Io(io) => {
            let digits = |bits: u8| usize::from(bits.div_ceil(4)).max(1);
            write!(
                out,
                " inputs=0x{:0in_width$X} outputs=0x{:0out_width$X}",
                io.inputs,
                io.outputs,
                in_width = digits(io.input_bits),
                out_width = digits(io.output_bits)
            )
        }
    }
}

/// Writes the whole answer to `state`: one line per subdevice, each ended by `\n`.
pub fn write_state(out: &mut impl Write, network: &Network) -> fmt::Result {
    for (position, esc) in network.escs().iter().enumerate() {
        write_line(out, position, esc)?;
        out.write_char('\n')?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NetworkSpec, build};

    #[test]
    fn a_fresh_line_answers_one_line_per_subdevice_in_ring_order() {
        let (network, handles) = build(&NetworkSpec {
            drives: 2,
            io: 1,
            ..NetworkSpec::default()
        });
        handles[0].set_inputs(0x1A5);
        let mut out = String::new();
        write_state(&mut out, &network).unwrap();
        assert_eq!(
            out,
            "subdevice 0 kind=drive al=INIT al_error=0 al_code=0x0000 watchdog_trips=0 \
             cia402=not_ready_to_switch_on statusword=0x0200 error_code=0x0000 \
             position_counts=0 velocity_counts_s=0 following_error_counts=0 stalled=0 \
             stopped_ms=- mode=8 target_velocity_counts_s=0 home_switch=0 motor_counts=0\n\
             subdevice 1 kind=drive al=INIT al_error=0 al_code=0x0000 watchdog_trips=0 \
             cia402=not_ready_to_switch_on statusword=0x0200 error_code=0x0000 \
             position_counts=0 velocity_counts_s=0 following_error_counts=0 stalled=0 \
             stopped_ms=- mode=8 target_velocity_counts_s=0 home_switch=0 motor_counts=0\n\
             subdevice 2 kind=io al=INIT al_error=0 al_code=0x0000 watchdog_trips=0 \
             inputs=0xA5 outputs=0x00\n"
        );
    }
}
