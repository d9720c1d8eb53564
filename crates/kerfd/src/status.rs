//! The status message the control thread answers with, from the cycle's snapshot.

use super::*;
use crate::worker::ManualStatus;

// The status carries one entry per ring position of the bus the daemon runs: the same
// number of positions, or the status would drop subdevices (or describe ones that cannot
// exist). kerf-proto does not depend on kerf-ethercat, so the two constants are tied here.
const _: () = assert!(kerf_proto::BUS_MAX_SUBDEVICES == kerf_ethercat::bus::MAX_SUBDEVICES);
// The status carries the AL states as kerf-ethercat reads them.
const _: () = assert!(kerf_proto::BUS_STATE_OP == kerf_ethercat::al::OP);
const _: () = assert!(kerf_proto::BUS_STATE_SAFE_OP == kerf_ethercat::al::SAFE_OP);

/// The snapshot before the cycle's first report.
pub(crate) fn idle_snapshot() -> Snapshot {
    Snapshot {
        cycles: 0,
        manual: ManualStatus::default(),
        state: MachineState::Idle,
        line: 0,
        position: [0.0; 6],
        feed_mm_s: 0.0,
        override_pct: 100.0,
        queued_segments: 0,
        queued_s: 0.0,
        program_id: 0,
        program_done: false,
        aborted: false,
        refusal: None,
        program_cycle: 0,
        shut_down: false,
        drives: worker::DriveReport {
            phase: kerf_drive::stage::Phase::Enabling,
            state: kerf_drive::safety::SafetyState::Running,
            fault: None,
            error_code: 0,
        },
        bus: None,
        reset: None,
        commands_applied: 0,
        machine: kerf_drive::machine::MachineStatus {
            pause: None,
            switches: kerf_drive::machine::Switches::default(),
            tool_in_spindle: 0,
            spindle: None,
            coolant: kerf_drive::machine::CoolantStatus {
                mist: false,
                flood: false,
            },
            feed_override_enabled: true,
            io: kerf_drive::machine::IoImage::default(),
            last_input: None,
            fault: None,
        },
        input_result_program: 0,
    }
}

pub(crate) fn axes_mask(config: &Config) -> u32 {
    let mut mask = 0b111;
    for (i, r) in config.axes.rotary().iter().enumerate() {
        if r.is_some() {
            mask |= 1 << (3 + i);
        }
    }
    mask
}

pub(crate) fn status_msg(
    s: &Snapshot,
    counters: &PlanningCounters,
    rt: u32,
    overruns: u64,
    window: u64,
    axes_mask: u32,
    period_ns: u64,
) -> StatusMsg {
    let mut msg = StatusMsg::zeroed();
    msg.state = match (s.state, s.refusal) {
        // A planner process that went away is no fault of the machine: it comes to rest
        // and reports idle (the reason stays in `fault` and `program_end`).
        (MachineState::Idle, Some(Refusal::SenderGone)) => MachineState::Idle,
        // A program the safety layer stopped (or refused while a fault was latched):
        // the fault is the drive side's, shown while it is latched (below); once reset,
        // the machine is idle.
        (MachineState::Idle, Some(Refusal::Safety(_) | Refusal::Faulted(_))) => MachineState::Idle,
        // A program refused because the machine was not ready for programs (not homed, on
        // a limit switch, moving by hand) left the machine as it was.
        (
            MachineState::Idle,
            Some(Refusal::NotHomed(_) | Refusal::OnLimitSwitch(_) | Refusal::ManualMotion),
        ) => MachineState::Idle,
        // The refused program's fault is shown until the next program begins.
        (MachineState::Idle, Some(_)) => MachineState::Fault,
        (state, _) => state,
    }
    .as_u32();
    msg.line = s.line;
    msg.position_mm_deg = s.position;
    let m = &s.manual;
    msg.homed = m.homed;
    msg.homing_required = u32::from(m.required);
    msg.homing = m.homing;
    msg.jogging = m.jogging;
    msg.home_switches = m.home_switches;
    msg.min_limit_switches = m.min_limit_switches;
    msg.max_limit_switches = m.max_limit_switches;
    msg.limit_released = m.limit_released;
    msg.home_phase[..6].copy_from_slice(&m.home_phase);
    msg.override_pct = s.override_pct;
    msg.queued_moves = s.queued_segments;
    msg.queued_s = s.queued_s;
    msg.cycles = s.cycles;
    msg.overruns = overruns;
    msg.rt = rt;
    msg.program_done = u32::from(s.program_done && !s.aborted && s.refusal.is_none());
    msg.program_end = match (s.program_done, s.aborted, s.refusal) {
        (false, ..) => kerf_proto::PROGRAM_END_NONE,
        (true, true, _) => kerf_proto::PROGRAM_END_ABORTED,
        (true, false, Some(_)) => kerf_proto::PROGRAM_END_REFUSED,
        (true, false, None) => kerf_proto::PROGRAM_END_FINISHED,
    };
    msg.program_id = s.program_id;
    msg.moves_received = counters.received.load(Ordering::Acquire);
    msg.window_items = window;
    msg.rejected = counters.refused.load(Ordering::Acquire);
    match s.refusal {
        Some(Refusal::Safety(_) | Refusal::Faulted(_)) if s.drives.fault.is_none() => {}
        Some(r) => {
            msg.fault = 1;
            msg.set_fault_text(&r.to_string());
        }
        None => {}
    }
    msg.axes_mask = axes_mask;
    msg.period_ns = period_ns;
    let d = &s.drives;
    msg.drives = match (d.phase, d.state) {
        (kerf_drive::stage::Phase::Enabling, _) => kerf_proto::DRIVES_ENABLING,
        (kerf_drive::stage::Phase::Resetting, _) => kerf_proto::DRIVES_RESETTING,
        (_, kerf_drive::safety::SafetyState::Running) => kerf_proto::DRIVES_RUNNING,
        (_, kerf_drive::safety::SafetyState::Holding) => kerf_proto::DRIVES_HOLDING,
        (_, kerf_drive::safety::SafetyState::QuickStop) => kerf_proto::DRIVES_QUICK_STOP,
        (_, kerf_drive::safety::SafetyState::Stopped) => kerf_proto::DRIVES_STOPPED,
    };
    if let Some(f) = d.fault {
        msg.state = MachineState::Fault.as_u32();
        msg.safety_check = f.check.code();
        msg.safety_axis = f.axis.map_or(kerf_proto::SAFETY_AXIS_NONE, |a| a as u32);
        msg.safety_value = f.value;
        msg.safety_limit = f.limit;
        msg.safety_line = f.line;
        msg.safety_cycle = f.cycle;
        msg.drive_error_code = u32::from(d.error_code);
        msg.fault = 2;
        msg.set_fault_text(&fault_text::safety_text(&msg).unwrap_or_default());
    }
    if let Some(bus) = &s.bus {
        fill_bus(&mut msg, bus);
    }
    msg
}

/// The EtherCAT section of the status (`bus_*`, `dc_*`) from the cycle's report of its bus.
fn fill_bus(msg: &mut StatusMsg, bus: &worker::fieldbus::BusReport) {
    msg.bus_subdevices = u32::from(bus.subdevices);
    msg.bus_recovering = u32::from(bus.recovering);
    // Positions beyond the bus stay 0, whatever the report holds there.
    let n = usize::from(bus.subdevices).min(kerf_proto::BUS_MAX_SUBDEVICES);
    msg.bus_states[..n].copy_from_slice(&bus.states[..n]);
    msg.bus_al_codes[..n].copy_from_slice(&bus.al_codes[..n]);
    let c = &bus.counters;
    msg.bus_cycles_complete = c.complete;
    msg.bus_cycles_lost = c.lost;
    msg.bus_cycles_short = c.short;
    msg.bus_cycles_not_op = c.not_op;
    msg.bus_longest_gap_cycles = c.longest_gap;
    if let Some(dc) = &bus.dc {
        msg.dc_used = 1;
        msg.dc_offset_ns = dc.offset_ns;
        msg.dc_offset_abs_p50_ns = dc.offset_abs.p50_ns;
        msg.dc_offset_abs_p99_ns = dc.offset_abs.p99_ns;
        msg.dc_offset_abs_p999_ns = dc.offset_abs.p999_ns;
        msg.dc_offset_abs_max_ns = dc.offset_abs.max_ns;
        msg.dc_samples = dc.samples;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timing::Percentiles;
    use worker::fieldbus::{BusCounters, BusReport, DcReport};

    fn status_of(bus: Option<BusReport>) -> StatusMsg {
        let snapshot = Snapshot {
            bus,
            ..idle_snapshot()
        };
        status_msg(
            &snapshot,
            &PlanningCounters::default(),
            1,
            0,
            64,
            0b111,
            1_000_000,
        )
    }

    /// A bus of 4 subdevices: the Y drive (position 1) dropped to SAFE-OP with a sync
    /// manager watchdog (0x001B) and a reset is bringing it back; DC in use.
    fn report() -> BusReport {
        let mut states = [0u8; 32];
        states[..4].copy_from_slice(&[8, 4, 8, 8]);
        // Garbage beyond the bus must not reach the status.
        states[4] = 8;
        let mut al_codes = [0u16; 32];
        al_codes[1] = 0x001B;
        al_codes[7] = 0x0011;
        BusReport {
            subdevices: 4,
            states,
            al_codes,
            counters: BusCounters {
                complete: 123_456,
                lost: 3,
                short: 2,
                not_op: 17,
                longest_gap: 5,
            },
            dc: Some(DcReport {
                offset_ns: -1_250,
                offset_abs: Percentiles {
                    p50_ns: 300,
                    p99_ns: 1_100,
                    p999_ns: 2_000,
                    max_ns: 3_400,
                },
                samples: 123_000,
            }),
            recovering: true,
        }
    }

    #[test]
    fn the_bus_section_is_filled_from_the_cycles_report() {
        let msg = status_of(Some(report()));
        assert_eq!(msg.bus_subdevices, 4);
        assert_eq!(msg.bus_positions(), 4);
        assert_eq!(msg.bus_recovering, 1);
        let mut states = [0u8; 32];
        states[..4].copy_from_slice(&[8, 4, 8, 8]);
        assert_eq!(msg.bus_states, states);
        let mut codes = [0u16; 32];
        codes[1] = 0x001B;
        assert_eq!(msg.bus_al_codes, codes);
        assert_eq!(
            (
                msg.bus_cycles_complete,
                msg.bus_cycles_lost,
                msg.bus_cycles_short,
                msg.bus_cycles_not_op,
                msg.bus_longest_gap_cycles
            ),
            (123_456, 3, 2, 17, 5)
        );
        assert_eq!(msg.dc_used, 1);
        assert_eq!(msg.dc_offset_ns, -1_250);
        assert_eq!(
            (
                msg.dc_offset_abs_p50_ns,
                msg.dc_offset_abs_p99_ns,
                msg.dc_offset_abs_p999_ns,
                msg.dc_offset_abs_max_ns,
                msg.dc_samples
            ),
            (300, 1_100, 2_000, 3_400, 123_000)
        );
        // The rest of the status is what it is without a bus.
        let without = status_of(None);
        let mut other = msg;
        other.bus_subdevices = 0;
        other.bus_recovering = 0;
        other.bus_states = [0; 32];
        other.bus_al_codes = [0; 32];
        other.bus_cycles_complete = 0;
        other.bus_cycles_lost = 0;
        other.bus_cycles_short = 0;
        other.bus_cycles_not_op = 0;
        other.bus_longest_gap_cycles = 0;
        other.dc_used = 0;
        other.dc_offset_ns = 0;
        other.dc_offset_abs_p50_ns = 0;
        other.dc_offset_abs_p99_ns = 0;
        other.dc_offset_abs_p999_ns = 0;
        other.dc_offset_abs_max_ns = 0;
        other.dc_samples = 0;
        assert_eq!(other, without);
    }

    #[test]
    fn without_distributed_clocks_the_dc_fields_are_zero() {
        let msg = status_of(Some(BusReport {
            dc: None,
            recovering: false,
            ..report()
        }));
        assert_eq!(msg.bus_subdevices, 4);
        assert_eq!(msg.bus_recovering, 0);
        assert_eq!(msg.dc_used, 0);
        assert_eq!(msg.dc_offset_ns, 0);
        assert_eq!(msg.dc_offset_abs_max_ns, 0);
        assert_eq!(msg.dc_samples, 0);
    }

    #[test]
    fn without_a_bus_the_section_is_zero() {
        let msg = status_of(None);
        assert_eq!(msg.bus_subdevices, 0);
        assert_eq!(msg.bus_positions(), 0);
        assert_eq!(msg.bus_states, [0; 32]);
        assert_eq!(msg.bus_al_codes, [0; 32]);
        assert_eq!(msg.bus_cycles_complete, 0);
        assert_eq!(msg.dc_used, 0);
    }
}
