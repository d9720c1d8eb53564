//! The distributed clock of one subdevice (ETG.1000.4 §9, registers 0x0900–0x09FF): a
//! local clock that is the line's oscillator time plus the device's power-on offset plus
//! what the drift control has corrected, the system time (local + offset 0x0920), the
//! receive-time latch of the ports (write to 0x0900), and the time control loop fed by
//! writes of the reference's system time to 0x0910 (FRMW / BWR).
//!
//! The time is an input (`now_ns`, the host's time from the caller), so the model is
//! deterministic. All emulated subdevices share one oscillator: it runs `drift_ppm`
//! parts per million fast (negative: slow) against the host's time, so every local clock
//! advances `now_ns · (1 + drift_ppm · 10⁻⁶)` (see [`oscillator_ns`]). They drift together
//! against the host, never against each other, and the control loop only removes the
//! offsets the MainDevice has not compensated. Like an ESC's loop it corrects gradually:
//! at most [`MAX_STEP_NS`] per system-time write, so the MainDevice's reset (a broadcast
//! write of 0 to 0x0910) does not throw the clock.

/// The most the control loop corrects the local clock per received system time, ns.
pub const MAX_STEP_NS: i64 = 1_000;
/// The frame's delay through one subdevice (to the next one), ns.
pub const HOP_DELAY_NS: u64 = 500;

/// The largest oscillator drift a clock accepts, parts per million either way (beyond it
/// the drift is clamped): 1 %, far beyond any quartz, and a clock that always advances.
pub const MAX_DRIFT_PPM: f64 = 10_000.0;

/// Parts per trillion in one part per million.
const PPT_PER_PPM: f64 = 1e6;

/// The drift `drift_ppm` (clamped to ±[`MAX_DRIFT_PPM`]; not a number counts as 0) in
/// parts per trillion, the integer the clocks compute with.
fn drift_ppt(drift_ppm: f64) -> i64 {
    if drift_ppm.is_nan() {
        return 0;
    }
    (drift_ppm.clamp(-MAX_DRIFT_PPM, MAX_DRIFT_PPM) * PPT_PER_PPM).round() as i64
}

/// The line's oscillator at the host's time `now_ns`: `now_ns · (1 + drift_ppt · 10⁻¹²)`,
/// rounded down, in exact integer arithmetic (a host nanosecond count of any size).
fn oscillator_ppt_ns(now_ns: u64, drift_ppt: i64) -> u64 {
    let gained = (i128::from(now_ns) * i128::from(drift_ppt)).div_euclid(1_000_000_000_000);
    now_ns.wrapping_add_signed(gained as i64)
}

/// The time of an oscillator that runs `drift_ppm` parts per million fast (negative:
/// slow) against the host, at the host's time `now_ns`, both counted from the same start:
/// `now_ns · (1 + drift_ppm · 10⁻⁶)` (the drift clamped to ±[`MAX_DRIFT_PPM`]).
pub fn oscillator_ns(now_ns: u64, drift_ppm: f64) -> u64 {
    oscillator_ppt_ns(now_ns, drift_ppt(drift_ppm))
}

/// One subdevice's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcClock {
    power_on_offset_ns: u64,
    drift_ppt: i64,
    correction_ns: i64,
}

impl DcClock {
    /// A clock that reads `power_on_offset_ns` ahead of the host's time at 0 and runs
    /// `drift_ppm` parts per million fast against it (negative: slow; see
    /// [`oscillator_ns`]).
    pub fn new(power_on_offset_ns: u64, drift_ppm: f64) -> DcClock {
        DcClock {
            power_on_offset_ns,
            drift_ppt: drift_ppt(drift_ppm),
            correction_ns: 0,
        }
    }

    /// Local time at the host's time `now_ns`.
    pub fn local_ns(&self, now_ns: u64) -> u64 {
        oscillator_ppt_ns(now_ns, self.drift_ppt)
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
        self.correct(difference)
    }

    /// As [`DcClock::steer`] for a 32-bit write of the system time: only the lower 32 bits
    /// are received and compared (the difference is taken modulo 2³², as the nearest of
    /// the candidates, within ±2.1 s).
    pub fn steer_32(
        &mut self,
        now_ns: u64,
        offset_ns: u64,
        delay_ns: u32,
        received_ns: u32,
    ) -> i64 {
        let own = self.system_ns(now_ns, offset_ns) as u32;
        let difference = received_ns.wrapping_add(delay_ns).wrapping_sub(own) as i32;
        self.correct(i64::from(difference))
    }

    fn correct(&mut self, difference_ns: i64) -> i64 {
        self.correction_ns = self
            .correction_ns
            .saturating_add(difference_ns.clamp(-MAX_STEP_NS, MAX_STEP_NS));
        difference_ns
    }
}

/// The system time difference register (0x092C) for a difference `received + delay −
/// own system time` as [`DcClock::steer`] returns it: bits 30:0 the magnitude in ns
/// (at most 0x7FFF_FFFF), bit 31 set when the local copy of the system time is smaller
/// than the received one (a positive difference).
pub fn difference_register(difference_ns: i64) -> u32 {
    let magnitude = difference_ns.unsigned_abs().min(0x7FFF_FFFF) as u32;
    let smaller = if difference_ns > 0 { 0x8000_0000 } else { 0 };
    magnitude | smaller
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
        let clock = DcClock::new(5_000, 0.0);
        assert_eq!(clock.local_ns(1_000_000), 1_005_000);
        assert_eq!(clock.system_ns(1_000_000, 10), 1_005_010);
    }

    #[test]
    fn the_loop_corrects_small_differences_at_once_and_large_ones_gradually() {
        let mut clock = DcClock::new(0, 0.0);
        assert_eq!(clock.steer(100, 0, 300, 100), 300);
        assert_eq!(clock.local_ns(100), 400);
        // A write of 0 (the MainDevice's reset) moves the clock by one step only.
        let d = clock.steer(1_000_000, 0, 0, 0);
        assert_eq!(d, -1_000_300);
        assert_eq!(clock.local_ns(1_000_000), 1_000_000 + 300 - 1_000);
    }

    #[test]
    fn a_32_bit_write_compares_the_lower_32_bits_only() {
        let mut clock = DcClock::new(0, 0.0);
        // Own system time 0x1_0000_0100 at now; received 0x0000_0180 (upper half not
        // sent), delay 0x20: 0xA0 ahead.
        let now_ns = 0x1_0000_0100;
        assert_eq!(clock.steer_32(now_ns, 0, 0x20, 0x180), 0xA0);
        assert_eq!(clock.local_ns(now_ns), 0x1_0000_01A0);
        // Across the 32-bit wrap: own …_FFFF_FFF0, received 0x10 is 0x20 ahead.
        let mut clock = DcClock::new(0, 0.0);
        assert_eq!(clock.steer_32(0x2_FFFF_FFF0, 0, 0, 0x10), 0x20);
        assert_eq!(clock.steer_32(0x2_FFFF_FFF0, 0, 0, 0xFFFF_FF00), -0x110);
    }

    #[test]
    fn the_difference_register_holds_the_magnitude_and_whether_the_own_copy_is_smaller() {
        // Received ahead of the own copy by 300 ns: the own copy is smaller, bit 31.
        assert_eq!(difference_register(300), 0x8000_012C);
        // Received behind by 300 ns: bit 31 clear.
        assert_eq!(difference_register(-300), 0x0000_012C);
        assert_eq!(difference_register(0), 0);
        // Beyond 31 bits the magnitude saturates.
        assert_eq!(difference_register(-(1 << 40)), 0x7FFF_FFFF);
        assert_eq!(difference_register(i64::MIN), 0x7FFF_FFFF);
        assert_eq!(difference_register(i64::MAX), 0xFFFF_FFFF);
    }

    #[test]
    fn a_drifting_oscillator_gains_its_parts_per_million_of_the_host_time() {
        // 50 ppm: 50 µs per second; over 2.5 s, 125 µs.
        let clock = DcClock::new(7_000, 50.0);
        assert_eq!(
            clock.local_ns(1_000_000_000) - clock.local_ns(0),
            1_000_050_000
        );
        assert_eq!(
            clock.local_ns(3_500_000_000) - clock.local_ns(1_000_000_000),
            2_500_125_000
        );
        // −20 ppm loses 20 µs per second; fractions of a ns round down.
        let slow = DcClock::new(0, -20.0);
        assert_eq!(slow.local_ns(1_000_000_000), 999_980_000);
        assert_eq!(oscillator_ns(1_000_000, -0.5), 999_999);
        assert_eq!(oscillator_ns(1_000, 0.5), 1_000);
        assert_eq!(oscillator_ns(1_000_000, 0.5), 1_000_000);
        assert_eq!(oscillator_ns(2_000_000, 0.5), 2_000_001);
        // Absurd drifts are clamped to 1 %, not a number to none.
        assert_eq!(oscillator_ns(1_000_000, 1e9), 1_010_000);
        assert_eq!(oscillator_ns(1_000_000, f64::NAN), 1_000_000);
        // Far from the start the arithmetic stays exact: 10⁶ s at 50 ppm gains 50 s.
        assert_eq!(
            oscillator_ns(1_000_000 * 1_000_000_000, 50.0),
            1_000_050 * 1_000_000_000
        );
    }

    #[test]
    fn clocks_on_one_oscillator_keep_their_offsets_as_they_drift() {
        let a = DcClock::new(0, 100.0);
        let b = DcClock::new(1_000_000, 100.0);
        for now_ns in [0u64, 1_000_000_000, 60_000_000_000] {
            assert_eq!(b.local_ns(now_ns) - a.local_ns(now_ns), 1_000_000);
        }
    }

    #[test]
    fn receive_times_grow_along_the_line_and_close_at_its_end() {
        assert_eq!(receive_times(1_000, 0, 3), (1_000, Some(3_000)));
        assert_eq!(receive_times(1_000, 1, 3), (1_500, Some(2_500)));
        assert_eq!(receive_times(1_000, 2, 3), (2_000, None));
    }
}
