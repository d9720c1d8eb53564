//! Switches wired to I/O terminal inputs that follow an emulated axis: a home or limit
//! switch on the machine, active while a drive's motor is at or beyond a point (in the
//! motor's own frame, counts from power-up), read by the MainDevice as an input bit of an
//! I/O subdevice. The emulator's `--switch` option.
//!
//! [`Switches::apply`] runs after each processed frame: the bits it drives are set from
//! the drives' motors as they are after that exchange, so the MainDevice reads them in
//! the next one (a one-cycle input delay, as a terminal's input filter adds). The other
//! input bits stay those the `inputs N BITS` command set.

use crate::esc::AppSnapshot;
use crate::io::IoHandle;
use crate::network::Network;

/// One switch: input `bit` of I/O subdevice `io` (0 first among the I/O subdevices) is
/// active while drive `drive`'s motor is at or above `counts` (`above`) or at or below
/// it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwitchInput {
    /// The I/O subdevice, 0 first among the I/O subdevices.
    pub io: u16,
    /// Its input bit.
    pub bit: u8,
    /// The drive's ring position.
    pub drive: u16,
    /// The switching point, counts in the motor's own frame.
    pub counts: f64,
    /// Active at and above the point (else at and below).
    pub above: bool,
}

impl SwitchInput {
    /// Parses `IO:BIT:DRIVE:>=COUNTS` or `IO:BIT:DRIVE:<=COUNTS`.
    pub fn parse(text: &str) -> Result<SwitchInput, String> {
        let parts: Vec<&str> = text.splitn(4, ':').collect();
        let [io, bit, drive, point] = parts[..] else {
            return Err(format!(
                "{text:?} is not IO:BIT:DRIVE:>=COUNTS or IO:BIT:DRIVE:<=COUNTS"
            ));
        };
        let number = |what: &str, t: &str| -> Result<u64, String> {
            t.parse().map_err(|e| format!("{what} {t:?}: {e}"))
        };
        let (above, counts) = if let Some(c) = point.strip_prefix(">=") {
            (true, c)
        } else if let Some(c) = point.strip_prefix("<=") {
            (false, c)
        } else {
            return Err(format!(
                "{point:?} must be >=COUNTS (active at and above) or <=COUNTS (at and below)"
            ));
        };
        let counts: f64 = counts
            .parse()
            .map_err(|e| format!("counts {counts:?}: {e}"))?;
        if !counts.is_finite() {
            return Err(format!("counts {counts} is not a position"));
        }
        let bit = number("bit", bit)?;
        if bit >= 64 {
            return Err(format!("bit {bit}: an I/O subdevice has at most 64 inputs"));
        }
        Ok(SwitchInput {
            io: u16::try_from(number("I/O subdevice", io)?).map_err(|e| e.to_string())?,
            bit: bit as u8,
            drive: u16::try_from(number("drive", drive)?).map_err(|e| e.to_string())?,
            counts,
            above,
        })
    }

    /// Whether the switch is active with the motor at `motor_counts`.
    pub fn active(&self, motor_counts: i64) -> bool {
        let x = motor_counts as f64;
        if self.above {
            x >= self.counts
        } else {
            x <= self.counts
        }
    }
}

/// The switches of a line and the input bits set by command, per I/O subdevice.
#[derive(Debug, Clone, Default)]
pub struct Switches {
    switches: Vec<SwitchInput>,
    /// The bits last set by `inputs N BITS`, per I/O subdevice.
    commanded: Vec<u64>,
}

impl Switches {
    /// The `switches` of a line with `io` I/O subdevices (each checked by the caller to
    /// name an existing one).
    pub fn new(switches: Vec<SwitchInput>, io: usize) -> Switches {
        Switches {
            switches,
            commanded: vec![0; io],
        }
    }

    /// The bits the `inputs N BITS` command sets on I/O subdevice `n`; the switches'
    /// bits are laid over them at the next [`Switches::apply`].
    pub fn command(&mut self, n: usize, bits: u64) {
        if let Some(c) = self.commanded.get_mut(n) {
            *c = bits;
        }
    }

    /// The input bits of I/O subdevice `n` with the motors of `network`: the commanded
    /// bits, each switch's bit set or cleared by its drive's motor.
    pub fn inputs(&self, network: &Network, n: usize) -> u64 {
        let mut bits = self.commanded.get(n).copied().unwrap_or(0);
        for s in self.switches.iter().filter(|s| usize::from(s.io) == n) {
            let motor = match network
                .escs()
                .get(usize::from(s.drive))
                .map(|e| e.app().snapshot())
            {
                Some(AppSnapshot::Drive(d)) => i64::from(d.motor_counts),
                _ => continue,
            };
            let mask = 1u64 << s.bit;
            if s.active(motor) {
                bits |= mask;
            } else {
                bits &= !mask;
            }
        }
        bits
    }

    /// Sets every I/O subdevice's inputs ([`Switches::inputs`]) through `handles`.
    pub fn apply(&self, network: &Network, handles: &[IoHandle]) {
        for (n, handle) in handles.iter().enumerate() {
            handle.set_inputs(self.inputs(network, n));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NetworkSpec, build};

    #[test]
    fn the_option_reads_both_directions_and_refuses_what_is_not_a_switch() {
        assert_eq!(
            SwitchInput::parse("0:3:1:>=-2500"),
            Ok(SwitchInput {
                io: 0,
                bit: 3,
                drive: 1,
                counts: -2500.0,
                above: true
            })
        );
        assert_eq!(
            SwitchInput::parse("1:0:2:<=40000").map(|s| s.above),
            Ok(false)
        );
        for bad in [
            "0:3:1",
            "0:3:1:2500",
            "0:64:1:>=0",
            "x:3:1:>=0",
            "0:3:1:>=inf",
        ] {
            assert!(SwitchInput::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_switch_bit_follows_its_drives_motor_over_the_commanded_bits() {
        let (network, handles) = build(&NetworkSpec {
            drives: 1,
            io: 1,
            ..NetworkSpec::default()
        });
        // The motor powers up at 0: a switch active at and above 0 is on, one at and
        // above 1 is off, one at and below 0 is on.
        let mut s = Switches::new(
            vec![
                SwitchInput::parse("0:1:0:>=0").unwrap(),
                SwitchInput::parse("0:2:0:>=1").unwrap(),
                SwitchInput::parse("0:5:0:<=0").unwrap(),
            ],
            1,
        );
        s.command(0, 0b1000_0101);
        // Bit 0 and 7 as commanded; bit 2 cleared (off), bits 1 and 5 set (on).
        assert_eq!(s.inputs(&network, 0), 0b1010_0011);
        s.apply(&network, &handles);
        let io = match network.escs()[1].app().snapshot() {
            AppSnapshot::Io(io) => io,
            other => panic!("{other:?}"),
        };
        assert_eq!(io.inputs, 0b1010_0011);
    }
}
