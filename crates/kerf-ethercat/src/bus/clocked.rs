//! Bring-up steps 4 and 5 with distributed clocks (see the parent module): SYNC0 on every
//! drive, the clocks settled and the host's cycle locked onto SYNC0, then SAFE-OP and OP
//! while cycling; and the exchange with distributed clocks that the cyclic exchange shares.

use std::time::Duration;

use ethercrab::subdevice_group::{DcConfiguration, HasDc, HasPdi, PreOp};
use ethercrab::{DcSync, MainDevice};
use kerf_config::ethercat::EthercatConfig;

use super::{
    BringUpError, Bus, BusDrive, Cyclic, DcSample, Exchange, Group, exchange_of, run, transition,
};
use crate::dc::PhaseLock;
use crate::pump::{Pump, PumpError};

/// A subdevice's clock has settled when its system time difference (0x092C) is within
/// this, ns.
pub const SETTLED_NS: u32 = 1_000;
/// The system time difference register of a subdevice's clock (ETG.1000.4).
const DC_DIFFERENCE_REGISTER: u16 = 0x092C;
/// Measured cycles in a row the host's cycle must stay in place before the bus goes to
/// SAFE-OP.
const LOCKED_CYCLES: u32 = 100;

impl Bus {
    /// Steps 4 and 5 with distributed clocks: SYNC0 on every drive, the clocks settled and
    /// the host's cycle locked onto SYNC0, then SAFE-OP and OP while cycling.
    pub(super) fn clocked(
        config: &EthercatConfig,
        period_ns: u64,
        maindevice: MainDevice<'static>,
        mut pump: Pump,
        mut group: Group<PreOp>,
        drives: &[BusDrive],
        names: Vec<(String, u16)>,
    ) -> Result<Bus, BringUpError> {
        let state_bound = Duration::from_millis(u64::from(config.state_timeout_ms)) * 2;
        for (position, mut sub) in group.iter_mut(&maindevice).enumerate() {
            if !drives.iter().any(|d| d.group_index == position) {
                continue;
            }
            if !sub.dc_support().any() {
                return Err(BringUpError::NoClock {
                    name: names[position].0.clone(),
                    position: u16::try_from(position).unwrap_or(u16::MAX),
                });
            }
            sub.set_dc_sync(DcSync::Sync0);
        }
        let group = run(
            &mut pump,
            || "process data image".to_owned(),
            group.into_pre_op_pdi(&maindevice),
            state_bound,
        )?;
        let group = run(
            &mut pump,
            || "distributed clocks: SYNC0".to_owned(),
            group.configure_dc_sync(
                &maindevice,
                DcConfiguration {
                    // SYNC0 starts once the clocks have had time to settle.
                    start_delay: Duration::from_millis(100),
                    sync0_period: Duration::from_nanos(period_ns),
                    sync0_shift: Duration::ZERO,
                },
            ),
            state_bound,
        )?;
        let mut lock = PhaseLock::new(period_ns, u64::from(config.sync0_shift_ns));
        let mut clock = kerf_rt::PeriodicClock::new(period_ns)
            .map_err(|_| BringUpError::Period { period_ns })?;
        let timeout = Duration::from_nanos(period_ns / 2);
        let settle_ms = config.dc_settle_timeout_ms;
        let settle_cycles = u64::from(settle_ms) * 1_000_000 / period_ns;
        // Settle: every subdevice's clock within SETTLED_NS of the reference's, and the
        // host's cycle within a tenth of a period of its place in LOCKED_CYCLES measured
        // cycles in a row.
        let mut locked = 0u32;
        let mut cycle = 0u64;
        let mut worst_clock: Option<(usize, i64)> = None;
        let mut last_offset = None;
        loop {
            if cycle > settle_cycles {
                let what = match (worst_clock, last_offset) {
                    (Some((position, difference)), _) => format!(
                        "{} (position {position}) differs from the reference clock by {difference} ns (at most {SETTLED_NS} ns allowed)",
                        names[position].0
                    ),
                    (None, Some(offset)) => format!(
                        "the cycle does not keep its place before SYNC0: last offset {:.1} µs (a tenth of the period allowed; see docs/ETHERCAT.md on preparing the NIC)",
                        offset as f64 / 1000.0
                    ),
                    (None, None) => "no frame came back".to_owned(),
                };
                return Err(BringUpError::Unsettled {
                    timeout_ms: settle_ms,
                    what,
                });
            }
            cycle += 1;
            let measured = locked_step(
                &maindevice,
                &mut pump,
                &group,
                &mut lock,
                &mut clock,
                timeout,
            );
            // A round trip too long to measure, or a frame lost, gives no verdict (the
            // cyclic supervision, not the settling, is about lost frames).
            if let Some(sample) = measured.ok().and_then(|(exchange, _)| exchange.dc) {
                last_offset = Some(sample.offset_ns);
                let in_place = sample.offset_ns.unsigned_abs() < period_ns / 10;
                locked = if in_place { locked + 1 } else { 0 };
            }
            if locked >= LOCKED_CYCLES && cycle.is_multiple_of(10) {
                worst_clock = worst_difference(&maindevice, &mut pump, &group, drives);
                if worst_clock.is_none() {
                    break;
                }
            }
        }
        let group = transition(
            &maindevice,
            &mut pump,
            &names,
            "PRE-OP to SAFE-OP",
            group.into_safe_op(&maindevice),
            state_bound,
        )?;
        let group = run(
            &mut pump,
            || "SAFE-OP to OP".to_owned(),
            group.request_into_op(&maindevice),
            state_bound,
        )?;
        // Cycle until every subdevice is in OP: the drives go to OP only with frames
        // arriving in time for SYNC0.
        // The same clock as the settling: its deadlines passed during the state change
        // are skipped, and the next keeps the phase the loop found.
        let op_cycles = u64::from(config.state_timeout_ms) * 1_000_000 / period_ns;
        for cycle in 0.. {
            let measured = locked_step(
                &maindevice,
                &mut pump,
                &group,
                &mut lock,
                &mut clock,
                timeout,
            );
            if matches!(measured, Ok((_, true))) {
                break;
            }
            if cycle > op_cycles {
                let step: Result<(), BringUpError> = Err(BringUpError::Step {
                    step: "SAFE-OP to OP".to_owned(),
                    source: ethercrab::error::Error::Timeout(
                        ethercrab::error::TimeoutError::StateTransition,
                    ),
                });
                Bus::named(&maindevice, &mut pump, &names, step)?;
            }
        }
        let first = clock.next_deadline_ns();
        Ok(Bus {
            maindevice,
            group: Cyclic::Clocked(group),
            pump,
            drives: Vec::new(),
            found: Vec::new(),
            names,
            lock: Some((lock, first)),
        })
    }
}

/// One exchange with distributed clocks on a group in any state with process data: the
/// outcome and whether every subdevice is in OP. The phase lock takes the measurement.
pub(super) fn cycle_dc_exchange<S: HasPdi>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    group: &Group<S, HasDc>,
    lock: &mut PhaseLock,
    start_ns: u64,
    timeout: Duration,
) -> Result<(Exchange, bool), PumpError> {
    let sent_ns = kerf_rt::now_ns();
    let response = pump
        .block_on(group.tx_rx_dc(maindevice), timeout)?
        .map_err(PumpError::Frame)?;
    let received_ns = kerf_rt::now_ns();
    let sample = lock
        .update(
            start_ns,
            sent_ns,
            received_ns,
            response.extra.dc_system_time,
        )
        .map(|(offset_ns, correction_ns)| DcSample {
            offset_ns,
            correction_ns,
        });
    let all_op = response.all_op();
    let exchange = exchange_of(response.working_counter, &response.subdevice_states, sample);
    Ok((exchange, all_op))
}

/// One bring-up cycle with distributed clocks: waits for `clock`'s next deadline,
/// exchanges ([`cycle_dc_exchange`]) and moves the clock by the phase lock's correction.
fn locked_step<S: HasPdi>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    group: &Group<S, HasDc>,
    lock: &mut PhaseLock,
    clock: &mut kerf_rt::PeriodicClock,
    timeout: Duration,
) -> Result<(Exchange, bool), PumpError> {
    let tick = clock.wait_next();
    let outcome = cycle_dc_exchange(maindevice, pump, group, lock, tick.deadline_ns, timeout)?;
    if let Some(sample) = outcome.0.dc {
        clock.shift_next(sample.correction_ns);
    }
    Ok(outcome)
}

/// The drive (other than the reference) whose clock differs most from the reference's
/// beyond [`SETTLED_NS`] (register 0x092C: bits 0–30 the difference, bit 31 its sign), if
/// any; a drive that does not answer counts as unsettled.
fn worst_difference<S: HasPdi>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    group: &Group<S, HasDc>,
    drives: &[BusDrive],
) -> Option<(usize, i64)> {
    let mut worst: Option<(usize, i64)> = None;
    // ethercrab's reference clock: the first subdevice in ring order with a clock.
    let reference = group
        .iter(maindevice)
        .find(|s| s.dc_support().any())
        .map(|s| s.configured_address());
    for d in drives {
        let Ok(sub) = group.subdevice(maindevice, d.group_index) else {
            continue;
        };
        // The reference clock is what the others follow: its own difference register is
        // not steered and means nothing.
        if reference == Some(sub.configured_address()) {
            continue;
        }
        let read = pump.block_on(
            sub.register_read::<u32>(DC_DIFFERENCE_REGISTER),
            Duration::from_millis(100),
        );
        let difference = match read {
            Ok(Ok(raw)) => {
                let magnitude = i64::from(raw & 0x7FFF_FFFF);
                if raw & 0x8000_0000 != 0 {
                    -magnitude
                } else {
                    magnitude
                }
            }
            _ => i64::MAX,
        };
        if difference.unsigned_abs() > u64::from(SETTLED_NS)
            && worst.is_none_or(|(_, w)| difference.unsigned_abs() > w.unsigned_abs())
        {
            worst = Some((d.group_index, difference));
        }
    }
    worst
}
