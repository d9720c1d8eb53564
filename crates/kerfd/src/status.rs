//! The status message the control thread answers with, from the cycle's snapshot.

use super::*;

/// The snapshot before the cycle's first report.
pub(crate) fn idle_snapshot() -> Snapshot {
    Snapshot {
        cycles: 0,
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
        // The refused program's fault is shown until the next program begins.
        (MachineState::Idle, Some(_)) => MachineState::Fault,
        (state, _) => state,
    }
    .as_u32();
    msg.line = s.line;
    msg.position_mm_deg = s.position;
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
    msg
}
