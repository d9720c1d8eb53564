"""Kerf's shared-memory protocol, version 5 (docs/PROTOCOL.md), as ctypes structures.

Every message is a C struct of u8, u16, u32, i32, u64, i64 and f64 (native byte order, 8-byte
alignment, no padding). The iceoryx2 Python bindings take a payload's type name from a
static ``type_name()`` method, which here returns the name the Rust crate gives the type
with ``#[type_name("kerf.MoveMsg.v6")]``: iceoryx2 matches the two ends of a service by that
name, the size and the alignment, so a layout that drifted would not even connect.

The tests in ``clients/python/tests/test_layout.py`` parse docs/PROTOCOL.md's tables and
compare every offset, size, type and constant with this module.
"""

import ctypes
import math

# ---------------------------------------------------------------------------------------
# Constants (the table "Constants" of docs/PROTOCOL.md, every row)
# ---------------------------------------------------------------------------------------

PROTOCOL_VERSION = 6

KIND_BEGIN = 1
KIND_LINE = 2
KIND_ARC = 3
KIND_EVENT = 4
KIND_END = 5

FLAG_RAPID = 1
FLAG_ABC = 2
FLAG_EVENT_VALUE = 4
FLAG_NAIVE_CAM = 8
FLAG_EVENT_P = 16
FLAG_EVENT_Q = 32

CORNER_EXACT_STOP = 1
CORNER_BLEND_DEFAULT = 2
CORNER_BLEND_TOLERANCE = 3

EVENT_M0 = 1
EVENT_M1 = 2
EVENT_M2 = 3
EVENT_M30 = 4
EVENT_M3 = 5
EVENT_M4 = 6
EVENT_M5 = 7
EVENT_M6 = 8
EVENT_M7 = 9
EVENT_M8 = 10
EVENT_M9 = 11
EVENT_S = 12
EVENT_T = 13
EVENT_G4 = 14
EVENT_M60 = 15
EVENT_MSG = 16
EVENT_DEBUG = 17
EVENT_PRINT = 18
EVENT_M19 = 19
EVENT_M48 = 20
EVENT_M49 = 21
EVENT_M50 = 22
EVENT_M51 = 23
EVENT_M52 = 24
EVENT_M53 = 25
EVENT_LOG = 26
EVENT_M62 = 27
EVENT_M63 = 28
EVENT_M64 = 29
EVENT_M65 = 30
EVENT_M66 = 31
EVENT_M66_ANALOG = 32
EVENT_M67 = 33
EVENT_M68 = 34
EVENT_USER_M100 = 100
EVENT_USER_M199 = 199

STATE_IDLE = 0
STATE_RUNNING = 1
STATE_HOLDING = 2
STATE_STARVED = 3
STATE_FAULT = 4
STATE_STOPPING = 5
STATE_PAUSED = 6
STATE_MANUAL = 7

REQUEST_STATUS = 1
REQUEST_HOLD = 2
REQUEST_RESUME = 3
REQUEST_ABORT = 4
REQUEST_OVERRIDE = 5
REQUEST_RESET = 6
REQUEST_DUMP = 7
REQUEST_INJECT = 8
REQUEST_PROGRAM = 9
REQUEST_OPTIONAL_STOP = 10
REQUEST_BLOCK_DELETE = 11
REQUEST_SINGLE_BLOCK = 12
REQUEST_SPINDLE_OVERRIDE = 13
REQUEST_SET_INPUT = 14
REQUEST_SET_ANALOG_INPUT = 15
REQUEST_JOG = 16
REQUEST_JOG_STOP = 17
REQUEST_HOME = 18
JOG_CONTINUOUS = 1
JOG_STEP = 2
JOG_TO = 3
HOME_PHASE_IDLE = 0
HOME_PHASE_WAITING = 1
HOME_PHASE_MOVE_OFF = 2
HOME_PHASE_SEARCH = 3
HOME_PHASE_BACK_OFF = 4
HOME_PHASE_LATCH = 5
HOME_PHASE_FINAL = 6

DIGITAL_IO = 64
ANALOG_IO = 16

PAUSE_NONE = 0
PAUSE_PROGRAM_STOP = 1
PAUSE_OPTIONAL_STOP = 2
PAUSE_PALLET_CHANGE = 3
PAUSE_SINGLE_BLOCK = 4
PAUSE_TOOL_CHANGE = 5
PAUSE_TOOL_CHANGING = 6
PAUSE_WAIT_INPUT = 7
PAUSE_AT_SPEED = 8
PAUSE_ORIENT = 9

SWITCH_OPTIONAL_STOP = 1
SWITCH_BLOCK_DELETE = 2
SWITCH_SINGLE_BLOCK = 4

TOOL_CHANGER_NONE = 0
TOOL_CHANGER_MANUAL = 1
TOOL_CHANGER_AUTOMATIC = 2

SPINDLE_NONE = 0
SPINDLE_DRIVE = 1
SPINDLE_OUTPUTS = 2

OVERRIDES_FEED = 1
OVERRIDES_SPINDLE = 2

COOLANT_MIST = 1
COOLANT_FLOOD = 2

REASON_OK = 0
REASON_WRONG_VERSION = 1
REASON_UNKNOWN_KIND = 2
REASON_BAD_VALUE = 3
REASON_NOT_ALLOWED = 4
REASON_NOT_IMPLEMENTED = 5

PROGRAM_END_NONE = 0
PROGRAM_END_FINISHED = 1
PROGRAM_END_ABORTED = 2
PROGRAM_END_REFUSED = 3

PROGRAM_FATE_UNKNOWN = 0
PROGRAM_FATE_RECEIVING = 1
PROGRAM_FATE_RUNNING = 2
PROGRAM_FATE_FINISHED = 3
PROGRAM_FATE_ABORTED = 4
PROGRAM_FATE_REFUSED = 5

DRIVES_ENABLING = 1
DRIVES_RUNNING = 2
DRIVES_HOLDING = 3
DRIVES_QUICK_STOP = 4
DRIVES_STOPPED = 5
DRIVES_RESETTING = 6

SAFETY_NONE = 0
SAFETY_VELOCITY = 1
SAFETY_ACCELERATION = 2
SAFETY_SOFT_LIMIT = 3
SAFETY_FOLLOWING_ERROR = 4
SAFETY_STREAM_STALL = 5
SAFETY_DRIVE_FAULT = 6
SAFETY_ENABLE_TIMEOUT = 7
SAFETY_DRIVE_DISABLED = 8
SAFETY_FIELDBUS = 9
SAFETY_SUBDEVICE_STATE = 10
SAFETY_SPINDLE_AT_SPEED = 11
SAFETY_SPINDLE_BAND = 12
SAFETY_SPINDLE_ORIENT = 13
SAFETY_TOOL_CHANGE = 14
# The spindle's drive on the fieldbus failed (safety_limit: 0 fault, 1 not enabled, 2 dropped out).
SAFETY_SPINDLE_DRIVE = 15
SAFETY_HOME_SEARCH = 16
SAFETY_HOME_RELEASE = 17
SAFETY_HOME_LATCH = 18
SAFETY_HARD_LIMIT = 19
SAFETY_DRIVE_HOMING = 20
SAFETY_AXIS_NONE = 255

BUS_MAX_SUBDEVICES = 32
BUS_STATE_INIT = 1
BUS_STATE_PRE_OP = 2
BUS_STATE_BOOT = 3
BUS_STATE_SAFE_OP = 4
BUS_STATE_OP = 8

#: Every constant of the table, by name (what the layout test compares with the page).
CONSTANTS = {
    name: value
    for name, value in dict(globals()).items()
    if name.isupper()
    and isinstance(value, int)
    and name.split("_")[0]
    in (
        "PROTOCOL",
        "KIND",
        "FLAG",
        "CORNER",
        "EVENT",
        "STATE",
        "REQUEST",
        "REASON",
        "PROGRAM",
        "DRIVES",
        "SAFETY",
        "BUS",
        "DIGITAL",
        "ANALOG",
        "PAUSE",
        "SWITCH",
        "TOOL",
        "SPINDLE",
        "OVERRIDES",
        "COOLANT",
        "JOG",
        "HOME",
    )
}


def names(prefix):
    """``{value: NAME}`` of the constants ``PREFIX_NAME`` (e.g. ``names("STATE")``)."""
    p = prefix.rstrip("_") + "_"
    return {v: k[len(p):] for k, v in CONSTANTS.items() if k.startswith(p)}


def name_of(prefix, value):
    """The name of ``value`` among the ``PREFIX_*`` constants, lower case, e.g.
    ``name_of("PROGRAM_FATE", 3) == "finished"``; ``"unknown(<value>)"`` if none."""
    n = names(prefix).get(value)
    return n.lower() if n is not None else f"unknown({value})"


# ---------------------------------------------------------------------------------------
# Numbers of the rules that are not in the constants table
# ---------------------------------------------------------------------------------------

#: Services, relative to ``kerf/<machine>/``.
SERVICE_MOVES = "moves"
SERVICE_SETPOINTS = "setpoints"
SERVICE_CONTROL = "control"

#: Arc tolerance (One arc, in millimetres): ``1e-6 mm + 2^-46 * m``.
ARC_TOLERANCE_ABS_MM = 1e-6
ARC_TOLERANCE_REL = 2.0**-46
#: An arc's ``axis`` length may differ from 1 by at most this.
ARC_AXIS_UNIT_TOLERANCE = 1e-9
#: Smallest arc radius, mm.
ARC_MIN_RADIUS_MM = 1e-12
#: BEGIN: each axis within this of the machine position (mm or degree).
BEGIN_POSITION_TOLERANCE = 1e-6
#: How many programs the daemon remembers (ids, fates).
REMEMBERED_PROGRAMS = 256
#: The moves service's buffer holds ``window_items`` + this.
MOVE_BUFFER_MARGIN = 64
#: Setpoint subscriber buffer, samples.
SETPOINT_BUFFER = 16_384


# ---------------------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------------------

u8 = ctypes.c_uint8
u16 = ctypes.c_uint16
u32 = ctypes.c_uint32
i32 = ctypes.c_int32
u64 = ctypes.c_uint64
i64 = ctypes.c_int64
f64 = ctypes.c_double


class _Message(ctypes.Structure):
    """Common helpers: field access by name, a copy, the bytes."""

    TYPE_NAME = ""

    @classmethod
    def type_name(cls):
        """The iceoryx2 type name (matches Rust's ``#[type_name(...)]``)."""
        return cls.TYPE_NAME

    def copy(self):
        """An independent copy."""
        return type(self).from_buffer_copy(bytes(self))

    def to_dict(self):
        """The fields as Python values: arrays as tuples, text fields as ``str``."""
        out = {}
        for name, ctype in self._fields_:
            value = getattr(self, name)
            if isinstance(value, _Message):
                value = value.to_dict()
            elif isinstance(value, ctypes.Array):
                if getattr(ctype, "_type_", None) is u8 and name in type(self).TEXT_FIELDS:
                    value = decode_text(bytes(value))
                else:
                    value = tuple(value)
            out[name] = value
        return out

    TEXT_FIELDS = ()

    def __eq__(self, other):
        return type(self) is type(other) and bytes(self) == bytes(other)

    def __repr__(self):
        fields = ", ".join(f"{k}={v!r}" for k, v in self.to_dict().items())
        return f"{type(self).__name__}({fields})"


def decode_text(raw):
    """A text field: UTF-8, NUL-padded; the bytes before the first NUL."""
    return raw.split(b"\0", 1)[0].decode("utf-8", errors="replace")


class MoveMsg(_Message):
    """One program item on the moves service (256 bytes)."""

    TYPE_NAME = "kerf.MoveMsg.v6"
    _fields_ = [
        ("version", u32),
        ("kind", u32),
        ("program_id", u64),
        ("seq", u64),
        ("line", u32),
        ("flags", u32),
        ("corner", u32),
        ("event_code", u32),
        ("feed_mm_min", f64),
        ("tolerance_mm", f64),
        ("start_mm", f64 * 3),
        ("end_mm", f64 * 3),
        ("center_mm", f64 * 3),
        ("axis", f64 * 3),
        ("sweep_rad", f64),
        ("abc_start_deg", f64 * 3),
        ("abc_end_deg", f64 * 3),
        ("event_value", f64),
        ("count", u64),
        ("naive_cam_mm", f64),
        ("event_p", f64),
        ("event_q", f64),
        ("reserved", u64),
    ]


class SetpointMsg(_Message):
    """The daemon's setpoint of one real-time cycle (160 bytes)."""

    TYPE_NAME = "kerf.SetpointMsg.v6"
    _fields_ = [
        ("version", u32),
        ("state", u32),
        ("seq", u64),
        ("time_ns", u64),
        ("program_id", u64),
        ("program_cycle", u64),
        ("position_mm_deg", f64 * 6),
        ("velocity_mm_deg_s", f64 * 6),
        ("feed_mm_s", f64),
        ("line", u32),
        ("axes_mask", u32),
        ("missed_periods", u64),
    ]


class Request(_Message):
    """A control request (48 bytes)."""

    TYPE_NAME = "kerf.Request.v6"
    _fields_ = [
        ("version", u32),
        ("kind", u32),
        ("id", u64),
        ("value", f64),
        ("program_id", u64),
        ("index", u32),
        ("mode", u32),
        ("speed", f64),
    ]


class StatusMsg(_Message):
    """The daemon's status, embedded in every Response (1200 bytes)."""

    TYPE_NAME = "kerf.StatusMsg.v6"
    TEXT_FIELDS = ("fault_text", "fault_dump", "pause_text")
    _fields_ = [
        ("state", u32),
        ("line", u32),
        ("position_mm_deg", f64 * 6),
        ("override_pct", f64),
        ("queued_moves", u64),
        ("queued_s", f64),
        ("cycles", u64),
        ("overruns", u64),
        ("rt", u32),
        ("program_done", u32),
        ("program_id", u64),
        ("moves_received", u64),
        ("window_items", u64),
        ("rejected", u64),
        ("fault", u32),
        ("axes_mask", u32),
        ("fault_text", u8 * 128),
        ("period_ns", u64),
        ("program_end", u32),
        ("drives", u32),
        ("safety_check", u32),
        ("safety_axis", u32),
        ("safety_value", f64),
        ("safety_limit", f64),
        ("safety_line", u32),
        ("drive_error_code", u32),
        ("safety_cycle", u64),
        ("fault_dump", u8 * 160),
        # The EtherCAT bus; all 0 when the drives are not on one.
        ("bus_subdevices", u32),
        ("bus_recovering", u32),
        ("bus_states", u8 * BUS_MAX_SUBDEVICES),
        ("bus_al_codes", u16 * BUS_MAX_SUBDEVICES),
        ("bus_cycles_complete", u64),
        ("bus_cycles_lost", u64),
        ("bus_cycles_short", u64),
        ("bus_cycles_not_op", u64),
        ("bus_longest_gap_cycles", u32),
        ("dc_used", u32),
        ("dc_offset_ns", i64),
        ("dc_offset_abs_p50_ns", u64),
        ("dc_offset_abs_p99_ns", u64),
        ("dc_offset_abs_p999_ns", u64),
        ("dc_offset_abs_max_ns", u64),
        ("dc_samples", u64),
        # The machine: pause, switches, tool, spindle, coolant, I/O.
        ("pause_reason", u32),
        ("pause_line", u32),
        ("pause_value", u32),
        ("switches", u32),
        ("tool_in_spindle", u32),
        ("tool_changer", u32),
        ("tool_length_mm", f64),
        ("spindle_kind", u32),
        ("spindle_dir", i32),
        ("spindle_programmed_rpm", f64),
        ("spindle_commanded_rpm", f64),
        ("spindle_actual_rpm", f64),
        ("spindle_override_pct", f64),
        ("spindle_at_speed", u32),
        ("overrides_enabled", u32),
        ("coolant", u32),
        ("input_result_line", u32),
        ("digital_outputs", u64),
        ("digital_inputs", u64),
        ("analog_outputs", f64 * ANALOG_IO),
        ("analog_inputs", f64 * ANALOG_IO),
        ("input_result_seq", u64),
        ("input_result_program", u64),
        ("input_result_value", f64),
        ("pause_text", u8 * 96),
        # Homing, jogging and the axes' switches (bit i: axis i).
        ("homed", u32),
        ("homing_required", u32),
        ("homing", u32),
        ("jogging", u32),
        ("home_switches", u32),
        ("min_limit_switches", u32),
        ("max_limit_switches", u32),
        ("limit_released", u32),
        ("home_phase", u8 * 8),
    ]


class Response(_Message):
    """The daemon's answer to a Request (1448 bytes)."""

    TYPE_NAME = "kerf.Response.v6"
    TEXT_FIELDS = ("message",)
    _fields_ = [
        ("version", u32),
        ("accepted", u32),
        ("request_id", u64),
        ("reason", u32),
        ("program_fate", u32),
        ("message", u8 * 224),
        ("status", StatusMsg),
    ]


#: The messages by the name docs/PROTOCOL.md gives them.
MESSAGES = {
    "MoveMsg": MoveMsg,
    "SetpointMsg": SetpointMsg,
    "Request": Request,
    "StatusMsg": StatusMsg,
    "Response": Response,
}


# ---------------------------------------------------------------------------------------
# Service names
# ---------------------------------------------------------------------------------------


def check_machine(machine):
    """Raises ValueError unless ``machine`` is 1 to 64 ASCII letters, digits, ``-``, ``_``."""
    ok = (
        isinstance(machine, str)
        and 1 <= len(machine) <= 64
        and all(c.isascii() and (c.isalnum() or c in "-_") for c in machine)
    )
    if not ok:
        raise ValueError(
            f"machine name {machine!r}: 1 to 64 characters, each an ASCII letter, "
            "digit, `-` or `_`"
        )
    return machine


def service_name(machine, which):
    """``kerf/<machine>/<which>`` (which: moves, setpoints or control)."""
    if which not in (SERVICE_MOVES, SERVICE_SETPOINTS, SERVICE_CONTROL):
        raise ValueError(f"unknown service {which!r}")
    return f"kerf/{check_machine(machine)}/{which}"


# ---------------------------------------------------------------------------------------
# One arc, in millimetres
# ---------------------------------------------------------------------------------------


def _sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]


def _norm(a):
    return math.sqrt(_dot(a, a))


def arc_tolerance_mm(start, end, center, axis, sweep_rad):
    """The arc tolerance ``1e-6 mm + 2^-46 * m`` of docs/PROTOCOL.md, where m is the
    largest magnitude among the coordinates of start, end, centre and the path length."""
    a = list(axis)
    n = _norm(a)
    a = [x / n for x in a]
    u = _sub(start, center)
    u = [u[i] - _dot(u, a) * a[i] for i in range(3)]
    r = _norm(u)
    m = max([abs(x) for x in list(start) + list(end) + list(center)] + [r * abs(sweep_rad)])
    return ARC_TOLERANCE_ABS_MM + ARC_TOLERANCE_REL * m


def arc_sweep_end(start, end, center, axis, sweep_rad):
    """The point ``q`` the sweep leads to (docs/PROTOCOL.md, "One arc, in millimetres")."""
    a = list(axis)
    n = _norm(a)
    a = [x / n for x in a]
    u = _sub(start, center)
    u = [u[i] - _dot(u, a) * a[i] for i in range(3)]
    r = _norm(u)
    e1 = [x / r for x in u]
    e2 = _cross(a, e1)
    h = _dot(_sub(end, start), a)
    c, s = math.cos(sweep_rad) - 1.0, math.sin(sweep_rad)
    return [start[i] + r * (e1[i] * c + e2[i] * s) + a[i] * h for i in range(3)]


def arc_mismatch_mm(start, end, center, axis, sweep_rad):
    """|q - end|: how far the arc's end is from where its sweep leads, mm."""
    q = arc_sweep_end(start, end, center, axis, sweep_rad)
    return _norm(_sub(q, end))


def arc_center_off_plane_mm(start, center, axis):
    """|(start - centre) . a|: the centre's distance from the start's plane, mm."""
    a = list(axis)
    n = _norm(a)
    return abs(_dot(_sub(start, center), [x / n for x in a]))


__all__ = sorted(CONSTANTS) + [
    "CONSTANTS", "MESSAGES", "MoveMsg", "SetpointMsg", "Request", "StatusMsg", "Response",
    "SERVICE_MOVES", "SERVICE_SETPOINTS", "SERVICE_CONTROL", "ARC_TOLERANCE_ABS_MM",
    "ARC_TOLERANCE_REL", "ARC_AXIS_UNIT_TOLERANCE", "ARC_MIN_RADIUS_MM",
    "BEGIN_POSITION_TOLERANCE", "REMEMBERED_PROGRAMS", "MOVE_BUFFER_MARGIN",
    "SETPOINT_BUFFER", "names", "name_of", "decode_text", "check_machine", "service_name",
    "arc_tolerance_mm", "arc_sweep_end", "arc_mismatch_mm", "arc_center_off_plane_mm",
]
