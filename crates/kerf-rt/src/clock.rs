//! Absolute-deadline periodic loop on `CLOCK_MONOTONIC`.

use crate::RtError;

const NS_PER_S: u64 = 1_000_000_000;

/// The current `CLOCK_MONOTONIC` time in nanoseconds.
///
/// Does not allocate. `clock_gettime` on `CLOCK_MONOTONIC` cannot fail on Linux for a valid
/// pointer; were it to, this returns 0 rather than panicking.
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec for the duration of the call.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    if rc != 0 {
        return 0;
    }
    // CLOCK_MONOTONIC is non-negative; the casts cannot lose anything for 584 years of uptime.
    (ts.tv_sec as u64)
        .saturating_mul(NS_PER_S)
        .saturating_add(ts.tv_nsec as u64)
}

/// One wake-up of a [`PeriodicClock`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tick {
    /// Index of this cycle, counting from 0 for the first wake-up (missed deadlines are not
    /// counted as cycles).
    pub cycle: u64,
    /// The absolute `CLOCK_MONOTONIC` deadline this wake-up was for, in ns.
    pub deadline_ns: u64,
    /// How late the wake-up was: the monotonic time read right after the sleep minus
    /// `deadline_ns`. Never negative: an absolute sleep does not return early.
    pub latency_ns: u64,
    /// How many further deadlines had already passed when the thread woke up (0 normally).
    /// They are skipped: the next wake-up is the first deadline after this one's wake-up time.
    pub missed: u64,
}

/// A fixed-period loop on absolute `CLOCK_MONOTONIC` deadlines.
///
/// Deadlines are `start + k·period`, so sleep jitter never accumulates into drift. The first
/// deadline is one period after [`PeriodicClock::new`].
// A copy would be a second instance of its state, silently diverging from the first.
#[allow(missing_copy_implementations)]
#[derive(Debug, Clone)]
pub struct PeriodicClock {
    period_ns: u64,
    next_deadline_ns: u64,
    cycles: u64,
    overruns: u64,
}

impl PeriodicClock {
    /// A clock whose first deadline is one period from now.
    pub fn new(period_ns: u64) -> Result<Self, RtError> {
        Self::starting_at(period_ns, now_ns().saturating_add(period_ns))
    }

    /// A clock whose first deadline is `first_deadline_ns` (`CLOCK_MONOTONIC`, ns), e.g. to
    /// align several loops on one time base.
    pub fn starting_at(period_ns: u64, first_deadline_ns: u64) -> Result<Self, RtError> {
        if period_ns == 0 {
            return Err(RtError::InvalidPeriod { period_ns });
        }
        Ok(Self {
            period_ns,
            next_deadline_ns: first_deadline_ns,
            cycles: 0,
            overruns: 0,
        })
    }

    /// The period in ns.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// The deadline the next [`PeriodicClock::wait_next`] sleeps until.
    pub fn next_deadline_ns(&self) -> u64 {
        self.next_deadline_ns
    }

    /// Moves the next deadline by `delta_ns` (negative = earlier), and with it every later
    /// one: how a loop that follows another clock (the EtherCAT bus's distributed clock)
    /// steers its phase. A deadline moved into the past is met at once by the next wait.
    pub fn shift_next(&mut self, delta_ns: i64) {
        self.next_deadline_ns = self.next_deadline_ns.saturating_add_signed(delta_ns);
    }

    /// Wake-ups so far.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    /// Deadlines skipped so far (the sum of every [`Tick::missed`]).
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Sleeps until the next deadline and returns what happened.
    ///
    /// The sleep is `clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)`, restarted on `EINTR`
    /// (the absolute deadline makes a restart exact). If the deadline has already passed the
    /// call returns at once; deadlines that passed during the late wake-up are counted as
    /// overruns and skipped. No allocation, lock or logging.
    pub fn wait_next(&mut self) -> Tick {
        let deadline_ns = self.next_deadline_ns;
        sleep_until_ns(deadline_ns);
        let woke_ns = now_ns().max(deadline_ns);
        let (missed, next_deadline_ns) = schedule_after(deadline_ns, woke_ns, self.period_ns);
        let tick = Tick {
            cycle: self.cycles,
            deadline_ns,
            latency_ns: woke_ns - deadline_ns,
            missed,
        };
        self.cycles += 1;
        self.overruns = self.overruns.saturating_add(missed);
        self.next_deadline_ns = next_deadline_ns;
        tick
    }
}

/// Given a deadline, the time the thread woke for it (`woke_ns >= deadline_ns`) and the
/// period: how many later deadlines had already passed (a deadline equal to `woke_ns` counts
/// as passed) and the first deadline strictly after `woke_ns`.
fn schedule_after(deadline_ns: u64, woke_ns: u64, period_ns: u64) -> (u64, u64) {
    let late_ns = woke_ns.saturating_sub(deadline_ns);
    let missed = late_ns / period_ns;
    let next = deadline_ns.saturating_add((missed + 1).saturating_mul(period_ns));
    (missed, next)
}

/// Absolute sleep on `CLOCK_MONOTONIC`, restarted on `EINTR`.
fn sleep_until_ns(deadline_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (deadline_ns / NS_PER_S) as libc::time_t,
        tv_nsec: (deadline_ns % NS_PER_S) as libc::c_long,
    };
    loop {
        // SAFETY: `ts` is a valid timespec; the remainder pointer may be null with TIMER_ABSTIME.
        let rc = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        // clock_nanosleep returns the error number instead of setting errno. The only other
        // errors (EINVAL for a malformed timespec or clock, EFAULT) cannot arise from the
        // normalised timespec above; if one did, returning beats spinning.
        if rc != libc::EINTR {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_time_wake_up_schedules_the_following_deadline() {
        assert_eq!(schedule_after(10_000, 10_000, 1_000), (0, 11_000));
        assert_eq!(schedule_after(10_000, 10_999, 1_000), (0, 11_000));
    }

    #[test]
    fn late_wake_up_skips_every_passed_deadline() {
        // Woke exactly on the next deadline: that one has passed, run at the one after.
        assert_eq!(schedule_after(10_000, 11_000, 1_000), (1, 12_000));
        // 3.5 periods late: deadlines 11 000, 12 000 and 13 000 passed.
        assert_eq!(schedule_after(10_000, 13_500, 1_000), (3, 14_000));
    }

    #[test]
    fn a_shifted_deadline_moves_the_following_ones_with_it() {
        let mut clock = PeriodicClock::starting_at(1_000, 50_000).expect("valid period");
        clock.shift_next(-30);
        assert_eq!(clock.next_deadline_ns(), 49_970);
        clock.shift_next(45);
        assert_eq!(clock.next_deadline_ns(), 50_015);
        // The deadline is in the past: the wait returns at once, and the one after keeps
        // the shifted phase.
        let tick = clock.wait_next();
        assert_eq!(tick.deadline_ns, 50_015);
        assert_eq!((clock.next_deadline_ns() - 50_015) % 1_000, 0);
    }

    #[test]
    fn zero_period_is_rejected() {
        assert!(matches!(
            PeriodicClock::new(0),
            Err(RtError::InvalidPeriod { period_ns: 0 })
        ));
    }

    #[test]
    fn deadlines_advance_by_whole_periods_and_never_burst() {
        let period_ns = 200_000;
        let mut clock = PeriodicClock::new(period_ns).expect("valid period");
        let mut previous: Option<Tick> = None;
        for i in 0..50 {
            if i == 20 {
                // Simulate a cycle whose work overran by 3.5 periods. `sleep` lasts at least
                // this long, so at least two more deadlines have passed at the next wake-up.
                std::thread::sleep(std::time::Duration::from_nanos(period_ns * 7 / 2));
            }
            let tick = clock.wait_next();
            assert_eq!(tick.cycle, i);
            let woke_ns = tick.deadline_ns + tick.latency_ns;
            // Never a deadline at or before the wake-up: no burst of catch-up cycles.
            assert!(clock.next_deadline_ns() > woke_ns);
            assert_eq!(
                clock.next_deadline_ns() - tick.deadline_ns,
                (tick.missed + 1) * period_ns
            );
            if i == 20 {
                assert!(tick.missed >= 2, "missed {}", tick.missed);
            }
            if let Some(p) = previous {
                assert_eq!(tick.deadline_ns - p.deadline_ns, (p.missed + 1) * period_ns);
            }
            previous = Some(tick);
        }
        assert_eq!(clock.cycles(), 50);
        assert!(clock.overruns() >= 2);
    }
}
