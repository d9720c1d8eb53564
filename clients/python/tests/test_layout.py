"""docs/PROTOCOL.md against the package: every message heading (size, alignment, type
name), every row of the message tables (offset, size, type, field) and the constants
table. The Rust crate's test `crates/kerf-proto/src/doc_layout.rs` checks the same tables
against the Rust types, so the Python structures and the Rust ones are tied through the
page. No daemon needed.
"""

import ctypes
import math
import re
import unittest

import support  # noqa: F401 - puts the package on the path
from support import PROTOCOL_MD

import iceoryx2 as iox2
from kerf_client import moves as mv
from kerf_client import protocol as p

#: The ctypes of the documented scalar types.
SCALARS = {"u8": ctypes.c_uint8, "u16": ctypes.c_uint16, "u32": ctypes.c_uint32,
           "u64": ctypes.c_uint64, "i64": ctypes.c_int64, "f64": ctypes.c_double}


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

    def test_the_page_is_protocol_version_4(self):
        self.assertIn("# Kerf shared-memory protocol, version 4", self.text)
        self.assertEqual(self.constants["PROTOCOL_VERSION"], p.PROTOCOL_VERSION)
        self.assertEqual(p.PROTOCOL_VERSION, 4)

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
