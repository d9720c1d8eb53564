//! The real-time thread: the cycle at the period, publishing through its helper.

use super::*;
use crate::status::axes_mask;

/// What the cycle thread is built from: the ring of planned items, the commands, the
/// status snapshots and the dump rings.
pub(crate) type CycleParts = (
    rtrb::Consumer<RtItem>,
    rtrb::Consumer<CycleCommand>,
    rtrb::Producer<Snapshot>,
    worker::DumpRings,
);

/// The real-time thread's loop; `real_time` asks for SCHED_FIFO and locked memory.
pub(crate) fn cycle_thread(
    config: &Config,
    real_time: bool,
    shared: Shared,
    ready: Ready,
    parts: CycleParts,
) -> Result<(), String> {
    let Shared {
        timing: timing_out,
        stop,
        cycles,
        overruns,
        rt_ok,
        counters,
        ..
    } = shared;
    let (items, commands, status, dump_rings) = parts;
    // iceoryx2 allocates on publish: a helper thread publishes (see `publish`).
    let helper_rt = real_time.then(|| kerf_rt::RtConfig {
        priority: Some(config.daemon.priority.saturating_sub(1).max(1)),
        cpu: config.daemon.cpu.map(|c| c as usize),
        prefault_stack_bytes: PREFAULT_STACK_BYTES,
    });
    let (mut publisher, helper) = match publish::spawn(&config.machine, helper_rt) {
        Ok(p) => p,
        Err(e) => {
            let _ = ready.send(Err(StartError::Setup(e.clone())));
            return Err(e);
        }
    };
    let mut cycle = match Cycle::new(config, [0.0; 6], items, commands, status, dump_rings) {
        Ok(c) => c,
        Err(e) => {
            let _ = ready.send(Err(StartError::Config(e.clone())));
            return Err(e);
        }
    };
    cycle.watch_planner(counters.behind.clone());
    let rt = if real_time {
        let report = kerf_rt::rt_setup(&kerf_rt::RtConfig {
            priority: Some(config.daemon.priority),
            cpu: config.daemon.cpu.map(|c| c as usize),
            prefault_stack_bytes: PREFAULT_STACK_BYTES,
        });
        match report {
            Ok(r) => {
                let ok = r.mlocked && r.fifo;
                rt_ok.store(ok, Ordering::Release);
                RtStatus {
                    rt: ok,
                    cpu_latency_us: None,
                    messages: r.messages,
                }
            }
            Err(e) => {
                let _ = ready.send(Err(StartError::Config(e.to_string())));
                return Err(e.to_string());
            }
        }
    } else {
        RtStatus {
            rt: false,
            cpu_latency_us: None,
            messages: vec!["real-time scheduling not requested".to_string()],
        }
    };
    let axes_mask = axes_mask(config);
    let bring_up_ns = kerf_rt::now_ns();
    if let Err(e) = cycle.start_bus(config) {
        let _ = ready.send(Err(StartError::Config(e.clone())));
        return Err(e);
    }
    if let Some(report) = cycle.bus_report() {
        // Before the first period: the cycle has not started, so it may log.
        tracing::info!(
            "EtherCAT: {} subdevices in OP {} ms after the scan began{}",
            report.subdevices,
            kerf_rt::now_ns().saturating_sub(bring_up_ns) / 1_000_000,
            if report.dc.is_some() {
                ", with distributed clocks settled and the cycle locked onto SYNC0"
            } else {
                ""
            }
        );
    }
    let period_ns = config.period_us as u64 * 1000;
    // With distributed clocks the bring-up locked the bus's cycle onto SYNC0: the clock
    // starts where it left off.
    let clock = match cycle.first_cycle_start_ns() {
        Some(first) => kerf_rt::PeriodicClock::starting_at(period_ns, first),
        None => kerf_rt::PeriodicClock::new(period_ns),
    };
    let mut clock = match clock {
        Ok(c) => c,
        Err(e) => {
            let _ = ready.send(Err(StartError::Config(e.to_string())));
            return Err(e.to_string());
        }
    };
    let _ = ready.send(Ok(Some(rt)));
    let mut msg = SetpointMsg::new();
    msg.axes_mask = axes_mask;
    let mut timing = timing::CycleTiming::new();
    loop {
        let tick = clock.wait_next();
        if tick.missed > 0 {
            overruns.fetch_add(tick.missed, Ordering::AcqRel);
            // The drives got no setpoint in the periods missed: they held.
            cycle.missed(tick.missed);
        }
        cycle.begin(tick.deadline_ns);
        let out = cycle.run();
        // With distributed clocks: the next start follows SYNC0.
        clock.shift_next(cycle.take_clock_correction_ns());
        out.fill(&mut msg, tick.deadline_ns);
        publisher.push(msg);
        let woke_ns = tick.deadline_ns + tick.latency_ns;
        timing.record(tick.latency_ns, kerf_rt::now_ns().saturating_sub(woke_ns));
        cycles.store(out.seq, Ordering::Release);
        if cycle.shut_down() || stop.load(Ordering::Acquire) {
            let mut summary = timing.summary();
            if let Some(h) = helper.finish() {
                summary.publish = h.percentiles();
            }
            tracing::info!(
                "cycle timing: {summary}; {} setpoints dropped",
                publisher.dropped()
            );
            if let Some(c) = cycle.bus_counters() {
                tracing::info!(
                    "EtherCAT: {} cycles exchanged, {} frames lost, {} short working counters, {} with a subdevice out of OP, at most {} incomplete in a row",
                    c.complete,
                    c.lost,
                    c.short,
                    c.not_op,
                    c.longest_gap
                );
            }
            if let Some(dc) = cycle.bus_report().and_then(|b| b.dc) {
                tracing::info!(
                    "EtherCAT distributed clocks: the cycle start's offset from its place before SYNC0 over {} cycles: {}",
                    dc.samples,
                    dc.offset_abs
                );
            }
            if let Ok(mut t) = timing_out.lock() {
                *t = Some(summary);
            }
            stop.store(true, Ordering::Release);
            return Ok(());
        }
    }
}
