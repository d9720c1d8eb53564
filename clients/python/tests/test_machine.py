"""The machine's side of protocol version 5 in the client, without a daemon: the status's
machine section as ``Status.machine`` shows it (the shapes of ``kerf status --json``), the
pause in words, and the requests of the switches, the spindle override and the simulated
inputs as they go onto the control service.
"""

import ctypes
import struct
import unittest

import support  # noqa: F401 - puts the package on the path

from kerf_client import protocol as p
from kerf_client.client import Client, Status, pause_name


def through_bytes(raw):
    """The status as the shared memory carries it."""
    return Status(p.StatusMsg.from_buffer_copy(bytes(raw)))


class MachineSection(unittest.TestCase):
    def test_an_idle_machine_without_spindle(self):
        s = through_bytes(p.StatusMsg())
        self.assertFalse(s.paused)
        self.assertEqual(s.pause_name, "none")
        self.assertIsNone(s.pause_message)
        self.assertEqual(s.machine, {
            "pause": None,
            "switches": {"optional_stop": False, "block_delete": False,
                         "single_block": False},
            "tool": {"in_spindle": 0, "length_mm": 0.0, "changer": "none"},
            "spindle": None,
            "feed_override_enabled": False,
            "coolant": {"mist": False, "flood": False},
            "io": {"digital_outputs": 0, "digital_inputs": 0,
                   "analog_outputs": [0.0] * 16, "analog_inputs": [0.0] * 16},
            "input_result": None,
        })

    def test_a_machine_at_a_manual_tool_change(self):
        raw = p.StatusMsg()
        raw.state = 6  # paused
        raw.pause_reason, raw.pause_line, raw.pause_value = 5, 30, 3
        text = b"insert tool T3 (length 45.200 mm)"
        raw.pause_text[:len(text)] = text
        raw.switches = 1 | 4            # optional stop and single block, not block delete
        raw.tool_in_spindle, raw.tool_changer, raw.tool_length_mm = 7, 1, 38.5
        raw.spindle_kind, raw.spindle_dir = 1, -1
        raw.spindle_programmed_rpm = 12000.0
        raw.spindle_commanded_rpm = -9600.0   # M4 at 80 %
        raw.spindle_actual_rpm = -9598.5
        raw.spindle_override_pct = 80.0
        raw.spindle_at_speed = 1
        raw.overrides_enabled = 2             # spindle override on, feed override off
        raw.coolant = 2                       # flood
        raw.digital_outputs = (1 << 0) | (1 << 63)
        raw.digital_inputs = 1 << 5
        raw.analog_outputs[2] = 4.5
        raw.analog_inputs[15] = -2.25
        raw.input_result_seq, raw.input_result_program = 4, 0xDEADBEEF
        raw.input_result_line, raw.input_result_value = 17, -1.0  # it timed out
        s = through_bytes(raw)
        self.assertEqual(s.state_name, "paused")
        self.assertTrue(s.paused)
        self.assertEqual(s.pause_text, "insert tool T3 (length 45.200 mm)")
        self.assertIs(s.spindle_at_speed, True)
        self.assertEqual(s.spindle_dir, -1)
        analog_out = [0.0] * 16
        analog_out[2] = 4.5
        analog_in = [0.0] * 16
        analog_in[15] = -2.25
        self.assertEqual(s.machine, {
            "pause": {
                "reason": "tool_change",
                "line": 30,
                "value": 3,
                "waits_for_operator": True,
                "text": "paused at line 30 (M6): insert tool T3 (length 45.200 mm), "
                        "then `kerf resume`",
            },
            "switches": {"optional_stop": True, "block_delete": False,
                         "single_block": True},
            "tool": {"in_spindle": 7, "length_mm": 38.5, "changer": "manual"},
            "spindle": {
                "kind": "drive",
                "dir": -1,
                "programmed_rpm": 12000.0,
                "commanded_rpm": -9600.0,
                "actual_rpm": -9598.5,
                "at_speed": True,
                "override_pct": 80.0,
                "override_enabled": True,
            },
            "feed_override_enabled": False,
            "coolant": {"mist": False, "flood": True},
            "io": {"digital_outputs": 9223372036854775809, "digital_inputs": 32,
                   "analog_outputs": analog_out, "analog_inputs": analog_in},
            "input_result": {"seq": 4, "program_id": 3735928559, "line": 17,
                             "value": -1.0},
        })

    def test_spindle_on_outputs_and_numbers_that_are_not_finite(self):
        raw = p.StatusMsg()
        raw.spindle_kind, raw.spindle_dir = 2, 1
        raw.spindle_actual_rpm = float("nan")
        raw.overrides_enabled = 1
        raw.coolant = 3
        raw.tool_changer = 2
        raw.analog_inputs[0] = float("inf")
        m = through_bytes(raw).machine
        self.assertEqual(m["spindle"]["kind"], "outputs")
        self.assertEqual(m["spindle"]["dir"], 1)
        self.assertIsNone(m["spindle"]["actual_rpm"])  # JSON's null
        self.assertFalse(m["spindle"]["override_enabled"])
        self.assertTrue(m["feed_override_enabled"])
        self.assertEqual(m["coolant"], {"mist": True, "flood": True})
        self.assertEqual(m["tool"]["changer"], "automatic")
        self.assertIsNone(m["io"]["analog_inputs"][0])
        # An unknown changer or pause value reads as none, never fails.
        raw.tool_changer, raw.pause_reason = 9, 99
        s = through_bytes(raw)
        self.assertEqual(s.machine["tool"]["changer"], "none")
        self.assertEqual(s.machine["pause"]["reason"], "none")
        self.assertEqual(s.machine["pause"]["text"], "")
        self.assertFalse(s.machine["pause"]["waits_for_operator"])

    def test_every_pause_by_name_and_in_words(self):
        # (reason, line, value, pause_text) -> name, waits for the operator, words.
        cases = [
            (1, 12, 0, "", "program_stop", True,
             "paused at line 12 (M0, program stop): `kerf resume` to continue"),
            (2, 13, 0, "", "optional_stop", True,
             "paused at line 13 (M1, optional stop): `kerf resume` to continue"),
            (3, 14, 0, "", "pallet_change", True,
             "paused at line 14 (M60, pallet change): `kerf resume` to continue"),
            (4, 15, 0, "", "single_block", True,
             "paused after line 15 (single block): `kerf resume` to continue"),
            (5, 16, 4, "", "tool_change", True,
             "paused at line 16 (M6): insert tool T4, then `kerf resume`"),
            (6, 17, 9, "", "tool_changing", False,
             "waiting at line 17 for the tool changer to load tool T9"),
            (7, 18, 2, "", "wait_input", False,
             "waiting at line 18 for input 2 (M66)"),
            (8, 19, 0, "", "spindle_at_speed", False,
             "waiting at line 19 for the spindle to reach its speed"),
            (9, 20, 0, "", "spindle_orient", False,
             "waiting at line 20 for the spindle's orientation (M19)"),
        ]
        for reason, line, value, text, name, operator, words in cases:
            with self.subTest(name=name):
                raw = p.StatusMsg()
                raw.pause_reason, raw.pause_line, raw.pause_value = reason, line, value
                s = through_bytes(raw)
                self.assertEqual(pause_name(reason), name)
                self.assertEqual(s.pause_name, name)
                self.assertIs(s.pause_waits_for_operator, operator)
                self.assertEqual(s.pause_message, words)
                self.assertEqual(s.machine["pause"], {
                    "reason": name, "line": line, "value": value,
                    "waits_for_operator": operator, "text": words})
        self.assertEqual(pause_name(0), "none")


class _Sample:
    def __init__(self, msg):
        self.msg = msg
        self.payload_ptr = ctypes.addressof(msg)

    def delete(self):
        pass


class _Pending:
    def __init__(self, response):
        self.response = response

    def receive(self):
        r, self.response = self.response, None
        return None if r is None else _Sample(r)

    def delete(self):
        pass


class _FakeControl:
    """Takes each request's bytes and answers it accepted."""

    def __init__(self):
        self.sent = []

    def send_copy(self, req):
        raw = bytes(req)
        self.sent.append(raw)
        resp = p.Response()
        resp.version = p.PROTOCOL_VERSION
        resp.accepted = 1
        resp.request_id = req.id
        return _Pending(resp)


def fake_client():
    c = Client.__new__(Client)
    c.machine, c.timeout_s = "default", 1.0
    c._client, c._next_id, c._moves, c._publisher = _FakeControl(), 1, None, None
    return c


class Requests(unittest.TestCase):
    """The requests of version 6 as bytes: version u32 at 0, kind u32 at 4, id u64 at 8,
    value f64 at 16, program_id u64 at 24, index u32 at 32, mode u32 at 36, speed f64 at
    40."""

    def decode(self, raw):
        self.assertEqual(len(raw), 48)
        return struct.unpack("=IIQdQIId", raw)

    def test_each_new_request(self):
        c = fake_client()
        calls = [
            (lambda: c.optional_stop(True), 10, 1.0, 0),
            (lambda: c.optional_stop(False), 10, 0.0, 0),
            (lambda: c.block_delete(True), 11, 1.0, 0),
            (lambda: c.single_block(True), 12, 1.0, 0),
            (lambda: c.single_block(False), 12, 0.0, 0),
            (lambda: c.spindle_override(80), 13, 80.0, 0),
            (lambda: c.set_input(63, True), 14, 1.0, 63),
            (lambda: c.set_input(0, False), 14, 0.0, 0),
            (lambda: c.set_analog_input(15, -2.5), 15, -2.5, 15),
            (lambda: c.resume(), 3, 0.0, 0),
        ]
        for n, (call, kind, value, index) in enumerate(calls, start=1):
            with self.subTest(kind=kind, value=value, index=index):
                r = call()
                self.assertTrue(r.accepted)
                self.assertEqual(r.request_id, n)
                self.assertEqual(self.decode(c._client.sent[-1]),
                                 (6, kind, n, value, 0, index, 0, 0.0))

    def test_manual_requests(self):
        c = fake_client()
        calls = [
            (lambda: c.jog(0, +1), 16, 1.0, 0, 1, 0.0),
            (lambda: c.jog(5, -1, speed=12.5), 16, -1.0, 5, 1, 12.5),
            (lambda: c.jog_step(2, -0.1, speed=1.0), 16, -0.1, 2, 2, 1.0),
            (lambda: c.jog_to(1, 250.0), 16, 250.0, 1, 3, 0.0),
            (lambda: c.jog_stop(3), 17, 0.0, 3, 0, 0.0),
            (lambda: c.home(0b101), 18, 0.0, 5, 0, 0.0),
        ]
        for n, (call, kind, value, index, mode, speed) in enumerate(calls, start=1):
            with self.subTest(kind=kind, value=value, index=index):
                r = call()
                self.assertTrue(r.accepted)
                self.assertEqual(self.decode(c._client.sent[-1]),
                                 (6, kind, n, value, 0, index, mode, speed))

    def test_an_index_that_is_no_u32_is_not_sent(self):
        c = fake_client()
        for bad in (-1, 2**32):
            with self.assertRaises(ValueError):
                c.set_input(bad, True)
        self.assertEqual(c._client.sent, [])
        # A number the daemon refuses (64) is sent: the daemon says why.
        c.set_input(64, True)
        self.assertEqual(self.decode(c._client.sent[-1])[5], 64)


if __name__ == "__main__":
    unittest.main()
