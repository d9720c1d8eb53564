"""Building MoveMsg items: BEGIN, LINE, ARC (and helices), EVENT, END.

Every helper returns a fresh :class:`~kerf_client.protocol.MoveMsg` with ``version`` set and
every field the kind does not use left zero (docs/PROTOCOL.md: "Reserved fields and fields
a message kind does not use must be zero"). Items (lines, arcs, events) are built with
``program_id`` and ``seq`` 0: :meth:`kerf_client.Client.run_program` stamps its program's
id and the item's sequence number into a copy of each, and numbers the items' ``line``
1, 2, ... where it was left 0.

Lengths are absolute machine millimetres, feeds mm/min, angles of arcs radians, rotary
axes degrees.
"""

import math

from . import protocol as proto


def _vec3(v, what):
    t = tuple(float(x) for x in v)
    if len(t) != 3:
        raise ValueError(f"{what}: 3 numbers expected, got {len(t)}")
    return t


def _finite(what, *values):
    for v in values:
        if not math.isfinite(v):
            raise ValueError(f"{what}: not a finite number")


def _set3(arr, values):
    for i in range(3):
        arr[i] = values[i]


def begin(program_id, start_mm_deg, count=0):
    """BEGIN: the program ``program_id`` starts from ``start_mm_deg`` (X, Y, Z mm, then
    optionally A, B, C degrees) and announces ``count`` items (0 = unknown)."""
    start = [float(x) for x in start_mm_deg]
    if len(start) not in (3, 6):
        raise ValueError("start_mm_deg: X, Y, Z or X, Y, Z, A, B, C")
    start += [0.0] * (6 - len(start))
    m = proto.MoveMsg()
    m.version = proto.PROTOCOL_VERSION
    m.kind = proto.KIND_BEGIN
    m.program_id = program_id
    m.seq = 0
    _set3(m.start_mm, start[:3])
    _set3(m.abc_start_deg, start[3:])
    m.count = count
    return m


def end(program_id, seq, count):
    """END of program ``program_id``: ``seq`` = items + 1, ``count`` = items sent."""
    m = proto.MoveMsg()
    m.version = proto.PROTOCOL_VERSION
    m.kind = proto.KIND_END
    m.program_id = program_id
    m.seq = seq
    m.count = count
    return m


def _corner(m, corner, tolerance_mm, naive_cam_mm):
    if corner not in (proto.CORNER_EXACT_STOP, proto.CORNER_BLEND_DEFAULT,
                      proto.CORNER_BLEND_TOLERANCE):
        raise ValueError(f"corner: unknown corner mode {corner}")
    m.corner = corner
    if corner == proto.CORNER_BLEND_TOLERANCE:
        if tolerance_mm is None or not tolerance_mm >= 0.0:
            raise ValueError("CORNER_BLEND_TOLERANCE needs tolerance_mm >= 0")
        _finite("tolerance_mm", tolerance_mm)
        m.tolerance_mm = tolerance_mm
    elif tolerance_mm is not None:
        raise ValueError("tolerance_mm is used only with CORNER_BLEND_TOLERANCE")
    if naive_cam_mm is not None:
        if corner == proto.CORNER_EXACT_STOP:
            raise ValueError("naive_cam_mm is not used with CORNER_EXACT_STOP")
        if not naive_cam_mm >= 0.0:
            raise ValueError("naive_cam_mm must be >= 0")
        _finite("naive_cam_mm", naive_cam_mm)
        m.flags |= proto.FLAG_NAIVE_CAM
        m.naive_cam_mm = naive_cam_mm


def _motion(kind, start, end_, feed_mm_min, rapid, corner, tolerance_mm, naive_cam_mm,
            abc_start, abc_end, line):
    m = proto.MoveMsg()
    m.version = proto.PROTOCOL_VERSION
    m.kind = kind
    m.line = line
    start = _vec3(start, "start")
    end_ = _vec3(end_, "end")
    _finite("start/end", *start, *end_)
    _set3(m.start_mm, start)
    _set3(m.end_mm, end_)
    if rapid:
        if feed_mm_min not in (None, 0, 0.0):
            raise ValueError("a rapid has no feed")
        m.flags |= proto.FLAG_RAPID
    else:
        if feed_mm_min is None or not feed_mm_min > 0.0:
            raise ValueError("a feed move needs feed_mm_min > 0")
        _finite("feed_mm_min", feed_mm_min)
        m.feed_mm_min = float(feed_mm_min)
    _corner(m, corner, tolerance_mm, naive_cam_mm)
    if (abc_start is None) != (abc_end is None):
        raise ValueError("abc_start and abc_end go together")
    if abc_start is not None:
        a0, a1 = _vec3(abc_start, "abc_start"), _vec3(abc_end, "abc_end")
        _finite("abc", *a0, *a1)
        m.flags |= proto.FLAG_ABC
        _set3(m.abc_start_deg, a0)
        _set3(m.abc_end_deg, a1)
    return m


def line(start, end, feed_mm_min=None, *, rapid=False, corner=proto.CORNER_BLEND_DEFAULT,
         tolerance_mm=None, naive_cam_mm=None, abc_start=None, abc_end=None, line=0):
    """A straight LINE from ``start`` to ``end`` (X, Y, Z mm): a feed move at
    ``feed_mm_min`` mm/min, or a rapid (``rapid=True``, no feed).

    ``corner``: ``CORNER_EXACT_STOP`` (G61/G9), ``CORNER_BLEND_DEFAULT`` (G64) or
    ``CORNER_BLEND_TOLERANCE`` with ``tolerance_mm`` (G64 P). ``naive_cam_mm`` (G64 Q) sets
    ``FLAG_NAIVE_CAM``; ``abc_start``/``abc_end`` (degrees) set ``FLAG_ABC``. ``line`` is the
    1-based source line (0: numbered by ``run_program``)."""
    return _motion(proto.KIND_LINE, start, end, feed_mm_min, rapid, corner, tolerance_mm,
                   naive_cam_mm, abc_start, abc_end, line)


def arc_sweep(start, end, center, axis=(0.0, 0.0, 1.0), *, ccw=True, turns=0):
    """The signed sweep (rad) of an arc about ``axis`` from ``start`` to ``end`` around
    ``center``: counter-clockwise about the axis (G3) when ``ccw``, clockwise (G2)
    otherwise, plus ``turns`` extra whole turns. A full circle (end on the start's
    angle) sweeps one whole turn."""
    a = _vec3(axis, "axis")
    n = math.sqrt(sum(x * x for x in a))
    a = [x / n for x in a]
    u = [start[i] - center[i] for i in range(3)]
    v = [end[i] - center[i] for i in range(3)]
    du, dv = sum(u[i] * a[i] for i in range(3)), sum(v[i] * a[i] for i in range(3))
    u = [u[i] - du * a[i] for i in range(3)]
    v = [v[i] - dv * a[i] for i in range(3)]
    e1 = u
    e2 = [a[1] * u[2] - a[2] * u[1], a[2] * u[0] - a[0] * u[2], a[0] * u[1] - a[1] * u[0]]
    x = sum(v[i] * e1[i] for i in range(3))
    y = sum(v[i] * e2[i] for i in range(3))
    theta = math.atan2(y, x)  # in (-pi, pi]
    if ccw:
        if theta <= 0.0:
            theta += 2.0 * math.pi
        return theta + 2.0 * math.pi * turns
    if theta >= 0.0:
        theta -= 2.0 * math.pi
    return theta - 2.0 * math.pi * turns


def arc(start, end, center, feed_mm_min=None, *, sweep_rad=None, ccw=None, turns=0,
        axis=(0.0, 0.0, 1.0), rapid=False, corner=proto.CORNER_BLEND_DEFAULT,
        tolerance_mm=None, naive_cam_mm=None, abc_start=None, abc_end=None, line=0,
        check=True):
    """A circular ARC or helix from ``start`` to ``end`` around ``center`` (in the plane
    through ``start`` normal to ``axis``; G17 +Z, G18 +Y, G19 +X).

    Give either ``sweep_rad`` (signed about ``axis``, right-hand rule, G3 > 0, whole turns
    included) or ``ccw`` (True for G3, False for G2) with optional ``turns``; a helix has
    ``end`` displaced along ``axis``. With ``check`` (the default) the arc must agree in
    millimetres as the daemon checks it (end where the sweep leads, centre in the start's
    plane, within the arc tolerance); ``check=False`` builds any arc (tests of refusals).
    Other arguments as :func:`line`."""
    if (sweep_rad is None) == (ccw is None):
        raise ValueError("give either sweep_rad or ccw")
    center = _vec3(center, "center")
    axis = _vec3(axis, "axis")
    if sweep_rad is None:
        sweep_rad = arc_sweep(start, end, center, axis, ccw=ccw, turns=turns)
    m = _motion(proto.KIND_ARC, start, end, feed_mm_min, rapid, corner, tolerance_mm,
                naive_cam_mm, abc_start, abc_end, line)
    _set3(m.center_mm, center)
    _set3(m.axis, axis)
    m.sweep_rad = float(sweep_rad)
    if check:
        _finite("center/axis/sweep", *center, *axis, m.sweep_rad)
        if abs(math.sqrt(sum(x * x for x in axis)) - 1.0) > proto.ARC_AXIS_UNIT_TOLERANCE:
            raise ValueError("axis: not a unit vector")
        if m.sweep_rad == 0.0:
            raise ValueError("sweep_rad: 0")
        s, e = tuple(m.start_mm), tuple(m.end_mm)
        tol = proto.arc_tolerance_mm(s, e, center, axis, m.sweep_rad)
        off = proto.arc_center_off_plane_mm(s, center, axis)
        if off > tol:
            raise ValueError(f"the centre lies {off:g} mm off the start's plane")
        miss = proto.arc_mismatch_mm(s, e, center, axis, m.sweep_rad)
        if miss > tol:
            raise ValueError(
                f"the end is {miss:g} mm from where the sweep leads (tolerance {tol:g} mm)"
            )
    return m


#: Events that must have a value: S rpm, T tool number, G4 seconds, M50-M53 (1 enabled,
#: 0 disabled), M62-M68 the output's or input's number.
EVENTS_WITH_VALUE = (
    proto.EVENT_S, proto.EVENT_T, proto.EVENT_G4,
    proto.EVENT_M50, proto.EVENT_M51, proto.EVENT_M52, proto.EVENT_M53,
    proto.EVENT_M62, proto.EVENT_M63, proto.EVENT_M64, proto.EVENT_M65,
    proto.EVENT_M66, proto.EVENT_M66_ANALOG, proto.EVENT_M67, proto.EVENT_M68,
)
#: Events that may have a value (M19 the angle, degrees); the user M codes M100-M199
#: (their P word) may have one too.
EVENTS_OPTIONAL_VALUE = (proto.EVENT_M19,)
#: Events that may have a P word in ``event_p``: M19 (its P, the direction mode) and M66
#: (its L word, the wait mode).
EVENTS_WITH_P = (proto.EVENT_M19, proto.EVENT_M66, proto.EVENT_M66_ANALOG)
#: Events that must have a Q word in ``event_q``: M67 and M68 (the analog value).
EVENTS_WITH_Q = (proto.EVENT_M67, proto.EVENT_M68)
#: Events that may have a Q word: M19 and M66 (the timeout, s); the user M codes may
#: have one too.
EVENTS_OPTIONAL_Q = (proto.EVENT_M19, proto.EVENT_M66, proto.EVENT_M66_ANALOG)

#: Every known event code.
_EVENT_CODES = frozenset(
    v for k, v in proto.CONSTANTS.items() if k.startswith("EVENT_")
) | frozenset(range(proto.EVENT_USER_M100, proto.EVENT_USER_M199 + 1))


def is_user_m(code):
    """Whether ``code`` is a user M code, M100 (``EVENT_USER_M100``) to M199."""
    return proto.EVENT_USER_M100 <= code <= proto.EVENT_USER_M199


def event_word(code):
    """The event's word as a program writes it: ``"M3"``, ``"S"``, ``"M66"`` (for
    ``EVENT_M66`` and ``EVENT_M66_ANALOG``), ``"M100"``; ``"event <code>"`` for a code that
    is none of the ``EVENT_*``."""
    if is_user_m(code):
        return f"M{100 + code - proto.EVENT_USER_M100}"
    name = proto.names("EVENT").get(code)
    if name is None:
        return f"event {code}"
    return "M66" if name == "M66_ANALOG" else name


def event(code, value=None, *, p=None, q=None, line=0, check=True):
    """An EVENT ``code`` (``EVENT_*``) as the daemon takes it (Rust's
    ``MoveMsg::from_event``): each of ``value``, ``p`` and ``q`` given sets its field
    (``event_value``, ``event_p``, ``event_q``) and its flag (``FLAG_EVENT_VALUE``,
    ``FLAG_EVENT_P``, ``FLAG_EVENT_Q``); one left None leaves both zero.

    - ``value``: S rpm, T tool number, G4 seconds (>= 0), M50-M53 1 or 0, M62-M68 the
      output's or input's number (P or E word) are required; M19's angle (R, degrees) and a
      user M code's P word are optional; every other event takes none.
    - ``p``: M19's P word (the direction mode) or M66's L word (the wait mode), optional;
      no other event takes one.
    - ``q``: M67's and M68's value (required); M19's and M66's timeout in s, and a user
      M code's Q word (optional); no other event takes one.

    So ``M66 P2 L3 Q1.5`` is ``event(EVENT_M66, 2, p=3, q=1.5)``, ``M66 E0 L1`` is
    ``event(EVENT_M66_ANALOG, 0, p=1)``, ``M67 E1 Q4.5`` is ``event(EVENT_M67, 1,
    q=4.5)``, ``M101 P2 Q3`` is ``event(EVENT_USER_M100 + 1, 2, q=3)``.

    With ``check`` (the default) the event must pass the daemon's checks of one message
    (docs/PROTOCOL.md, MoveMsg, EVENT): a known code, the words it needs and no word it
    does not take, finite numbers, no negative dwell; ``ValueError`` says what is wrong.
    ``check=False`` builds any event (tests of the daemon's refusals)."""
    m = proto.MoveMsg()
    m.version = proto.PROTOCOL_VERSION
    m.kind = proto.KIND_EVENT
    m.line = line
    m.event_code = code
    word = event_word(code)
    if check and code not in _EVENT_CODES:
        raise ValueError(f"unknown event code {code}")
    for what, given, flag, field in (
        ("value", value, proto.FLAG_EVENT_VALUE, "event_value"),
        ("P word", p, proto.FLAG_EVENT_P, "event_p"),
        ("Q word", q, proto.FLAG_EVENT_Q, "event_q"),
    ):
        if given is None:
            continue
        given = float(given)
        if check:
            _finite(f"event {word} {what}", given)
        m.flags |= flag
        setattr(m, field, given)
    if not check:
        return m
    user = is_user_m(code)
    if value is None and code in EVENTS_WITH_VALUE:
        raise ValueError(f"event {word} needs a value")
    if value is not None and not (
        code in EVENTS_WITH_VALUE or code in EVENTS_OPTIONAL_VALUE or user
    ):
        raise ValueError(f"event {word} takes no value")
    if p is not None and code not in EVENTS_WITH_P:
        raise ValueError(f"event {word} takes no P or L word")
    if q is None and code in EVENTS_WITH_Q:
        raise ValueError(f"event {word} needs a Q word")
    if q is not None and not (code in EVENTS_WITH_Q or code in EVENTS_OPTIONAL_Q or user):
        raise ValueError(f"event {word} takes no Q word")
    if code == proto.EVENT_G4 and m.event_value < 0.0:
        raise ValueError("a dwell is >= 0 s")
    return m


def item_end_mm(m):
    """Where an item leaves the machine (X, Y, Z): a move's end; None for an event."""
    if m.kind in (proto.KIND_LINE, proto.KIND_ARC):
        return tuple(m.end_mm)
    return None
