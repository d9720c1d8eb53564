//! The distributed clock of one subdevice (ETG.1000.4 §9, registers 0x0900–0x09FF): a
//! local clock that is the loop's time plus the device's power-on offset plus what the
//! drift control has corrected, the system time (local + offset 0x0920), the receive-time
//! latch of the ports (write to 0x0900), and the time control loop fed by writes of the
//! reference's system time to 0x0910 (FRMW / BWR).
//!
//! The time is an input (`now_ns` from the caller), so the model is deterministic: all
//! emulated subdevices run from the same time base, as if their oscillators had no drift,
//! and the control loop only removes the offsets the MainDevice has not compensated. Like
//! an ESC's loop it corrects gradually: at most [`MAX_STEP_NS`] per system-time write, so
//! the MainDevice's reset (a broadcast write of 0 to 0x0910) does not throw the clock.

/// The most the control loop corrects the local clock per received system time, ns.
pub const MAX_STEP_NS: i64 = 1_000;
/// The frame's delay through one subdevice (to the next one), ns.
pub const HOP_DELAY_NS: u64 = 500;

/// One subdevice's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcClock {
    power_on_offset_ns: u64,
    correction_ns: i64,
}

impl DcClock {
    /// A clock that reads `power_on_offset_ns` ahead of the loop's time.
    pub fn new(power_on_offset_ns: u64) -> DcClock {
        DcClock {
            power_on_offset_ns,
            correction_ns: 0,
        }
    }

    /// Local time at the loop's time `now_ns`.
    pub fn local_ns(&self, now_ns: u64) -> u64 {
        now_ns
            .wrapping_add(self.power_on_offset_ns)
            .wrapping_add_signed(self.correction_ns)
    }

    /// System time: local time plus the system time offset register.
    pub fn system_ns(&self, now_ns: u64, offset_ns: u64) -> u64 {
        self.local_ns(now_ns).wrapping_add(offset_ns)
    }

    /// The control loop receives the reference's system time `received_ns` (already
    /// delayed by `delay_ns` on its way here); returns the difference it saw (received +
    /// delay − own system time), of which it corrects at most [`MAX_STEP_NS`].
    pub fn steer(&mut self, now_ns: u64, offset_ns: u64, delay_ns: u32, received_ns: u64) -> i64 {
        let own = self.system_ns(now_ns, offset_ns);
        let difference = received_ns
            .wrapping_add(u64::from(delay_ns))
            .wrapping_sub(own) as i64;
        self.correction_ns += difference.clamp(-MAX_STEP_NS, MAX_STEP_NS);
        difference
    }
}

/// The port receive times latched by a write to 0x0900 for the subdevice at `position` of
/// a line of `count`: port 0 when the frame arrives, port 1 when it comes back from the
/// rest of the line (`None` at the line's end, where port 1 is closed).
pub fn receive_times(local_ns: u64, position: u16, count: u16) -> (u64, Option<u64>) {
    let arrive = local_ns.wrapping_add(u64::from(position) * HOP_DELAY_NS);
    let behind = count.saturating_sub(position + 1);
    if behind == 0 {
        (arrive, None)
    } else {
        (arrive, Some(arrive + 2 * u64::from(behind) * HOP_DELAY_NS))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn system_time_is_local_time_plus_offset() {
        let clock = DcClock::new(5_000);
        assert_eq!(clock.local_ns(1_000_000), 1_005_000);
        assert_eq!(clock.system_ns(1_000_000, 10), 1_005_010);
    }

    #[test]
    fn the_loop_corrects_small_differences_at_once_and_large_ones_gradually() {
        let mut clock = DcClock::new(0);
        assert_eq!(clock.steer(100, 0, 300, 100), 300);
        assert_eq!(clock.local_ns(100), 400);
        // A write of 0 (the MainDevice's reset) moves the clock by one step only.
        let d = clock.steer(1_000_000, 0, 0, 0);
        assert_eq!(d, -1_000_300);
        assert_eq!(clock.local_ns(1_000_000), 1_000_000 + 300 - 1_000);
    }

    #[test]
    fn receive_times_grow_along_the_line_and_close_at_its_end() {
        assert_eq!(receive_times(1_000, 0, 3), (1_000, Some(3_000)));
        assert_eq!(receive_times(1_000, 1, 3), (1_500, Some(2_500)));
        assert_eq!(receive_times(1_000, 2, 3), (2_000, None));
    }
}
