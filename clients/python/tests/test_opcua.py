"""``kerf serve``'s OPC UA server from a third-party client: Python ``asyncua`` (from PyPI)
browses the machine's address space, subscribes to an axis position and the active
program's state while a program runs (sent through the JSON API), sees the values change
and the program end, and is refused a write; and one client reads two machines, each with
its own daemon and ``kerf serve``, side by side (docs/API.md, "OPC UA").

Needs ``pip install asyncua`` (``.ci/run`` installs it) and the debug binaries.
"""

import asyncio
import hashlib
import json
import os
import re
import signal
import subprocess
import time
import unittest
import urllib.request

from support import KERF, PATIENCE_S, Machine

try:
    from asyncua import Client, ua
except ImportError:  # pragma: no cover - said by the test itself
    Client = None

TOKEN = "opcua-test-token-0123456789"


class Served:
    """A homed machine with its daemon and ``kerf serve`` on free ports of 127.0.0.1."""

    def __init__(self, test, tag):
        self.m = Machine(test, tag)
        with open(self.m.config, "a", encoding="utf-8") as f:
            digest = hashlib.sha256(TOKEN.encode()).hexdigest()
            f.write(f'\n[serve]\ncontrol_token_sha256 = "{digest}"\n'
                    f'manufacturer = "Test Works"\nserial_number = "SN-{tag}"\n')
        self.m.start()
        env = dict(os.environ, STATE_DIRECTORY=self.m.dir)
        self.err_path = self.m.path("serve.stderr")
        with open(self.err_path, "wb") as err:
            self.proc = subprocess.Popen(
                [KERF, "serve", "--config", self.m.config,
                 "--http", "127.0.0.1:0", "--opcua", "127.0.0.1:0"],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, env=env,
            )
        test.addCleanup(self.close)
        deadline = time.monotonic() + PATIENCE_S
        while True:
            with open(self.err_path, encoding="utf-8", errors="replace") as f:
                said = f.read()
            found = re.search(r"on http://([^/]+)/ .* and opc\.tcp://([^/]+)/", said)
            if found:
                self.http, self.opcua = found.group(1), found.group(2)
                break
            if self.proc.poll() is not None or time.monotonic() > deadline:
                test.fail(f"kerf serve never listened: {said}")
            time.sleep(0.05)

    def post_program(self, name, text):
        request = urllib.request.Request(
            f"http://{self.http}/api/v1/program?name={name}", data=text.encode(),
            headers={"Authorization": f"Bearer {TOKEN}"}, method="POST")
        with urllib.request.urlopen(request, timeout=PATIENCE_S) as r:
            return json.load(r)

    def close(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


async def machine_node(client, machine):
    """The machine's object: Objects / Machines / MACHINE, by browse names in its
    namespace."""
    ns = await client.get_namespace_index(f"urn:kerf:{machine}")
    objects = client.nodes.objects
    node = await objects.get_child([f"{ns}:Machines", f"{ns}:{machine}"])
    return ns, node


class Collector:
    """An asyncua subscription handler that keeps every value per node."""

    def __init__(self):
        self.values = {}

    def datachange_notification(self, node, val, data):
        self.values.setdefault(node.nodeid.to_string(), []).append(val)


class OpcUaTest(unittest.TestCase):
    def setUp(self):
        if Client is None:
            self.fail("Python asyncua is not installed: `pip install asyncua` (.ci/run does)")

    def test_a_client_browses_subscribes_while_a_program_runs_and_is_refused_writes(self):
        s = Served(self, "opcua")
        asyncio.run(self.browse_and_subscribe(s))

    async def browse_and_subscribe(self, s):
        async with Client(url=f"opc.tcp://{s.opcua}/", timeout=PATIENCE_S) as client:
            ns, machine = await machine_node(client, s.m.machine)
            child = lambda *path: machine.get_child([f"{ns}:{p}" for p in path])  # noqa: E731
            # Identification from the configuration.
            self.assertEqual(await (await child("Identification", "Manufacturer")).read_value(),
                             "Test Works")
            self.assertEqual(await (await child("Identification", "SerialNumber")).read_value(),
                             "SN-opcua")
            # Every node the documentation lists is there.
            for path in [("Monitoring", "MachineTool", "OperationMode"),
                         ("Monitoring", "MachineTool", "PowerOnDuration"),
                         ("Monitoring", "Channel1", "ChannelState"),
                         ("Monitoring", "Channel1", "FeedOverride"),
                         ("Monitoring", "Spindle", "Override"),
                         ("Monitoring", "Spindle", "IsRotating"),
                         ("Monitoring", "Y", "ActualPosition"),
                         ("Monitoring", "Z", "ActualPosition"),
                         ("Production", "ActiveProgram", "Name"),
                         ("Production", "ActiveProgram", "Line")]:
                await (await child(*path)).read_value()
            x = await child("Monitoring", "X", "ActualPosition")
            state = await child("Production", "ActiveProgram", "State")
            self.assertEqual(await state.read_value(), "Initializing")
            self.assertEqual(await (await child("Monitoring", "Channel1", "FeedOverride")).read_value(),
                             100.0)
            # Refused: the server has no writable variable.
            with self.assertRaises(ua.UaStatusCodeError):
                await x.write_value(ua.DataValue(ua.Variant(5.0, ua.VariantType.Double)))
            self.assertEqual(await x.read_value(), 0.0, "a refused write changed nothing")
            # A program through the JSON API; the subscription sees it move and end.
            handler = Collector()
            subscription = await client.create_subscription(50, handler)
            await subscription.subscribe_data_change([x, state])
            answer = s.post_program("part.ngc", "G21 G90\nG1 X20 F1200\nG1 X0\nM2\n")
            self.assertTrue(answer["ok"], answer)
            deadline = time.monotonic() + PATIENCE_S
            while "Ended" not in handler.values.get(state.nodeid.to_string(), []):
                self.assertLess(time.monotonic(), deadline, f"never ended: {handler.values}")
                await asyncio.sleep(0.05)
            states = handler.values[state.nodeid.to_string()]
            self.assertIn("Running", states)
            self.assertEqual(states[-1], "Ended")
            positions = handler.values[x.nodeid.to_string()]
            self.assertGreater(len(set(positions)), 3, positions)
            self.assertGreater(max(positions), 10.0, positions)
            self.assertEqual(await x.read_value(), 0.0)
            name = await child("Production", "ActiveProgram", "Name")
            self.assertEqual(await name.read_value(), "part.ngc")
            await subscription.delete()

    def test_one_client_reads_two_machines_side_by_side(self):
        a, b = Served(self, "mill_a"), Served(self, "mill_b")
        asyncio.run(self.side_by_side(a, b))

    async def side_by_side(self, a, b):
        serials = {}
        for s in (a, b):
            async with Client(url=f"opc.tcp://{s.opcua}/", timeout=PATIENCE_S) as client:
                ns, machine = await machine_node(client, s.m.machine)
                serial = await machine.get_child([f"{ns}:Identification", f"{ns}:SerialNumber"])
                x = await machine.get_child([f"{ns}:Monitoring", f"{ns}:X", f"{ns}:ActualPosition"])
                serials[s.m.machine] = (await serial.read_value(), await x.read_value())
        self.assertEqual(serials, {a.m.machine: ("SN-mill_a", 0.0), b.m.machine: ("SN-mill_b", 0.0)})


if __name__ == "__main__":
    unittest.main()
