"""A client of a running ``kerfd``: control requests, the setpoint stream, and streaming a
program with the flow control of docs/PROTOCOL.md.
"""

import ctypes
import itertools
import math
import os
import secrets
import time
from dataclasses import dataclass, field
from typing import Iterable, Optional

import iceoryx2 as iox2

from . import moves as mv
from . import protocol as p


class KerfError(Exception):
    """No daemon, a service that cannot be opened, an unanswered request."""


def _copy(ptr, cls):
    """A copy of the ``cls`` at address ``ptr`` (shared memory is not kept)."""
    return cls.from_buffer_copy(ctypes.string_at(ptr, ctypes.sizeof(cls)))


# ---------------------------------------------------------------------------------------
# Parsed messages
# ---------------------------------------------------------------------------------------


#: ``pause_reason`` -> its name in ``kerf status --json`` (``pause.reason``); any other
#: value is ``"none"`` (crates/kerf/src/status_view.rs, ``pause_name``).
PAUSE_NAMES = {
    p.PAUSE_PROGRAM_STOP: "program_stop",
    p.PAUSE_OPTIONAL_STOP: "optional_stop",
    p.PAUSE_PALLET_CHANGE: "pallet_change",
    p.PAUSE_SINGLE_BLOCK: "single_block",
    p.PAUSE_TOOL_CHANGE: "tool_change",
    p.PAUSE_TOOL_CHANGING: "tool_changing",
    p.PAUSE_WAIT_INPUT: "wait_input",
    p.PAUSE_AT_SPEED: "spindle_at_speed",
    p.PAUSE_ORIENT: "spindle_orient",
}

#: The pauses that wait for cycle start (:meth:`Client.resume`, ``kerf resume``) rather
#: than for the machine.
OPERATOR_PAUSES = (
    p.PAUSE_PROGRAM_STOP,
    p.PAUSE_OPTIONAL_STOP,
    p.PAUSE_PALLET_CHANGE,
    p.PAUSE_SINGLE_BLOCK,
    p.PAUSE_TOOL_CHANGE,
)


def pause_name(reason):
    """The name of a ``pause_reason`` as ``kerf status --json`` writes it
    (``"program_stop"``, ``"tool_change"``, ``"spindle_at_speed"``, ...; ``"none"`` for
    ``PAUSE_NONE`` and any unknown value)."""
    return PAUSE_NAMES.get(reason, "none")


def _num(v):
    """A number as ``kerf status --json`` writes it: None (``null``) when not finite."""
    return v if math.isfinite(v) else None


class Status:
    """A parsed :class:`~kerf_client.protocol.StatusMsg`: every field as an attribute
    (arrays as tuples, ``fault_text``, ``fault_dump`` and ``pause_text`` as ``str``,
    ``rt``, ``program_done``, ``bus_recovering``, ``dc_used`` and ``spindle_at_speed`` as
    bool), plus ``state_name``, ``program_end_name``, ``drives_name``, ``position`` (X, Y,
    Z), ``pause_name``, ``pause_waits_for_operator``, ``pause_message``, and ``machine``
    and ``ethercat`` (sections shaped as ``kerf status --json`` shows them)."""

    def __init__(self, raw: p.StatusMsg):
        self.raw = raw.copy()
        for k, v in raw.to_dict().items():
            setattr(self, k, v)
        self.rt = bool(raw.rt)
        self.program_done = bool(raw.program_done)
        self.bus_recovering = bool(raw.bus_recovering)
        self.dc_used = bool(raw.dc_used)
        self.spindle_at_speed = bool(raw.spindle_at_speed)

    @property
    def state_name(self):
        return p.name_of("STATE", self.state)

    @property
    def program_end_name(self):
        return p.name_of("PROGRAM_END", self.program_end)

    @property
    def drives_name(self):
        return p.name_of("DRIVES", self.drives)

    @property
    def position(self):
        return self.position_mm_deg[:3]

    @property
    def paused(self):
        """True while the program waits at rest for something (``pause_reason`` is not
        ``PAUSE_NONE``; the state is ``STATE_PAUSED`` unless a hold or a fault says
        more)."""
        return self.pause_reason != p.PAUSE_NONE

    @property
    def pause_name(self):
        """``pause_reason`` by name, as ``kerf status --json``'s ``pause.reason``."""
        return pause_name(self.pause_reason)

    @property
    def pause_waits_for_operator(self):
        """True when the pause waits for cycle start (:meth:`Client.resume`): a program
        stop, an optional stop, a pallet change, single block or a manual tool change;
        False when it waits for the machine (or there is none)."""
        return self.pause_reason in OPERATOR_PAUSES

    @property
    def pause_message(self):
        """What the program waits for, for a person, as ``kerf status`` says it ("paused
        at line 12 (M0, program stop): `kerf resume` to continue"); None when it waits
        for nothing."""
        line, value = self.pause_line, self.pause_value
        resume = "`kerf resume` to continue"
        r = self.pause_reason
        if r == p.PAUSE_PROGRAM_STOP:
            return f"paused at line {line} (M0, program stop): {resume}"
        if r == p.PAUSE_OPTIONAL_STOP:
            return f"paused at line {line} (M1, optional stop): {resume}"
        if r == p.PAUSE_PALLET_CHANGE:
            return f"paused at line {line} (M60, pallet change): {resume}"
        if r == p.PAUSE_SINGLE_BLOCK:
            return f"paused after line {line} (single block): {resume}"
        if r == p.PAUSE_TOOL_CHANGE:
            what = self.pause_text or f"insert tool T{value}"
            return f"paused at line {line} (M6): {what}, then `kerf resume`"
        if r == p.PAUSE_TOOL_CHANGING:
            return f"waiting at line {line} for the tool changer to load tool T{value}"
        if r == p.PAUSE_WAIT_INPUT:
            return f"waiting at line {line} for input {value} (M66)"
        if r == p.PAUSE_AT_SPEED:
            return f"waiting at line {line} for the spindle to reach its speed"
        if r == p.PAUSE_ORIENT:
            return f"waiting at line {line} for the spindle's orientation (M19)"
        return None

    @property
    def machine(self):
        """The machine section as ``kerf status --json`` shows it, a dict with the same
        keys and shapes (numbers that are not finite are None, JSON's ``null``):

        - ``pause``: None, or ``reason`` (:func:`pause_name`), ``line``, ``value``,
          ``waits_for_operator``, ``text`` (:attr:`pause_message`);
        - ``switches``: ``optional_stop``, ``block_delete``, ``single_block`` (bool);
        - ``tool``: ``in_spindle`` (0 none), ``length_mm``, ``changer`` (``"none"``,
          ``"manual"``, ``"automatic"``);
        - ``spindle``: None without one, or ``kind`` (``"drive"``, ``"outputs"``), ``dir``
          (1, -1, 0), ``programmed_rpm``, ``commanded_rpm``, ``actual_rpm``, ``at_speed``,
          ``override_pct``, ``override_enabled``;
        - ``feed_override_enabled`` (bool);
        - ``coolant``: ``mist``, ``flood`` (bool);
        - ``io``: ``digital_outputs``, ``digital_inputs`` (bit n: number n on, as ints),
          ``analog_outputs``, ``analog_inputs`` (lists of 16);
        - ``input_result``: None before the first wait on an input (M66) ended, else
          ``seq``, ``program_id``, ``line``, ``value`` (``#5399``: -1 after a time-out).
        """
        pause = None
        if self.pause_reason != p.PAUSE_NONE:
            pause = {
                "reason": self.pause_name,
                "line": self.pause_line,
                "value": self.pause_value,
                "waits_for_operator": self.pause_waits_for_operator,
                "text": self.pause_message or "",
            }
        changer = {p.TOOL_CHANGER_MANUAL: "manual",
                   p.TOOL_CHANGER_AUTOMATIC: "automatic"}.get(self.tool_changer, "none")
        spindle = None
        if self.spindle_kind != p.SPINDLE_NONE:
            spindle = {
                "kind": "drive" if self.spindle_kind == p.SPINDLE_DRIVE else "outputs",
                "dir": self.spindle_dir,
                "programmed_rpm": _num(self.spindle_programmed_rpm),
                "commanded_rpm": _num(self.spindle_commanded_rpm),
                "actual_rpm": _num(self.spindle_actual_rpm),
                "at_speed": self.spindle_at_speed,
                "override_pct": _num(self.spindle_override_pct),
                "override_enabled": bool(self.overrides_enabled & p.OVERRIDES_SPINDLE),
            }
        input_result = None
        if self.input_result_seq != 0:
            input_result = {
                "seq": self.input_result_seq,
                "program_id": self.input_result_program,
                "line": self.input_result_line,
                "value": _num(self.input_result_value),
            }
        return {
            "pause": pause,
            "switches": {
                "optional_stop": bool(self.switches & p.SWITCH_OPTIONAL_STOP),
                "block_delete": bool(self.switches & p.SWITCH_BLOCK_DELETE),
                "single_block": bool(self.switches & p.SWITCH_SINGLE_BLOCK),
            },
            "tool": {
                "in_spindle": self.tool_in_spindle,
                "length_mm": _num(self.tool_length_mm),
                "changer": changer,
            },
            "spindle": spindle,
            "feed_override_enabled": bool(self.overrides_enabled & p.OVERRIDES_FEED),
            "coolant": {
                "mist": bool(self.coolant & p.COOLANT_MIST),
                "flood": bool(self.coolant & p.COOLANT_FLOOD),
            },
            "io": {
                "digital_outputs": self.digital_outputs,
                "digital_inputs": self.digital_inputs,
                "analog_outputs": [_num(x) for x in self.analog_outputs],
                "analog_inputs": [_num(x) for x in self.analog_inputs],
            },
            "input_result": input_result,
        }

    @property
    def ethercat(self):
        """None without an EtherCAT bus; else a dict as ``kerf status --json``'s
        ``"ethercat"`` (without the subdevices' names, which come from the machine's
        configuration): ``subdevices`` (``position``, ``state`` such as ``"SAFE-OP"`` or
        ``"unknown"``, ``al_status_code``), ``recovering``, ``cycles`` (``complete``,
        ``lost``, ``short``, ``not_op``, ``longest_gap``) and ``dc`` (None, or
        ``offset_ns``, ``offset_abs_ns`` with ``p50``, ``p99``, ``p999``, ``max``, and
        ``samples``)."""
        n = min(self.bus_subdevices, p.BUS_MAX_SUBDEVICES)
        if n == 0:
            return None
        states = {v: k.replace("_", "-") for v, k in p.names("BUS_STATE").items()}
        return {
            "subdevices": [
                {
                    "position": i,
                    "state": states.get(self.bus_states[i], "unknown"),
                    "al_status_code": self.bus_al_codes[i],
                }
                for i in range(n)
            ],
            "recovering": self.bus_recovering,
            "cycles": {
                "complete": self.bus_cycles_complete,
                "lost": self.bus_cycles_lost,
                "short": self.bus_cycles_short,
                "not_op": self.bus_cycles_not_op,
                "longest_gap": self.bus_longest_gap_cycles,
            },
            "dc": {
                "offset_ns": self.dc_offset_ns,
                "offset_abs_ns": {
                    "p50": self.dc_offset_abs_p50_ns,
                    "p99": self.dc_offset_abs_p99_ns,
                    "p999": self.dc_offset_abs_p999_ns,
                    "max": self.dc_offset_abs_max_ns,
                },
                "samples": self.dc_samples,
            } if self.dc_used else None,
        }

    def __repr__(self):
        return (
            f"Status(state={self.state_name}, position={self.position_mm_deg}, "
            f"program_id={self.program_id}, program_end={self.program_end_name}, "
            f"program_done={self.program_done}, moves_received={self.moves_received}, "
            f"window_items={self.window_items}, rejected={self.rejected}, "
            f"fault={self.fault}, fault_text={self.fault_text!r}, "
            f"pause={self.pause_name})"
        )


@dataclass
class Reply:
    """A parsed :class:`~kerf_client.protocol.Response`."""

    accepted: bool
    reason: int
    message: str
    fate: int
    request_id: int
    status: Status
    raw: p.Response = field(repr=False)

    @property
    def reason_name(self):
        return p.name_of("REASON", self.reason)

    @property
    def fate_name(self):
        return p.name_of("PROGRAM_FATE", self.fate)

    @staticmethod
    def parse(raw: p.Response) -> "Reply":
        return Reply(
            accepted=bool(raw.accepted),
            reason=raw.reason,
            message=p.decode_text(bytes(raw.message)),
            fate=raw.program_fate,
            request_id=raw.request_id,
            status=Status(raw.status),
            raw=raw.copy(),
        )


#: Fates after which nothing changes any more.
FINAL_FATES = (p.PROGRAM_FATE_FINISHED, p.PROGRAM_FATE_ABORTED, p.PROGRAM_FATE_REFUSED)

#: ``program_end`` -> the fate it means.
_END_FATE = {
    p.PROGRAM_END_FINISHED: p.PROGRAM_FATE_FINISHED,
    p.PROGRAM_END_ABORTED: p.PROGRAM_FATE_ABORTED,
    p.PROGRAM_END_REFUSED: p.PROGRAM_FATE_REFUSED,
}


@dataclass
class ProgramResult:
    """What :meth:`Client.run_program` returns."""

    program_id: int
    #: ``PROGRAM_FATE_*`` (final: finished, aborted or refused).
    fate: int
    #: The daemon's reason for a refused or aborted program.
    message: str
    #: Items published (BEGIN and END not counted).
    items_sent: int
    #: Whether END was published.
    end_sent: bool
    #: The status of the last answer.
    status: Status

    @property
    def fate_name(self):
        return p.name_of("PROGRAM_FATE", self.fate)


# ---------------------------------------------------------------------------------------
# The setpoint stream
# ---------------------------------------------------------------------------------------


class Setpoint:
    """One parsed :class:`~kerf_client.protocol.SetpointMsg`, with what the stream
    detected before it: ``lost_before`` samples lost (a gap in ``seq``) and
    ``skipped_before`` periods the daemon skipped (the increase of ``missed_periods``)."""

    __slots__ = (
        "raw", "version", "state", "seq", "time_ns", "program_id", "program_cycle",
        "position_mm_deg", "velocity_mm_deg_s", "feed_mm_s", "line", "axes_mask",
        "missed_periods", "lost_before", "skipped_before",
    )

    def __init__(self, raw: p.SetpointMsg, lost_before=0, skipped_before=0):
        self.raw = raw
        self.version = raw.version
        self.state = raw.state
        self.seq = raw.seq
        self.time_ns = raw.time_ns
        self.program_id = raw.program_id
        self.program_cycle = raw.program_cycle
        self.position_mm_deg = tuple(raw.position_mm_deg)
        self.velocity_mm_deg_s = tuple(raw.velocity_mm_deg_s)
        self.feed_mm_s = raw.feed_mm_s
        self.line = raw.line
        self.axes_mask = raw.axes_mask
        self.missed_periods = raw.missed_periods
        self.lost_before = lost_before
        self.skipped_before = skipped_before

    def __repr__(self):
        return (
            f"Setpoint(seq={self.seq}, program_id={self.program_id}, "
            f"program_cycle={self.program_cycle}, position={self.position_mm_deg}, "
            f"feed_mm_s={self.feed_mm_s}, line={self.line})"
        )


class SetpointStream:
    """A subscription to ``kerf/<machine>/setpoints``. It buffers up to 16,384 samples
    (16 s at 1 kHz) from the moment it is created: subscribe before you start what you
    want to watch, then read often enough.

    Gap detection: ``lost`` counts the samples lost so far (gaps in ``seq``),
    ``skipped_periods`` the periods the daemon skipped between samples read (increases of
    ``missed_periods``); each :class:`Setpoint` carries its own ``lost_before`` and
    ``skipped_before``. Samples of another protocol version are ignored (``ignored``)."""

    def __init__(self, subscriber, service):
        self._subscriber = subscriber
        self._service = service
        self.last_seq = None
        self.last_missed = None
        self.lost = 0
        self.skipped_periods = 0
        self.ignored = 0
        self.received = 0

    def receive(self) -> Optional[Setpoint]:
        """The next sample, or None when none is waiting."""
        while True:
            sample = self._subscriber.receive()
            if sample is None:
                return None
            raw = _copy(sample.payload_ptr, p.SetpointMsg)
            sample.delete()
            if raw.version != p.PROTOCOL_VERSION:
                self.ignored += 1
                continue
            lost = skipped = 0
            if self.last_seq is not None:
                lost = max(0, raw.seq - self.last_seq - 1)
                skipped = max(0, raw.missed_periods - self.last_missed)
            self.lost += lost
            self.skipped_periods += skipped
            self.last_seq = raw.seq
            self.last_missed = raw.missed_periods
            self.received += 1
            return Setpoint(raw, lost, skipped)

    def drain(self):
        """Every sample waiting now, in order."""
        out = []
        while True:
            s = self.receive()
            if s is None:
                return out
            out.append(s)

    def __iter__(self):
        """Yields samples as they come, without end (sleeps briefly while none waits)."""
        while True:
            s = self.receive()
            if s is None:
                time.sleep(0.0005)
                continue
            yield s

    def close(self):
        if self._subscriber is not None:
            self._subscriber.delete()
            self._subscriber = None
            self._service = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# ---------------------------------------------------------------------------------------
# The client
# ---------------------------------------------------------------------------------------

_node_counter = itertools.count()


def new_program_id():
    """64 random bits, never 0 (program ids must be unique for the daemon's lifetime)."""
    while True:
        pid = secrets.randbits(64)
        if pid:
            return pid


class Client:
    """A client of the daemon of ``machine`` (the ``machine`` of its configuration).

    Opens the control service at once (raises :class:`KerfError` when no daemon serves
    it); the moves publisher and setpoint subscriptions are opened when first needed.
    ``timeout_s`` bounds the wait for each answer."""

    def __init__(self, machine="default", *, timeout_s=5.0):
        self.machine = p.check_machine(machine)
        self.timeout_s = timeout_s
        iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
        name = f"kerf-py-{os.getpid()}-{next(_node_counter)}"
        try:
            self._node = (
                iox2.NodeBuilder.new()
                .name(iox2.NodeName.new(name))
                .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
                .create(iox2.ServiceType.Ipc)
            )
        except Exception as e:  # noqa: BLE001 - iceoryx2's errors are plain exceptions
            raise KerfError(f"cannot create an iceoryx2 node: {e!r}") from e
        try:
            self._control = (
                self._node.service_builder(
                    iox2.ServiceName.new(p.service_name(machine, p.SERVICE_CONTROL))
                )
                .request_response(p.Request, p.Response)
                .open()
            )
            self._client = self._control.client_builder().create()
        except Exception as e:  # noqa: BLE001
            raise KerfError(
                f"no daemon for machine `{machine}` (cannot open "
                f"{p.service_name(machine, p.SERVICE_CONTROL)}: {e!r})"
            ) from e
        self._next_id = 1
        self._moves = None
        self._publisher = None

    # -- control ---------------------------------------------------------------------

    def request(
        self, kind, value=0.0, program_id=0, timeout_s=None, *, index=0, mode=0, speed=0.0
    ) -> Reply:
        """Sends one ``REQUEST_*`` (with ``value``, ``program_id``, ``index``, ``mode`` and
        ``speed`` as the kind uses them; 0 otherwise) and waits for its answer."""
        if not 0 <= index <= 0xFFFF_FFFF:
            raise ValueError(f"index {index}: not a u32")
        req = p.Request()
        req.version = p.PROTOCOL_VERSION
        req.kind = kind
        req.id = self._next_id
        self._next_id += 1
        req.value = value
        req.program_id = program_id
        req.index = index
        req.mode = mode
        req.speed = speed
        pending = self._client.send_copy(req)
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        other_versions = 0
        try:
            while True:
                resp = pending.receive()
                if resp is not None:
                    raw = _copy(resp.payload_ptr, p.Response)
                    resp.delete()
                    if raw.version != p.PROTOCOL_VERSION:
                        other_versions += 1  # clients ignore other versions
                    elif raw.request_id != req.id:
                        raise KerfError(
                            f"answer to request {raw.request_id}, expected {req.id}"
                        )
                    else:
                        return Reply.parse(raw)
                if time.monotonic() > deadline:
                    extra = (
                        f" ({other_versions} answers of another protocol version ignored)"
                        if other_versions
                        else ""
                    )
                    raise KerfError(
                        f"no answer from the daemon of `{self.machine}` to request "
                        f"kind {kind}{extra}"
                    )
                time.sleep(0.0002)
        finally:
            pending.delete()

    def status(self) -> Reply:
        """REQUEST_STATUS: the status only."""
        return self.request(p.REQUEST_STATUS)

    def hold(self) -> Reply:
        """REQUEST_HOLD: feed hold (answered once the cycle has applied it)."""
        return self.request(p.REQUEST_HOLD)

    def resume(self) -> Reply:
        """REQUEST_RESUME, cycle start: resume after a feed hold, and go on after a pause
        that waits for the operator (a program stop M0, an optional stop M1, a pallet
        change M60, single block, or a manual tool change once the tool is in the
        spindle: ``Status.pause_waits_for_operator``). Refused with ``REASON_NOT_ALLOWED``
        when there is nothing to resume."""
        return self.request(p.REQUEST_RESUME)

    def abort(self) -> Reply:
        """REQUEST_ABORT: stop smoothly on the path, drop the queued moves, end the
        open program."""
        return self.request(p.REQUEST_ABORT)

    def override(self, pct) -> Reply:
        """REQUEST_OVERRIDE: feed override, 0 to 200 percent."""
        return self.request(p.REQUEST_OVERRIDE, value=float(pct))

    def spindle_override(self, pct) -> Reply:
        """REQUEST_SPINDLE_OVERRIDE: spindle override, 0 to 200 percent (it applies while
        the spindle override is enabled: M48, M51)."""
        return self.request(p.REQUEST_SPINDLE_OVERRIDE, value=float(pct))

    def optional_stop(self, on) -> Reply:
        """REQUEST_OPTIONAL_STOP: the optional-stop switch; while on, M1 pauses the
        program like M0."""
        return self.request(p.REQUEST_OPTIONAL_STOP, value=1.0 if on else 0.0)

    def block_delete(self, on) -> Reply:
        """REQUEST_BLOCK_DELETE: the block-delete switch; while on, programs sent from
        then on skip their lines that start with ``/`` (the planner process reads the
        switch when it starts a program; :meth:`run_program` sends resolved items, so it is
        for the planner that builds them to honour it)."""
        return self.request(p.REQUEST_BLOCK_DELETE, value=1.0 if on else 0.0)

    def single_block(self, on) -> Reply:
        """REQUEST_SINGLE_BLOCK: the single-block switch; while on, the program pauses
        after every block the daemon plans from then on (:meth:`resume` runs the next)."""
        return self.request(p.REQUEST_SINGLE_BLOCK, value=1.0 if on else 0.0)

    def set_input(self, n, on) -> Reply:
        """REQUEST_SET_INPUT: set simulated digital input ``n`` (0 to 63) on or off;
        refused with ``REASON_NOT_ALLOWED`` for an input that is not configured or not
        simulated, ``REASON_BAD_VALUE`` for a number out of range."""
        return self.request(p.REQUEST_SET_INPUT, value=1.0 if on else 0.0, index=n)

    def set_analog_input(self, n, value) -> Reply:
        """REQUEST_SET_ANALOG_INPUT: set simulated analog input ``n`` (0 to 15) to
        ``value`` (finite); refused as :meth:`set_input`."""
        return self.request(p.REQUEST_SET_ANALOG_INPUT, value=float(value), index=n)

    def jog(self, axis, direction, speed=0.0) -> Reply:
        """REQUEST_JOG, JOG_CONTINUOUS: jog axis ``axis`` (0 to 5 = X to C) in
        ``direction`` (+1 or -1) at ``speed`` mm/s or deg/s (0: the configured default).
        The axis moves while this is renewed within the daemon's dead-man time
        (``[jog] deadman_ms``): call it again every few tens of milliseconds."""
        return self.request(p.REQUEST_JOG, value=1.0 if direction > 0 else -1.0,
                            index=axis, mode=p.JOG_CONTINUOUS, speed=float(speed))

    def jog_step(self, axis, step, speed=0.0) -> Reply:
        """REQUEST_JOG, JOG_STEP: move axis ``axis`` by ``step`` (signed, not 0)."""
        return self.request(p.REQUEST_JOG, value=float(step), index=axis,
                            mode=p.JOG_STEP, speed=float(speed))

    def jog_to(self, axis, position, speed=0.0) -> Reply:
        """REQUEST_JOG, JOG_TO: move axis ``axis`` to machine coordinate ``position``."""
        return self.request(p.REQUEST_JOG, value=float(position), index=axis,
                            mode=p.JOG_TO, speed=float(speed))

    def jog_stop(self, axis) -> Reply:
        """REQUEST_JOG_STOP: stop the jog of axis ``axis`` on a jerk-limited ramp."""
        return self.request(p.REQUEST_JOG_STOP, index=axis)

    def home(self, axes_mask) -> Reply:
        """REQUEST_HOME: home the axes of ``axes_mask`` (bit i: axis i) in their home
        sequence; the status's ``homing``, ``home_phase`` and ``homed`` tell the
        progress."""
        return self.request(p.REQUEST_HOME, index=axes_mask)

    def reset(self) -> Reply:
        """REQUEST_RESET: clear the drive side's latched fault once its cause is gone."""
        return self.request(p.REQUEST_RESET)

    def dump(self) -> Reply:
        """REQUEST_DUMP: write the black box; ``message`` is the file's path."""
        return self.request(p.REQUEST_DUMP)

    def program_fate(self, program_id) -> Reply:
        """REQUEST_PROGRAM: the fate of program ``program_id`` in ``Reply.fate``
        (``PROGRAM_FATE_*``); ``message`` says why a program was refused or aborted."""
        if not program_id:
            raise ValueError("program_id 0 is no program")
        return self.request(p.REQUEST_PROGRAM, program_id=program_id)

    # -- setpoints -------------------------------------------------------------------

    def setpoints(self) -> SetpointStream:
        """A new subscription to the setpoint stream (it buffers from now on)."""
        try:
            service = (
                self._node.service_builder(
                    iox2.ServiceName.new(p.service_name(self.machine, p.SERVICE_SETPOINTS))
                )
                .publish_subscribe(p.SetpointMsg)
                .open()
            )
            sub = service.subscriber_builder().create()
        except Exception as e:  # noqa: BLE001
            raise KerfError(f"cannot subscribe to the setpoints: {e!r}") from e
        return SetpointStream(sub, service)

    # -- moves -----------------------------------------------------------------------

    def _move_publisher(self):
        if self._publisher is None:
            try:
                self._moves = (
                    self._node.service_builder(
                        iox2.ServiceName.new(p.service_name(self.machine, p.SERVICE_MOVES))
                    )
                    .publish_subscribe(p.MoveMsg)
                    .open()
                )
                self._publisher = (
                    self._moves.publisher_builder()
                    .backpressure_strategy(iox2.BackpressureStrategy.RetryUntilDelivered)
                    .create()
                )
            except Exception as e:  # noqa: BLE001
                raise KerfError(f"cannot publish moves: {e!r}") from e
        return self._publisher

    def publish(self, msg: p.MoveMsg):
        """Publishes one MoveMsg as it is, with no check and no flow control (for tools
        and tests; :meth:`run_program` is the way to stream a program). The publisher stays
        open until :meth:`close`: the daemon stops a program whose publisher went away."""
        self._move_publisher().send_copy(msg)

    def run_program(self, items: Iterable[p.MoveMsg], start_mm_deg, program_id=None, *,
                    count=None, timeout_s=None, poll_s=0.002, on_sent=None
                    ) -> ProgramResult:
        """Streams one program: BEGIN at ``start_mm_deg`` (X, Y, Z mm, optionally A, B, C
        degrees: the machine position it starts from), the ``items`` (MoveMsg of kind
        LINE, ARC or EVENT, e.g. from :mod:`kerf_client.moves`; copies are stamped with the
        program id and seq 1, 2, ..., and line k where their line is 0), then END; waits
        for the program's final fate and returns it.

        Flow control (docs/PROTOCOL.md, stream rule 7): item k is published only after a
        status with ``program_id`` equal to this program's and ``moves_received >= k -
        window_items`` was seen (before that, the first ``window_items`` items go at once).
        As soon as the program has ended (``program_end`` set for it, or a final fate from
        REQUEST_PROGRAM: aborted or refused) nothing more is sent, END included.

        ``program_id``: default 64 random bits. ``count``: the number of items announced
        in BEGIN (default ``len(items)`` when it has one, else 0 = unknown).
        ``timeout_s``: give up (KerfError) if the fate is not final by then (None: wait
        as long as the program runs). ``on_sent(k)`` is called after item k was sent."""
        if program_id is None:
            program_id = new_program_id()
        if count is None:
            try:
                count = len(items)  # type: ignore[arg-type]
            except TypeError:
                count = 0
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        publisher = self._move_publisher()
        window = self.status().status.window_items
        if window <= 0:
            raise KerfError("the daemon advertises no flow-control window")

        publisher.send_copy(mv.begin(program_id, start_mm_deg, count))

        acked = 0           # moves_received of ours (0 until the daemon took BEGIN)
        ended = False       # the program ended early (aborted or refused)
        last_reply = None
        sent = 0
        last_check = time.monotonic()

        def check():
            """Polls the daemon: updates ``acked``; True when the program has ended."""
            nonlocal acked, last_reply, last_check
            last_check = time.monotonic()
            r = self.status()
            last_reply = r
            s = r.status
            if s.program_id == program_id:
                acked = s.moves_received
                return s.program_end != p.PROGRAM_END_NONE
            # Not (or no longer) the current program: its BEGIN may not have been taken
            # yet, or it was refused before becoming current.
            f = self.program_fate(program_id)
            last_reply = f
            return f.fate in (p.PROGRAM_FATE_ABORTED, p.PROGRAM_FATE_REFUSED,
                              p.PROGRAM_FATE_FINISHED)

        for k, item in enumerate(items, start=1):
            # Wait until item k may go; look at the daemon at least every 20 ms anyway
            # so that an aborted or refused program stops at once.
            while k > acked + window or time.monotonic() - last_check > 0.02:
                if check():
                    ended = True
                    break
                if k > acked + window:
                    if deadline is not None and time.monotonic() > deadline:
                        raise KerfError(f"program {program_id}: timed out while streaming")
                    time.sleep(poll_s)
            if ended:
                break
            msg = item.copy()
            if msg.kind not in (p.KIND_LINE, p.KIND_ARC, p.KIND_EVENT):
                raise ValueError(f"item {k}: kind {msg.kind} is not an item")
            msg.program_id = program_id
            msg.seq = k
            if msg.line == 0:
                msg.line = k
            publisher.send_copy(msg)
            sent = k
            if on_sent is not None:
                on_sent(k)

        end_sent = False
        if not ended and not check():
            publisher.send_copy(mv.end(program_id, sent + 1, sent))
            end_sent = True

        # Wait for the final fate.
        while True:
            f = self.program_fate(program_id)
            if f.accepted and f.fate in FINAL_FATES:
                return ProgramResult(program_id, f.fate, f.message, sent, end_sent, f.status)
            s = f.status
            if s.program_id == program_id and s.program_end in _END_FATE:
                # The status tells the fate of the current program too ("final once
                # program_end is not PROGRAM_END_NONE"), also from a daemon that does not
                # answer REQUEST_PROGRAM.
                return ProgramResult(program_id, _END_FATE[s.program_end], s.fault_text,
                                     sent, end_sent, s)
            if deadline is not None and time.monotonic() > deadline:
                raise KerfError(
                    f"program {program_id}: no final fate within {timeout_s} s "
                    f"(fate {f.fate_name}, {f.status!r})"
                )
            time.sleep(max(poll_s, 0.005))

    # -- life --------------------------------------------------------------------------

    def close(self):
        """Closes the ports (a program still streaming from this client stops)."""
        for name in ("_publisher", "_client"):
            port = getattr(self, name, None)
            if port is not None:
                port.delete()
                setattr(self, name, None)
        self._moves = None
        self._control = None
        self._node = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def wait_for_daemon(machine="default", timeout_s=30.0, **kwargs) -> Client:
    """A :class:`Client` once the daemon of ``machine`` answers a status request."""
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        try:
            c = Client(machine, **kwargs)
            c.status()
            return c
        except KerfError as e:
            last = e
            time.sleep(0.05)
    raise KerfError(f"the daemon of `{machine}` never answered: {last}")

