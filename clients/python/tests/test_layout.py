"""docs/PROTOCOL.md against the package: every message heading (size, alignment, type
name), every row of the message tables (offset, size, type, field) and the constants
table. The Rust crate's test `crates/kerf-proto/src/doc_layout.rs` checks the same tables
against the Rust types, so the Python structures and the Rust ones are tied through the
page. No daemon needed.
"""

import ctypes
import math
import re
import struct
import unittest

import support  # noqa: F401 - puts the package on the path
from support import PROTOCOL_MD

import iceoryx2 as iox2
from kerf_client import moves as mv
from kerf_client import protocol as p

#: The ctypes of the documented scalar types.
SCALARS = {"u8": ctypes.c_uint8, "u16": ctypes.c_uint16, "u32": ctypes.c_uint32,
           "i32": ctypes.c_int32, "u64": ctypes.c_uint64, "i64": ctypes.c_int64,
           "f64": ctypes.c_double}


def cells(row):
    inner = row.strip().strip("|")
    return [c.strip().strip("`") for c in inner.split("|")]


def parse_protocol_md(text):
    """({message: (size, align, type_name, [(offset, size, type, field)])}, {const: value})."""
    lines = text.splitlines()
    messages, constants = {}, {}
    i = 0
    while i < len(lines):
        line = lines[i]
        i += 1
        m = re.match(r"^### (\w+): (\d+) bytes, align (\d+), type name `([^`]+)`\s*$", line)
        if m:
            name, size, align, type_name = m.group(1), int(m.group(2)), int(m.group(3)), m.group(4)
            while i < len(lines) and not lines[i].startswith("| offset"):
                i += 1
            i += 2
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                c = cells(lines[i])
                assert len(c) == 5, f"{name}: row {c} has not 5 cells"
                rows.append((int(c[0]), int(c[1]), c[2], c[3]))
                i += 1
            messages[name] = (size, align, type_name, rows)
        elif line.startswith("### "):
            raise AssertionError(f"a message heading not in the expected form: {line}")
        elif line.startswith("| constant"):
            i += 1
            while i < len(lines) and lines[i].startswith("|"):
                c = cells(lines[i])
                constants[c[0]] = int(c[1])
                i += 1
    return messages, constants


def expected_ctype(ty):
    """The ctypes type of a documented type: a scalar, ``T[n]`` or a message name."""
    m = re.match(r"^(\w+)\[(\d+)\]$", ty)
    if m:
        return expected_ctype(m.group(1)) * int(m.group(2))
    if ty in SCALARS:
        return SCALARS[ty]
    return p.MESSAGES[ty]


def same_ctype(a, b):
    if isinstance(a, type) and issubclass(a, ctypes.Array):
        return (isinstance(b, type) and issubclass(b, ctypes.Array)
                and a._length_ == b._length_ and same_ctype(a._type_, b._type_))
    return a is b


class ProtocolMdTables(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        with open(PROTOCOL_MD, encoding="utf-8") as f:
            cls.text = f.read()
        cls.messages, cls.constants = parse_protocol_md(cls.text)

    def test_the_page_is_protocol_version_6(self):
        self.assertIn("# Kerf shared-memory protocol, version 6", self.text)
        self.assertEqual(self.constants["PROTOCOL_VERSION"], p.PROTOCOL_VERSION)
        self.assertEqual(p.PROTOCOL_VERSION, 6)
        for name, cls in p.MESSAGES.items():
            self.assertEqual(cls.type_name(), f"kerf.{name}.v6")

    def test_every_message_is_documented_and_every_documented_one_exists(self):
        self.assertEqual(sorted(self.messages), sorted(p.MESSAGES))

    def test_headings_size_alignment_type_name(self):
        for name, (size, align, type_name, _) in self.messages.items():
            cls = p.MESSAGES[name]
            with self.subTest(message=name):
                self.assertEqual(ctypes.sizeof(cls), size)
                self.assertEqual(ctypes.alignment(cls), align)
                self.assertEqual(cls.type_name(), type_name)
                # What iceoryx2's Python bindings send as the type name.
                self.assertEqual(iox2.get_type_name(cls), type_name)

    def test_every_field_offset_size_type_and_no_padding(self):
        for name, (size, _, _, rows) in self.messages.items():
            cls = p.MESSAGES[name]
            fields = dict(cls._fields_)
            self.assertEqual([r[3] for r in rows], [f for f, _ in cls._fields_],
                             f"{name}: the fields and their order")
            next_offset = 0
            for offset, fsize, ty, field in rows:
                with self.subTest(message=name, field=field):
                    desc = getattr(cls, field)
                    self.assertEqual(desc.offset, offset, "offset")
                    self.assertEqual(desc.size, fsize, "size")
                    self.assertTrue(same_ctype(fields[field], expected_ctype(ty)),
                                    f"type {fields[field]} is not {ty}")
                    self.assertEqual(ctypes.sizeof(expected_ctype(ty)), fsize, "type size")
                    self.assertEqual(offset, next_offset, "gap or overlap before it")
                next_offset = offset + fsize
            self.assertEqual(next_offset, size, f"{name}: the table does not cover every byte")

    def test_constants_table_equals_the_package(self):
        self.assertGreater(len(self.constants), 80)
        self.assertEqual(self.constants, p.CONSTANTS)
        for k, v in self.constants.items():
            self.assertEqual(getattr(p, k), v, k)

    def test_the_fields_where_versions_5_and_6_put_them(self):
        """The fields versions 5 and 6 added or moved, at the offsets of the change
        (written out here, not read from the page): what an older client must not meet."""
        at = {
            p.MoveMsg: [("naive_cam_mm", 224, 8), ("event_p", 232, 8), ("event_q", 240, 8),
                        ("reserved", 248, 8)],
            p.Request: [("program_id", 24, 8), ("index", 32, 4), ("mode", 36, 4),
                        ("speed", 40, 8)],
            p.StatusMsg: [("dc_samples", 672, 8), ("pause_reason", 680, 4),
                          ("spindle_dir", 716, 4), ("digital_outputs", 768, 8),
                          ("analog_outputs", 784, 128), ("analog_inputs", 912, 128),
                          ("input_result_value", 1056, 8), ("pause_text", 1064, 96),
                          ("homed", 1160, 4), ("jogging", 1172, 4),
                          ("limit_released", 1188, 4), ("home_phase", 1192, 8)],
            p.Response: [("message", 24, 224), ("status", 248, 1200)],
        }
        for cls, fields in at.items():
            for field, offset, size in fields:
                with self.subTest(message=cls.__name__, field=field):
                    d = getattr(cls, field)
                    self.assertEqual((d.offset, d.size), (offset, size))
        self.assertEqual([ctypes.sizeof(c) for c in (p.MoveMsg, p.Request, p.StatusMsg,
                                                      p.Response)], [256, 48, 1200, 1448])
        # spindle_dir is signed: -1 (M4) reads back as -1, its bytes as two's complement.
        st = p.StatusMsg()
        st.spindle_dir = -1
        self.assertEqual(bytes(st)[716:720], b"\xff\xff\xff\xff")
        self.assertEqual(p.StatusMsg.from_buffer_copy(bytes(st)).spindle_dir, -1)
        # The new text field reads as text.
        st.pause_text[:5] = b"T3 ok"
        self.assertEqual(st.to_dict()["pause_text"], "T3 ok")

    def test_v5_constants(self):
        """A few of version 5's constants, from the change itself."""
        self.assertEqual((p.FLAG_EVENT_P, p.FLAG_EVENT_Q), (16, 32))
        self.assertEqual((p.EVENT_M62, p.EVENT_M66_ANALOG, p.EVENT_M68), (27, 32, 34))
        self.assertEqual(p.STATE_PAUSED, 6)
        self.assertEqual(p.name_of("STATE", 6), "paused")
        self.assertEqual((p.REQUEST_OPTIONAL_STOP, p.REQUEST_SET_ANALOG_INPUT), (10, 15))
        self.assertEqual((p.SAFETY_SPINDLE_AT_SPEED, p.SAFETY_TOOL_CHANGE), (11, 14))
        self.assertEqual(p.SAFETY_SPINDLE_DRIVE, 15)
        self.assertEqual((p.DIGITAL_IO, p.ANALOG_IO), (64, 16))

    def test_v6_constants(self):
        """Version 6's constants, from the change itself."""
        self.assertEqual((p.REQUEST_JOG, p.REQUEST_JOG_STOP, p.REQUEST_HOME), (16, 17, 18))
        self.assertEqual((p.JOG_CONTINUOUS, p.JOG_STEP, p.JOG_TO), (1, 2, 3))
        self.assertEqual((p.HOME_PHASE_IDLE, p.HOME_PHASE_FINAL), (0, 6))
        self.assertEqual((p.SAFETY_HOME_SEARCH, p.SAFETY_HARD_LIMIT), (16, 19))

    def test_service_names(self):
        self.assertEqual(p.service_name("default", "moves"), "kerf/default/moves")
        self.assertEqual(p.service_name("a-b_9", "setpoints"), "kerf/a-b_9/setpoints")
        self.assertEqual(p.service_name("x" * 64, "control"), f"kerf/{'x' * 64}/control")
        for bad in ("", "x" * 65, "a b", "a/b", "é"):
            with self.assertRaises(ValueError):
                p.service_name(bad, "moves")


class Helpers(unittest.TestCase):
    """The message helpers fill exactly the fields their kind uses."""

    def used(self, m):
        """The fields of ``m`` whose bytes are not all zero."""
        raw = bytes(m)
        out = set()
        for f, _ in m._fields_:
            d = getattr(type(m), f)
            if any(raw[d.offset:d.offset + d.size]):
                out.add(f)
        return out

    def test_line_uses_only_its_fields(self):
        m = mv.line((0, 0, 0), (1, 2, 3), 600, line=4)
        self.assertEqual(self.used(m),
                         {"version", "kind", "line", "corner", "feed_mm_min", "end_mm"})
        self.assertEqual(m.corner, p.CORNER_BLEND_DEFAULT)
        r = mv.line((1, 0, 0), (1, 2, 3), rapid=True, corner=p.CORNER_EXACT_STOP)
        self.assertEqual(r.flags, p.FLAG_RAPID)
        self.assertEqual(r.feed_mm_min, 0.0)
        t = mv.line((1, 0, 0), (2, 0, 0), 100, corner=p.CORNER_BLEND_TOLERANCE,
                    tolerance_mm=0.05, naive_cam_mm=0.01, abc_start=(0, 0, 0),
                    abc_end=(90, 0, 0))
        self.assertEqual(t.flags, p.FLAG_ABC | p.FLAG_NAIVE_CAM)
        self.assertEqual(t.tolerance_mm, 0.05)
        with self.assertRaises(ValueError):
            mv.line((0, 0, 0), (1, 0, 0))  # a feed move without feed
        with self.assertRaises(ValueError):
            mv.line((0, 0, 0), (1, 0, 0), 100, tolerance_mm=0.1)  # without its corner mode

    def test_arc_helix_and_consistency(self):
        a = mv.arc((10, 0, 0), (20, 10, 0), (10, 10, 0), 600, ccw=True, line=3)
        self.assertEqual(a.sweep_rad, math.pi / 2)
        self.assertEqual(self.used(a), {"version", "kind", "line", "corner", "feed_mm_min",
                                        "start_mm", "end_mm", "center_mm", "axis",
                                        "sweep_rad"})
        h = mv.arc((30, 20, 0), (30, 20, -3), (30, 15, 0), 600, ccw=True)
        self.assertEqual(h.sweep_rad, 2 * math.pi)
        self.assertEqual(mv.arc_sweep((20, 10, 0), (30, 20, 0), (30, 10, 0), ccw=False),
                         -math.pi / 2)
        with self.assertRaises(ValueError):  # the end is not where the sweep leads
            mv.arc((10, 0, 0), (20, 10, 0), (10, 10, 0), 600, sweep_rad=math.pi / 2 + 1e-6)
        # ... unless asked for (tests of the daemon's refusals).
        bad = mv.arc((10, 0, 0), (20, 10, 0), (10, 10, 0), 600,
                     sweep_rad=math.pi / 2 + 1e-6, check=False)
        self.assertGreater(p.arc_mismatch_mm((10, 0, 0), (20, 10, 0), (10, 10, 0),
                                             (0, 0, 1), bad.sweep_rad), 1e-6)

    def test_event_value_flag(self):
        e = mv.event(p.EVENT_M5)
        self.assertEqual(self.used(e), {"version", "kind", "event_code"})
        s = mv.event(p.EVENT_S, 12000, line=7)
        self.assertEqual(s.flags, p.FLAG_EVENT_VALUE)
        self.assertEqual(s.event_value, 12000.0)
        with self.assertRaises(ValueError):
            mv.event(p.EVENT_T)
        with self.assertRaises(ValueError):
            mv.event(p.EVENT_G4, -1)

    def test_events_with_p_and_q_words(self):
        """Each word given sets its field and its flag, as Rust's MoveMsg::from_event;
        one not given leaves both zero. Flags: value 4, P 16, Q 32."""
        # M66 P2 L3 Q1.5: wait on digital input 2, mode 3, at most 1.5 s.
        m66 = mv.event(p.EVENT_M66, 2, p=3, q=1.5, line=7)
        self.assertEqual(m66.flags, 4 | 16 | 32)
        self.assertEqual((m66.event_code, m66.event_value, m66.event_p, m66.event_q,
                          m66.line), (31, 2.0, 3.0, 1.5, 7))
        self.assertEqual(self.used(m66), {"version", "kind", "line", "flags", "event_code",
                                          "event_value", "event_p", "event_q"})
        raw = bytes(m66)
        self.assertEqual(struct.unpack_from("=dd", raw, 232), (3.0, 1.5))
        self.assertEqual(raw[248:256], bytes(8))
        # M66 E0 L1 (analog input 0, no timeout): no Q.
        a = mv.event(p.EVENT_M66_ANALOG, 0, p=1)
        self.assertEqual((a.flags, a.event_code, a.event_q), (4 | 16, 32, 0.0))
        # A value 0 is a value: the flag says it is there.
        self.assertEqual(a.event_value, 0.0)
        # M67 E1 Q4.5 and M68 E0 Q-2: output number and value.
        m67 = mv.event(p.EVENT_M67, 1, q=4.5)
        self.assertEqual((m67.flags, m67.event_value, m67.event_q), (4 | 32, 1.0, 4.5))
        m68 = mv.event(p.EVENT_M68, 0, q=-2)
        self.assertEqual((m68.flags, m68.event_code, m68.event_q), (4 | 32, 34, -2.0))
        # M19 R90 Q2 P1, and M19 alone.
        m19 = mv.event(p.EVENT_M19, 90, p=1, q=2)
        self.assertEqual((m19.flags, m19.event_value, m19.event_p, m19.event_q),
                         (4 | 16 | 32, 90.0, 1.0, 2.0))
        self.assertEqual(mv.event(p.EVENT_M19).flags, 0)
        # M101 P2 Q3: a user M code's P is its value; its Q goes to event_q.
        u = mv.event(p.EVENT_USER_M100 + 1, 2, q=3)
        self.assertEqual((u.event_code, u.flags, u.event_value, u.event_p, u.event_q),
                         (101, 4 | 32, 2.0, 0.0, 3.0))
        self.assertEqual(mv.event(p.EVENT_USER_M199, q=0.5).flags, 32)
        # M62 P5 .. M65 P5: the output number is required.
        for code in (p.EVENT_M62, p.EVENT_M63, p.EVENT_M64, p.EVENT_M65):
            self.assertEqual(mv.event(code, 5).flags, 4)

    def test_events_the_daemon_would_refuse(self):
        """The rules of docs/PROTOCOL.md (MoveMsg, EVENT) for one event, with the words of
        the daemon's reasons; check=False builds the event anyway."""
        nan = float("nan")
        cases = [
            ((p.EVENT_M67, 1), {}, "event M67 needs a Q word"),
            ((p.EVENT_M68, 1), {}, "event M68 needs a Q word"),
            ((p.EVENT_M3,), {"q": 1}, "event M3 takes no Q word"),
            ((p.EVENT_M62, 1), {"q": 1}, "event M62 takes no Q word"),
            ((p.EVENT_M3,), {"p": 1}, "event M3 takes no P or L word"),
            ((p.EVENT_M67, 1), {"p": 1, "q": 1}, "event M67 takes no P or L word"),
            ((p.EVENT_USER_M100, 1), {"p": 2}, "event M100 takes no P or L word"),
            ((p.EVENT_M3, 1), {}, "event M3 takes no value"),
            ((p.EVENT_M66,), {"p": 1}, "event M66 needs a value"),
            ((p.EVENT_M66_ANALOG,), {}, "event M66 needs a value"),
            ((p.EVENT_M63,), {}, "event M63 needs a value"),
            ((p.EVENT_M50,), {}, "event M50 needs a value"),
            ((p.EVENT_S,), {}, "event S needs a value"),
            ((35,), {}, "unknown event code 35"),
            ((99,), {}, "unknown event code 99"),
            ((200,), {}, "unknown event code 200"),
            ((p.EVENT_M66, 1), {"q": nan}, "not a finite number"),
            ((p.EVENT_G4, -0.5), {}, "a dwell is >= 0 s"),
        ]
        for args, kwargs, words in cases:
            with self.subTest(args=args, kwargs=kwargs):
                with self.assertRaises(ValueError) as cm:
                    mv.event(*args, **kwargs)
                self.assertIn(words, str(cm.exception))
                m = mv.event(*args, **kwargs, check=False)
                self.assertEqual(m.event_code, args[0])
        bad = mv.event(p.EVENT_M3, p=1, q=nan, check=False)
        self.assertEqual(bad.flags, 16 | 32)
        self.assertTrue(math.isnan(bad.event_q))

    def test_begin_and_end(self):
        b = mv.begin(7, (1, 2, 3), 5)
        self.assertEqual(self.used(b), {"version", "kind", "program_id", "start_mm", "count"})
        b6 = mv.begin(7, (1, 2, 3, 4, 5, 6))
        self.assertEqual(tuple(b6.abc_start_deg), (4.0, 5.0, 6.0))
        e = mv.end(7, 6, 5)
        self.assertEqual(self.used(e), {"version", "kind", "program_id", "seq", "count"})


class EthercatStatus(unittest.TestCase):
    """The bus section of the status as ``Status.ethercat`` shows it."""

    def test_a_bus_with_a_subdevice_out_of_op_and_distributed_clocks(self):
        from kerf_client.client import Status

        raw = p.StatusMsg()
        raw.bus_subdevices = 3
        raw.bus_recovering = 1
        raw.bus_states[0], raw.bus_states[1], raw.bus_states[2] = 8, 4, 0
        raw.bus_states[3] = 8  # beyond the bus: not shown
        raw.bus_al_codes[1] = 0x001B
        raw.bus_cycles_complete, raw.bus_cycles_lost = 1000, 3
        raw.bus_cycles_short, raw.bus_cycles_not_op = 2, 17
        raw.bus_longest_gap_cycles = 5
        raw.dc_used = 1
        raw.dc_offset_ns = -1240
        raw.dc_offset_abs_p50_ns, raw.dc_offset_abs_p99_ns = 300, 1100
        raw.dc_offset_abs_p999_ns, raw.dc_offset_abs_max_ns = 2000, 3400
        raw.dc_samples = 990
        # Through the bytes, as the shared memory carries it.
        s = Status(p.StatusMsg.from_buffer_copy(bytes(raw)))
        self.assertEqual(s.ethercat, {
            "subdevices": [
                {"position": 0, "state": "OP", "al_status_code": 0},
                {"position": 1, "state": "SAFE-OP", "al_status_code": 27},
                {"position": 2, "state": "unknown", "al_status_code": 0},
            ],
            "recovering": True,
            "cycles": {"complete": 1000, "lost": 3, "short": 2, "not_op": 17,
                       "longest_gap": 5},
            "dc": {"offset_ns": -1240,
                   "offset_abs_ns": {"p50": 300, "p99": 1100, "p999": 2000, "max": 3400},
                   "samples": 990},
        })
        self.assertEqual(s.bus_al_codes[:2], (0, 0x001B))
        self.assertIs(s.dc_used, True)

    def test_no_bus_and_no_distributed_clocks(self):
        from kerf_client.client import Status

        self.assertIsNone(Status(p.StatusMsg()).ethercat)
        raw = p.StatusMsg()
        raw.bus_subdevices = 1
        raw.bus_states[0] = 2
        self.assertEqual(Status(raw).ethercat["subdevices"],
                         [{"position": 0, "state": "PRE-OP", "al_status_code": 0}])
        self.assertIsNone(Status(raw).ethercat["dc"])
        # A count beyond the arrays (a broken writer) is cut to them.
        raw.bus_subdevices = 0xFFFFFFFF
        self.assertEqual(len(Status(raw).ethercat["subdevices"]), p.BUS_MAX_SUBDEVICES)


class _FakeSample:
    def __init__(self, msg):
        self.msg = msg
        self.payload_ptr = ctypes.addressof(msg)

    def delete(self):
        pass


class _FakeSubscriber:
    def __init__(self, msgs):
        self.msgs = list(msgs)

    def receive(self):
        return _FakeSample(self.msgs.pop(0)) if self.msgs else None


class GapDetection(unittest.TestCase):
    """The setpoint stream's bookkeeping: a gap in ``seq`` is lost samples, an increase
    of ``missed_periods`` skipped periods, another version is ignored."""

    def test_lost_samples_and_skipped_periods(self):
        from kerf_client.client import SetpointStream

        def sp(seq, missed, version=p.PROTOCOL_VERSION):
            m = p.SetpointMsg()
            m.version, m.seq, m.missed_periods = version, seq, missed
            return m

        stream = SetpointStream(_FakeSubscriber([
            sp(10, 0), sp(11, 0), sp(14, 0), sp(15, 2), sp(16, 2, version=2), sp(17, 5),
        ]), None)
        got = stream.drain()
        self.assertEqual([g.seq for g in got], [10, 11, 14, 15, 17])
        self.assertEqual([g.lost_before for g in got], [0, 0, 2, 0, 1])
        self.assertEqual([g.skipped_before for g in got], [0, 0, 0, 2, 3])
        self.assertEqual((stream.lost, stream.skipped_periods, stream.ignored), (3, 5, 1))


if __name__ == "__main__":
    unittest.main()
