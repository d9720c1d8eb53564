"""The Python client against a real ``kerfd`` (one daemon per test, see support.py).

1. A program published from Python (lines, an arc, a helix, a rapid, M2) runs to
   FINISHED and the machine stops at its end point; the status the client parses equals
   what `kerf status --json` (the Rust side) reports.
2. The setpoints read for that program equal `kerf sim`'s CSV of the same program written
   as G-code, bit for bit, with no gap.
3. Adversarial messages are refused, counted in `rejected`, and move nothing.
4. Abort while streaming 200,000 short lines: ABORTED, `run_program` returns at once and
   the machine stops.
5. The operator's switches set from Python and from `kerf` read the same on both sides,
   the machine section of the status equals `kerf status --json`'s, and requests the
   daemon must refuse (a switch 0.5, an input out of range or not simulated, a spindle
   override of 250 %) are refused with their reason.

Build the binaries first: `cargo build -p kerf -p kerfd --bins` (or set KERFD and KERF).
"""

import json
import math
import threading
import time
import unittest

import support
from support import Collector, Machine, wait_until

import kerf_client as k
from kerf_client import moves as mv
from kerf_client import protocol as p

F = 3000.0  # mm/min

#: The program of tests 1 and 2, as G-code (line 1 is the modal line).
GCODE = """G21 G90 G17 G64
G1 X10 Y0 F3000
G3 X20 Y10 I0 J10
G2 X30 Y20 I10 J0
G3 X30 Y20 Z-3 I0 J-5
G1 X5 Y5 Z-1
G0 X5 Y5 Z2
M2
"""
END_POINT = (5.0, 5.0, 2.0)


def program_items(start=(0.0, 0.0, 0.0)):
    """The same program built with the helpers, source lines as in GCODE (the G-code
    starts at the origin; ``start`` must be the origin for the two to be the same)."""
    return [
        mv.line(start, (10, 0, 0), F, line=2),
        mv.arc((10, 0, 0), (20, 10, 0), (10, 10, 0), F, ccw=True, line=3),
        mv.arc((20, 10, 0), (30, 20, 0), (30, 10, 0), F, ccw=False, line=4),
        mv.arc((30, 20, 0), (30, 20, -3), (30, 15, 0), F, ccw=True, line=5),  # helix
        mv.line((30, 20, -3), (5, 5, -1), F, line=6),
        mv.line((5, 5, -1), END_POINT, rapid=True, line=7),
        mv.event(p.EVENT_M2, line=8),
    ]


def wait_fate_final(client, program_id, what, timeout_s=support.PATIENCE_S):
    """The REQUEST_PROGRAM reply once the program's fate is final."""
    last = [None]

    def final():
        last[0] = client.program_fate(program_id)
        return last[0] if last[0].fate in k.FINAL_FATES else None

    try:
        return wait_until(f"the final fate of {what}", final, timeout_s=timeout_s)
    except AssertionError:
        raise AssertionError(
            f"the fate of {what} ({program_id}) is not final after {timeout_s} s: "
            f"{last[0]}") from None


class ProgramFromPython(unittest.TestCase):
    def test_1_program_runs_to_its_end_and_status_matches_kerf_status(self):
        m = Machine(self, "run")
        c = m.start()
        s0 = c.status().status
        self.assertEqual(s0.state, p.STATE_IDLE)
        self.assertEqual(s0.position, (0.0, 0.0, 0.0))
        self.assertGreater(s0.window_items, 0)

        r = c.run_program(program_items(s0.position), s0.position, timeout_s=60)
        self.assertEqual(r.fate, p.PROGRAM_FATE_FINISHED, r)
        self.assertEqual(r.items_sent, 7)
        self.assertTrue(r.end_sent)

        f = c.program_fate(r.program_id)
        self.assertTrue(f.accepted, f)
        self.assertEqual(f.fate, p.PROGRAM_FATE_FINISHED, f)
        s = c.status().status
        self.assertEqual(s.program_id, r.program_id)
        self.assertEqual(s.program_end, p.PROGRAM_END_FINISHED, s)
        self.assertTrue(s.program_done, s)
        self.assertEqual(s.state, p.STATE_IDLE, s)
        self.assertEqual(s.moves_received, 7, s)  # items only, never BEGIN and END
        self.assertEqual(s.position, END_POINT, s)
        self.assertEqual(s.rejected, 0, s)

        # The Rust side's reading of the same status (`kerf status --json`).
        j = json.loads(m.kerf("status", "--json").stdout)
        s = c.status().status
        self.assertEqual(j["machine"], m.machine)
        self.assertEqual((j["position"]["x"], j["position"]["y"], j["position"]["z"]),
                         s.position)
        self.assertEqual(j["state"], s.state_name)
        self.assertEqual(j["program_end"], s.program_end_name)
        self.assertEqual(j["program_id"], s.program_id)
        self.assertEqual(j["program_done"], s.program_done)
        self.assertEqual(j["moves_received"], s.moves_received)
        self.assertEqual(j["window_items"], s.window_items)
        self.assertEqual(j["rejected"], s.rejected)
        self.assertEqual(j["override_pct"], s.override_pct)
        self.assertEqual(j["queued_moves"], s.queued_moves)
        self.assertEqual(j["rt"], s.rt)
        self.assertEqual(j["drives"], s.drives_name)
        # Simulated drives: no EtherCAT bus on either side.
        self.assertIsNone(j["ethercat"])
        self.assertIsNone(s.ethercat)
        self.assertEqual(j["period_us"] * 1000.0, s.period_ns)
        # The machine section (protocol version 5), key for key.
        for key, value in s.machine.items():
            self.assertEqual(j[key], value, key)
        self.assertLessEqual(j["cycles"], c.status().status.cycles)

        # The control requests answer with the status after they were handled.
        o = c.override(50)
        self.assertTrue(o.accepted, o)
        self.assertEqual(o.status.override_pct, 50.0)
        o = c.override(250)
        self.assertFalse(o.accepted)
        self.assertEqual(o.reason, p.REASON_BAD_VALUE)
        o = c.resume()  # not holding
        self.assertFalse(o.accepted)
        self.assertEqual(o.reason, p.REASON_NOT_ALLOWED)
        self.assertTrue(c.override(100).accepted)
        u = c.program_fate(k.new_program_id())
        self.assertEqual(u.fate, p.PROGRAM_FATE_UNKNOWN, u)

    def test_2_setpoints_equal_kerf_sim(self):
        m = Machine(self, "sim")
        # Same program as G-code, simulated: one row per period, row 0 the start.
        prog = m.write("prog.ngc", GCODE)
        csv = m.path("sim.csv")
        m.kerf("sim", prog, "--out", csv)
        header, rows = support.read_csv(csv)
        self.assertEqual(header, ["t", "x", "y", "z", "line", "feed_mm_s"])

        # The helpers build exactly what the interpreter resolves (`kerf plan`).
        plan = [json.loads(x) for x in m.kerf("plan", prog).stdout.splitlines()]
        items = program_items()
        self.assertEqual(len(plan), len(items))
        for want, got in zip(plan, items):
            with self.subTest(line=want["line"]):
                self.assertEqual(got.line, want["line"])
                if want["type"] == "event":
                    self.assertEqual(got.kind, p.KIND_EVENT)
                    self.assertEqual(p.name_of("EVENT", got.event_code), want["code"].lower())
                    continue
                self.assertEqual(got.kind, p.KIND_ARC if want["type"] == "arc" else p.KIND_LINE)
                self.assertEqual(list(got.start_mm), want["start"])
                self.assertEqual(list(got.end_mm), want["end"])
                if want["type"] == "arc":
                    self.assertEqual(list(got.center_mm), want["center"])
                    self.assertEqual(list(got.axis), want["axis"])
                    self.assertEqual(got.sweep_rad, want["sweep_rad"])
                    self.assertEqual(got.feed_mm_min, want["feed_mm_min"])
                else:
                    self.assertEqual(bool(got.flags & p.FLAG_RAPID), want["rapid"])
                    self.assertEqual(got.feed_mm_min, want["feed_mm_min"] or 0.0)

        c = m.start()
        s0 = c.status().status
        self.assertEqual(s0.position, (0.0, 0.0, 0.0))
        period_s = s0.period_ns * 1e-9
        stream = c.setpoints()  # subscribed before anything is sent
        collector = Collector(stream)
        r = c.run_program(items, s0.position, timeout_s=60)
        self.assertEqual(r.fate, p.PROGRAM_FATE_FINISHED, r)
        # A few more cycles, so that the last of the program's is in.
        n0 = c.status().status.cycles
        wait_until("50 more cycles", lambda: c.status().status.cycles >= n0 + 50)
        samples = collector.stop()

        self.assertGreater(len(samples), len(rows))
        self.assertEqual(stream.lost, 0, "samples lost (a gap in seq)")
        seqs = [s.seq for s in samples]
        self.assertEqual(seqs, list(range(seqs[0], seqs[0] + len(seqs))), "seq gap")
        if stream.skipped_periods:
            print(f"\n  note: the daemon skipped {stream.skipped_periods} periods "
                  "(missed deadlines) while the program ran")

        mine = [s for s in samples if s.program_id == r.program_id and s.program_cycle > 0]
        self.assertEqual([s.program_cycle for s in mine], list(range(1, len(mine) + 1)),
                         "program cycles 1, 2, ... without a gap")
        self.assertEqual(len(mine), len(rows) - 1, "one sample per CSV row after row 0")
        # Row 0 is the start: the position before the program's first cycle.
        self.assertEqual([float(x) for x in rows[0][1:4]], [0.0, 0.0, 0.0])
        before = [s for s in samples if s.seq < mine[0].seq]
        self.assertTrue(before)
        self.assertEqual(before[-1].position_mm_deg[:3], (0.0, 0.0, 0.0))
        first_diff = None
        worst = 0.0
        for s in mine:
            row = rows[s.program_cycle]
            self.assertTrue(math.isclose(float(row[0]), s.program_cycle * period_s,
                                         rel_tol=0, abs_tol=1e-9), row)
            want = (float(row[1]), float(row[2]), float(row[3]), int(row[4]), float(row[5]))
            got = (*s.position_mm_deg[:3], s.line, s.feed_mm_s)
            if want != got and first_diff is None:
                first_diff = (s.program_cycle, want, got)
            worst = max(worst, *(abs(a - b) for a, b in zip(want[:3], got[:3])))
        self.assertIsNone(first_diff, f"first row that differs (cycle, sim, daemon); "
                                      f"largest position difference {worst} mm")
        self.assertEqual(mine[-1].position_mm_deg[:3], END_POINT)
        after = [s for s in samples if s.seq > mine[-1].seq]
        self.assertTrue(after)
        for s in after:
            self.assertEqual(s.position_mm_deg[:3], END_POINT)
            self.assertEqual(s.program_cycle, 0)


class Adversarial(unittest.TestCase):
    def test_3_adversarial_messages_are_refused_counted_and_move_nothing(self):
        """Every case runs as a subtest: a failing one is reported and the next still run
        (the counts are re-based on what the daemon counted)."""
        m = Machine(self, "adv")
        c = m.start()
        s0 = c.status().status
        home = s0.position
        x0, y0, z0 = home
        rejected0 = s0.rejected
        stream = c.setpoints()
        collector = Collector(stream)
        pub = c.publish

        sent = {}        # kind -> adversarial messages sent
        counted = {}     # kind -> how much `rejected` grew
        refused = {}     # program id -> what (programs that must be REFUSED)
        hosts = {}       # program id -> what (valid programs that must FINISH)
        base = [rejected0]

        def rejected():
            return c.status().status.rejected

        def expect_rejected(kind, n, settle_s=0.1):
            """``n`` more refusals for ``kind``: wait for them, then check that no more
            come."""
            sent[kind] = sent.get(kind, 0) + n
            want = base[0] + n
            try:
                wait_until(f"rejected = {want} after {kind}",
                           lambda: rejected() >= want, timeout_s=5)
            except AssertionError:
                pass  # reported by the equality below
            time.sleep(settle_s)
            got = rejected()
            counted[kind] = got - base[0]
            base[0] = got
            self.assertEqual(got - (want - n), n,
                             f"{kind}: `rejected` grew by {got - (want - n)}, "
                             f"expected {n}")

        def final_fate(pid, what):
            return wait_fate_final(c, pid, what, timeout_s=10)

        def loop_items():
            """A valid little path out and back to the start: 5 mm in X and back."""
            out = (x0 + 5.0, y0, z0)
            return [mv.line(home, out, F, line=1), mv.line(out, home, F, line=2)]

        def stamp(msg, pid, seq):
            msg = msg.copy()
            msg.program_id = pid
            msg.seq = seq
            return msg

        def one_bad_item(kind, bad, seq=1):
            """A program whose first item is ``bad``: BEGIN, bad, END (END is dropped
            uncounted: the program already stopped, rule 6)."""
            pid = k.new_program_id()
            refused[pid] = kind
            pub(mv.begin(pid, home, 0))
            pub(stamp(bad, pid, seq))
            pub(mv.end(pid, 2, 1))
            with self.subTest(kind=kind, check="counted once"):
                expect_rejected(kind, 1)
            with self.subTest(kind=kind, check="fate and status"):
                f = final_fate(pid, kind)
                self.assertEqual(f.fate, p.PROGRAM_FATE_REFUSED, f"{kind}: {f}")
                self.assertTrue(f.message, f"{kind}: a refused program's fate says why")
                s = c.status().status
                self.assertEqual(s.program_id, pid, f"{kind}: {s}")
                self.assertEqual(s.program_end, p.PROGRAM_END_REFUSED, f"{kind}: {s}")
                self.assertTrue(s.fault_text, f"{kind}: {s}")
                self.assertFalse(s.program_done, f"{kind}: {s}")
            return pid

        # 1. Inconsistent arcs: the centre 1e8 mm (then 1e10 mm) away, the end 10 mm from
        #    the start on the circle, the sweep 9e-7 rad more than the end's angle: the end
        #    is r * 9e-7 (90 mm, 9000 mm) from where the sweep leads.
        for kind, r in (("inconsistent arc r=1e8", 1e8), ("inconsistent arc r=1e10", 1e10)):
            center = (x0, y0 + r, z0)
            phi = 2.0 * math.asin(10.0 / (2.0 * r))
            end = (x0 + r * math.sin(phi), y0 + r - r * math.cos(phi), z0)
            self.assertAlmostEqual(math.dist(home, end), 10.0, delta=1e-3)
            sweep = phi + 9e-7
            miss = p.arc_mismatch_mm(home, end, center, (0, 0, 1), sweep)
            tol = p.arc_tolerance_mm(home, end, center, (0, 0, 1), sweep)
            self.assertGreater(miss, 1000 * tol, f"{kind}: the arc must be clearly wrong")
            bad = mv.arc(home, end, center, F, sweep_rad=sweep, line=1, check=False)
            one_bad_item(kind, bad)

        # 2. A BEGIN while another program is open: refused, the open program finishes.
        kind = "BEGIN while a program is open"
        host = k.new_program_id()
        intruder = k.new_program_id()
        hosts[host] = "host of the second BEGIN"
        refused[intruder] = kind
        a, b = loop_items()
        pub(mv.begin(host, home, 2))
        pub(stamp(a, host, 1))
        pub(mv.begin(intruder, home, 0))
        pub(stamp(b, host, 2))
        pub(mv.end(host, 3, 2))
        with self.subTest(kind=kind, check="counted once"):
            expect_rejected(kind, 1)
        with self.subTest(kind=kind, check="the open program finishes"):
            f = final_fate(host, "host of the second BEGIN")
            self.assertEqual(f.fate, p.PROGRAM_FATE_FINISHED, f)
            s = c.status().status
            self.assertEqual(s.program_id, host, s)
            self.assertEqual(s.position, home, s)
        with self.subTest(kind=kind, check="the refused BEGIN's fate"):
            f = final_fate(intruder, kind)
            self.assertEqual(f.fate, p.PROGRAM_FATE_REFUSED, f)
            self.assertTrue(f.message, f)

        # 3. A BEGIN repeating the previous program's id (a valid BEGIN otherwise).
        kind = "BEGIN repeating the previous program's id"
        wait_until("the host to be at rest", lambda: (lambda s: s.program_id == host and
                   s.program_end != p.PROGRAM_END_NONE)(c.status().status), timeout_s=10)
        pub(mv.begin(host, home, 0))
        with self.subTest(kind=kind, check="counted once"):
            expect_rejected(kind, 1)
        with self.subTest(kind=kind, check="the finished program stays finished"):
            s = c.status().status
            self.assertEqual(s.program_id, host, s)
            self.assertEqual(s.program_end, p.PROGRAM_END_FINISHED, s)
            self.assertTrue(s.program_done, s)
            f = c.program_fate(host)
            # The program that ran under this id finished; the page does not say which of
            # the two a lookup by the shared id reports, only that both are final.
            print(f"\n  REQUEST_PROGRAM for the id of a finished program after a refused "
                  f"BEGIN repeating it: {f.fate_name} {f.message!r}", end="")
            self.assertIn(f.fate, (p.PROGRAM_FATE_FINISHED, p.PROGRAM_FATE_REFUSED), f)

        # 4. A BEGIN that does not start at the machine position (0.5 mm off in X), with
        #    an item and END: the program is refused whole; the BEGIN counts once.
        kind = "BEGIN off the machine position"
        pid = k.new_program_id()
        refused[pid] = kind
        off = (x0 + 0.5, y0, z0)
        pub(mv.begin(pid, off, 1))
        pub(stamp(mv.line(off, (x0 + 3.0, y0, z0), F, line=1), pid, 1))
        pub(mv.end(pid, 2, 1))
        with self.subTest(kind=kind, check="counted once"):
            expect_rejected(kind, 1)
        with self.subTest(kind=kind, check="fate and status"):
            f = final_fate(pid, kind)
            self.assertEqual(f.fate, p.PROGRAM_FATE_REFUSED, f)
            self.assertTrue(f.message, f)
            s = c.status().status
            self.assertEqual(s.program_id, pid, s)
            self.assertEqual(s.program_end, p.PROGRAM_END_REFUSED, s)
            self.assertTrue(s.fault_text, s)

        # 5. NaN in a used field (the end's Y).
        nan_line = mv.line(home, (x0 + 1.0, y0 + 1.0, z0), F, line=1)
        nan_line.end_mm[1] = float("nan")
        one_bad_item("NaN in a used field", nan_line)

        # 6. A nonzero reserved field.
        res_line = mv.line(home, (x0 + 1.0, y0, z0), F, line=1)
        res_line.reserved = 1
        one_bad_item("nonzero reserved field", res_line)

        # 7. A message of another program id inside an open program: refused, the open
        #    program goes on and finishes.
        kind = "message of another program id"
        host2 = k.new_program_id()
        stranger = k.new_program_id()
        hosts[host2] = "host of the foreign message"
        a, b = loop_items()
        pub(mv.begin(host2, home, 2))
        pub(stamp(a, host2, 1))
        pub(stamp(mv.line(home, (x0 + 1.0, y0, z0), F, line=9), stranger, 2))
        pub(stamp(b, host2, 2))
        pub(mv.end(host2, 3, 2))
        with self.subTest(kind=kind, check="counted once"):
            expect_rejected(kind, 1)
        with self.subTest(kind=kind, check="the open program finishes"):
            f = final_fate(host2, "host of the foreign message")
            self.assertEqual(f.fate, p.PROGRAM_FATE_FINISHED, f)
            self.assertNotEqual(c.program_fate(stranger).fate, p.PROGRAM_FATE_FINISHED)

        # 8. A gap in seq: the first item carries seq 2.
        one_bad_item("gap in seq", mv.line(home, (x0 + 1.0, y0, z0), F, line=1), seq=2)

        # Everything is in: the count, the fates, the position, the setpoints.
        time.sleep(0.3)
        samples = collector.stop()
        s = c.status().status
        total = sum(sent.values())
        moving = [x for x in samples if x.program_cycle > 0]
        print(f"\n  adversarial messages sent per kind: {sent}"
              f"\n  `rejected` grew per kind:           {counted}"
              f"\n  refused in all: {s.rejected - rejected0} of {total}; moving cycles: "
              f"{len(moving)} (programs {sorted({x.program_id for x in moving})}; valid "
              f"hosts {sorted(hosts)}); samples read {len(samples)}, lost {stream.lost}")
        with self.subTest(check="total count"):
            self.assertEqual(s.rejected - rejected0, total, sent)
        with self.subTest(check="fates"):
            for pid, what in refused.items():
                f = c.program_fate(pid)
                self.assertNotEqual(f.fate, p.PROGRAM_FATE_FINISHED, f"{what}: {f}")
                self.assertEqual(f.fate, p.PROGRAM_FATE_REFUSED, f"{what}: {f}")
                self.assertTrue(f.message, f"{what}: {f}")
            for pid, what in hosts.items():
                self.assertEqual(c.program_fate(pid).fate, p.PROGRAM_FATE_FINISHED, what)
        with self.subTest(check="nothing moved but the valid hosts, and they came back"):
            self.assertEqual(s.position, home, "the machine ends where it started")
            self.assertEqual(stream.lost, 0, "samples lost")
            for x in moving:
                self.assertIn(x.program_id, hosts,
                              f"a moving cycle of a program that is not a valid host: {x} "
                              f"({refused.get(x.program_id, '?')})")
            for x in samples:
                if x.program_id not in hosts or x.program_cycle == 0:
                    self.assertEqual(x.position_mm_deg[:3], home, f"moved: {x}")


class Abort(unittest.TestCase):
    def test_4_abort_while_streaming_a_long_program(self):
        m = Machine(self, "abort")
        runner = m.start()
        ctl = m.client()
        s0 = ctl.status().status
        x0, y0, z0 = s0.position
        # 200,000 lines of 0.5 mm around a square, each with an exact stop. (Exact stops
        # keep every line a segment of its own, so the motion queue fills and the motion
        # starts while the program streams; blended lines this short are smoothed into
        # few segments, and the motion would wait for the END.)
        n_items, side = 200_000, 0.5
        square = [(x0, y0, z0), (x0 + side, y0, z0), (x0 + side, y0 + side, z0),
                  (x0, y0 + side, z0)]

        def items():
            for i in range(n_items):
                yield mv.line(square[i % 4], square[(i + 1) % 4], 6000.0, line=i + 1,
                              corner=p.CORNER_EXACT_STOP)

        stream = ctl.setpoints()
        collector = Collector(stream)
        pid = k.new_program_id()
        result = {}
        sent = [0]

        def run():
            try:
                result["r"] = runner.run_program(items(), s0.position, program_id=pid,
                                                 count=n_items, timeout_s=120,
                                                 on_sent=lambda i: sent.__setitem__(0, i))
            except BaseException as e:  # noqa: BLE001 - reported by the test
                result["e"] = e

        t = threading.Thread(target=run, daemon=True)
        t.start()
        wait_until("the program to move", lambda: (lambda s: s.program_id == pid
                   and s.position != s0.position)(ctl.status().status))
        time.sleep(0.5)
        sent_at_abort = sent[0]
        t_abort = time.monotonic()
        a = ctl.abort()
        self.assertTrue(a.accepted, a)
        t.join(10)
        returned_after = time.monotonic() - t_abort
        self.assertFalse(t.is_alive(), "run_program did not return within 10 s of the abort")
        self.assertNotIn("e", result, result.get("e"))
        r = result["r"]
        print(f"\n  abort: {sent_at_abort} items sent at the abort, {r.items_sent} in all "
              f"of {n_items}; run_program returned {returned_after:.2f} s after the abort")
        self.assertEqual(r.fate, p.PROGRAM_FATE_ABORTED, r)
        self.assertFalse(r.end_sent)
        self.assertLess(r.items_sent, n_items)
        self.assertLess(returned_after, 5.0)
        f = ctl.program_fate(pid)
        self.assertEqual(f.fate, p.PROGRAM_FATE_ABORTED, f)
        self.assertTrue(f.message, f)
        s1 = ctl.status().status
        self.assertEqual(s1.program_id, pid, s1)
        self.assertEqual(s1.program_end, p.PROGRAM_END_ABORTED, s1)
        self.assertFalse(s1.program_done, s1)
        # The client stopped sending: the daemon takes off (and drops) what was sent, and
        # then no more arrives.
        wait_until("the daemon to have taken every item sent",
                   lambda: ctl.status().status.moves_received == r.items_sent, timeout_s=10)
        time.sleep(0.5)
        s2 = ctl.status().status
        self.assertEqual(s2.moves_received, r.items_sent, s2)
        self.assertEqual(s2.position, s1.position, "the machine still moves after the abort")
        self.assertEqual(s2.state, p.STATE_IDLE, s2)
        samples = collector.stop()
        self.assertEqual(stream.lost, 0)
        self.assertTrue(any(x.program_id == pid and x.program_cycle > 0
                            and x.position_mm_deg != s0.position_mm_deg for x in samples),
                        "the program never moved")
        # After the fate was final, the setpoints stand still.
        last = [x for x in samples if x.seq >= samples[-1].seq - 300]
        self.assertTrue(all(x.position_mm_deg == s2.position_mm_deg for x in last))


#: The keys of the machine section of `kerf status --json` (crates/kerf/src/status_view.rs).
MACHINE_KEYS = ("pause", "switches", "tool", "spindle", "feed_override_enabled", "coolant",
                "io", "input_result")


class Switches(unittest.TestCase):
    def test_5_switches_and_the_machine_section(self):
        m = Machine(self, "switch")
        c = m.start()
        s0 = c.status().status
        self.assertEqual(sorted(s0.machine), sorted(MACHINE_KEYS))
        self.assertIsNone(s0.machine["pause"], s0)

        def kerf_json():
            return json.loads(m.kerf("status", "--json").stdout)

        # Each switch on from Python: the answer's status already shows it (the status
        # after the request), and `kerf status --json` reads the same.
        bits = {"optional_stop": p.SWITCH_OPTIONAL_STOP,
                "block_delete": p.SWITCH_BLOCK_DELETE,
                "single_block": p.SWITCH_SINGLE_BLOCK}
        setters = {"optional_stop": c.optional_stop, "block_delete": c.block_delete,
                   "single_block": c.single_block}
        for name, setter in setters.items():
            with self.subTest(switch=name):
                r = setter(True)
                self.assertTrue(r.accepted, r)
                self.assertTrue(r.status.switches & bits[name], r.status)
                self.assertIs(r.status.machine["switches"][name], True)
        j = kerf_json()
        s = c.status().status
        self.assertEqual(j["switches"], {"optional_stop": True, "block_delete": True,
                                         "single_block": True})
        for key in MACHINE_KEYS:
            self.assertEqual(j[key], s.machine[key], key)
        # Off from `kerf`, read from Python.
        m.kerf("optional-stop", "off")
        m.kerf("single-block", "off")
        self.assertEqual(c.status().status.machine["switches"],
                         {"optional_stop": False, "block_delete": True,
                          "single_block": False})
        self.assertTrue(c.block_delete(False).accepted)
        self.assertEqual(c.status().status.switches, 0)

        # Refusals with their reason; nothing changes.
        r = c.request(p.REQUEST_OPTIONAL_STOP, value=0.5)
        self.assertEqual((r.accepted, r.reason), (False, p.REASON_BAD_VALUE), r)
        r = c.request(p.REQUEST_HOLD, index=1)
        self.assertEqual((r.accepted, r.reason), (False, p.REASON_BAD_VALUE), r)
        r = c.set_input(p.DIGITAL_IO, True)
        self.assertEqual((r.accepted, r.reason), (False, p.REASON_BAD_VALUE), r)
        r = c.set_analog_input(p.ANALOG_IO, 1.0)
        self.assertEqual((r.accepted, r.reason), (False, p.REASON_BAD_VALUE), r)
        r = c.spindle_override(250)
        self.assertEqual((r.accepted, r.reason), (False, p.REASON_BAD_VALUE), r)
        # config/kerf.toml has no input 30: in range, but not allowed; nor is input 3, the
        # X axis's simulated home switch (it follows the axis).
        for n in (30, 3):
            r = c.set_input(n, True)
            self.assertEqual((r.accepted, r.reason), (False, p.REASON_NOT_ALLOWED), r)
            self.assertTrue(r.message, r)
        s = c.status().status
        # Inputs 0 and 1 (part_present, door_closed) start on in config/kerf.toml; the
        # switches of the homed axes (3 to 11) are off.
        self.assertEqual((s.switches, s.digital_inputs), (0, 0b11), s)
        self.assertEqual(s.state, p.STATE_IDLE, s)


if __name__ == "__main__":
    unittest.main()
