//! The host's cycle locked onto the bus's distributed clock.
//!
//! With distributed clocks every drive takes its outputs at SYNC0, a pulse its own clock
//! makes at the period on the bus's time (DC system time, SYNC0 where it is a multiple of
//! the period). The host's cycle runs on the host's clock, whose oscillator drifts against
//! the reference subdevice's by some tens of ppm: left alone, the cycle start walks across
//! SYNC0 (µs per second) until a frame arrives after the pulse it was meant for, and the
//! drive interpolates a stale setpoint — the "gravel" sound of drifting DC.
//!
//! [`PhaseLock`] measures, once per cycle, where the cycle started on the bus's time and
//! steers the next cycle's start by a PI loop so that SYNC0 comes `shift_ns` after it:
//! the time the frame has to reach every subdevice.
//!
//! The measurement: the cyclic frame reads the reference's system time as it passes
//! (ethercrab's `tx_rx_dc`, a read-multiple-write of 0x0910). The host notes its own
//! clock just before sending and when the frame is back; the frame passed the reference
//! at about the middle of that round trip, so the cycle's start on the bus's time is the
//! system time read minus the host's time from the cycle start to that middle. A frame
//! whose round trip took longer than a quarter of the period (a busy host, a NIC that
//! held it) says too little about when it passed: it is not taken, and the loop keeps
//! its course for that cycle.
//!
//! The offset is the cycle start's distance from where it should be (`shift_ns` before
//! SYNC0), wrapped into half a period either way; positive = late.

/// Proportional gain: the share of the offset corrected in the next cycle.
const KP: f64 = 0.1;
/// Integral gain: the share of the summed offsets, which takes up a steady drift.
const KI: f64 = 0.01;

/// A PI loop on the offset between the cycle start and SYNC0 (see the module).
#[derive(Debug, Clone, Copy)]
pub struct PhaseLock {
    period_ns: u64,
    shift_ns: u64,
    /// The most one cycle's start is moved, ns.
    max_step_ns: i64,
    integral_ns: f64,
    offset_ns: i64,
}

impl PhaseLock {
    /// A loop for a cycle of `period_ns` whose start should come `shift_ns` before SYNC0.
    pub fn new(period_ns: u64, shift_ns: u64) -> PhaseLock {
        PhaseLock {
            period_ns,
            shift_ns: shift_ns % period_ns.max(1),
            // A twentieth of the period per cycle: enough to take up any oscillator's
            // drift at once, small enough that the cycle's timing stays regular.
            max_step_ns: (period_ns / 20).max(1) as i64,
            integral_ns: 0.0,
            offset_ns: 0,
        }
    }

    /// The longest round trip a measurement is taken from, ns.
    pub fn max_round_trip_ns(&self) -> u64 {
        self.period_ns / 4
    }

    /// The offset of a cycle that started at `start_ns` (host clock) and whose frame
    /// passed the reference at host time `passed_ns`, reading its system time `dc_time_ns`.
    pub fn offset_ns(&self, start_ns: u64, passed_ns: u64, dc_time_ns: u64) -> i64 {
        let period = self.period_ns as i64;
        let start_on_bus = dc_time_ns.wrapping_sub(passed_ns.saturating_sub(start_ns));
        // Where the start lies in the SYNC0 period, and where it should: `shift` before
        // the next pulse.
        let phase = (start_on_bus % self.period_ns) as i64;
        let wanted = (period - self.shift_ns as i64) % period;
        let mut offset = phase - wanted;
        if offset >= period / 2 {
            offset -= period;
        } else if offset < -period / 2 {
            offset += period;
        }
        offset
    }

    /// Takes one cycle's measurement: the cycle started at `start_ns`, its frame left at
    /// `sent_ns` and was back at `received_ns` (host clock) with the reference's system
    /// time `dc_time_ns`. Returns the offset and the correction to add to the next cycle's
    /// start, ns (negative = earlier); `None` when the round trip was too long to say.
    pub fn update(
        &mut self,
        start_ns: u64,
        sent_ns: u64,
        received_ns: u64,
        dc_time_ns: u64,
    ) -> Option<(i64, i64)> {
        let round_trip_ns = received_ns.saturating_sub(sent_ns);
        if round_trip_ns > self.max_round_trip_ns() {
            return None;
        }
        let passed_ns = sent_ns + round_trip_ns / 2;
        let offset = self.offset_ns(start_ns, passed_ns, dc_time_ns);
        self.offset_ns = offset;
        let max = self.max_step_ns as f64;
        // The integral is bounded so that a long disturbance (a frame lost, a late
        // cycle) does not wind it up beyond what one step can give back.
        self.integral_ns = (self.integral_ns + offset as f64).clamp(-max / KI, max / KI);
        let correction = -(KP * offset as f64 + KI * self.integral_ns);
        Some((offset, correction.clamp(-max, max).round() as i64))
    }

    /// The last offset measured, ns.
    pub fn last_offset_ns(&self) -> i64 {
        self.offset_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD: u64 = 1_000_000;
    const SHIFT: u64 = 300_000;

    /// A bus clock that runs `ppm` fast against the host's and is `offset_ns` ahead of it.
    fn bus_time(host_ns: u64, ppm: f64, offset_ns: u64) -> u64 {
        (host_ns as f64 * (1.0 + ppm * 1e-6)) as u64 + offset_ns
    }

    #[test]
    fn a_start_shift_before_sync0_has_no_offset_and_one_later_is_late() {
        let lock = PhaseLock::new(PERIOD, SHIFT);
        // SYNC0 at bus time 5 ms; the cycle started at 4.7 ms on the bus's time and sent
        // its frame 20 µs later.
        assert_eq!(lock.offset_ns(1_000, 21_000, 4_720_000), 0);
        assert_eq!(lock.offset_ns(1_000, 21_000, 4_730_000), 10_000);
        assert_eq!(lock.offset_ns(1_000, 21_000, 4_700_000), -20_000);
        // Wrapped to half a period: 0.6 ms late is 0.4 ms early.
        assert_eq!(lock.offset_ns(1_000, 1_000, 5_300_000), -400_000);
    }

    /// Runs `cycles` of a host clock that starts each cycle where the loop says, against
    /// a bus clock `ppm` fast; returns the offsets.
    fn run(ppm: f64, cycles: usize) -> Vec<i64> {
        let mut lock = PhaseLock::new(PERIOD, SHIFT);
        let mut start = 10_000_000u64;
        let bus_offset = 123_456_789;
        let mut offsets = Vec::new();
        for _ in 0..cycles {
            let sent = start + 15_000;
            let passed = sent + 10_000;
            let dc = bus_time(passed, ppm, bus_offset);
            let (offset, correction) = lock.update(start, sent, passed + 10_000, dc).unwrap();
            offsets.push(offset);
            start = (start as i64 + PERIOD as i64 + correction) as u64;
        }
        offsets
    }

    #[test]
    fn a_drifting_bus_clock_is_followed() {
        for ppm in [0.0, 50.0, -100.0, 500.0] {
            let offsets = run(ppm, 20_000);
            // Wherever it began, after settling within a microsecond, where without the loop
            // the drift would have walked the start by ppm µs per second (20 s here).
            let settled = offsets[1_000..].iter().map(|o| o.abs()).max().unwrap();
            assert!(settled <= 1_000, "{ppm} ppm: {settled} ns");
        }
    }

    #[test]
    fn a_frame_with_a_long_round_trip_is_not_taken_and_the_middle_of_a_short_one_is() {
        let mut lock = PhaseLock::new(PERIOD, SHIFT);
        // Started on time (SYNC0 at 5 ms on the bus, the start 0.3 ms before it), the
        // frame out 20 µs later and back 40 µs after that: it passed at 40 µs.
        assert_eq!(lock.update(1_000, 21_000, 61_000, 4_740_000).unwrap().0, 0);
        // Back only after 300 µs, beyond a quarter period: not taken.
        assert_eq!(lock.update(1_000, 21_000, 321_000, 4_740_000), None);
        assert_eq!(lock.last_offset_ns(), 0);
    }

    #[test]
    fn a_start_a_quarter_period_off_is_brought_in_at_a_bounded_rate() {
        let mut lock = PhaseLock::new(PERIOD, SHIFT);
        let mut start = 0u64;
        let mut offsets = Vec::new();
        // The bus's time puts SYNC0 250 µs away from where it should be.
        for _ in 0..400 {
            let dc = start + 700_000 + 250_000;
            let (offset, correction) = lock.update(start, start, start, dc).unwrap();
            assert!(correction.abs() <= (PERIOD / 20) as i64);
            offsets.push(offset);
            start = (start as i64 + PERIOD as i64 + correction) as u64;
        }
        assert_eq!(offsets[0], 250_000);
        assert!(offsets[399].abs() < 1_000, "{:?}", &offsets[390..]);
    }
}
