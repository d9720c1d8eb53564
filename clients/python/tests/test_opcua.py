"""``kerf serve``'s OPC UA server from a third-party client: Python ``asyncua`` (from PyPI)
browses the machine's address space (the Machine Tools specification's browse names, and
its types, whose definitions resolve on the server), subscribes to an axis position and the active
program's state while a program runs (sent through the JSON API), sees the values change
and the program end, and is refused a write; and one client reads two machines, each with
its own daemon and ``kerf serve``, side by side (docs/API.md, "OPC UA"); and with a
certificate configured, the secure endpoints: a client's certificate rejected until an
administrator trusts it, users logging in with passwords kept as PBKDF2 hashes (made here
with Python's own hashlib), and only an operator holding, overriding and resuming a
running program through the Control methods.

Needs ``pip install asyncua`` (``.ci/run`` installs it) and the debug binaries.
"""

import asyncio
import hashlib
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import time
import unittest
import urllib.error
import urllib.request
from pathlib import Path

from support import KERF, PATIENCE_S, Machine

try:
    from asyncua import Client, ua
    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
    from cryptography.x509.oid import ExtendedKeyUsageOID
except ImportError:  # pragma: no cover - said by the test itself
    Client = None

TOKEN = "opcua-test-token-0123456789"


class Served:
    """A homed machine with its daemon and ``kerf serve`` on free ports of 127.0.0.1."""

    def __init__(self, test, tag, serve_lines=None):
        self.m = Machine(test, tag)
        with open(self.m.config, "a", encoding="utf-8") as f:
            digest = hashlib.sha256(TOKEN.encode()).hexdigest()
            f.write(f'\n[serve]\ncontrol_token_sha256 = "{digest}"\n'
                    f'manufacturer = "Test Works"\nserial_number = "SN-{tag}"\n')
            if serve_lines:
                f.write(serve_lines(self.m))
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

    def post_json(self, path, body, client=None):
        """POST ``body`` to ``path`` with the token (and ``Kerf-Client``): the status code
        and the answer."""
        headers = {"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/json"}
        if client:
            headers["Kerf-Client"] = client
        request = urllib.request.Request(f"http://{self.http}{path}",
                                         data=json.dumps(body).encode(), headers=headers,
                                         method="POST")
        try:
            with urllib.request.urlopen(request, timeout=PATIENCE_S) as r:
                return r.status, json.load(r)
        except urllib.error.HTTPError as e:
            return e.code, json.load(e)

    def status(self):
        with urllib.request.urlopen(f"http://{self.http}/api/v1/status", timeout=PATIENCE_S) as r:
            return json.load(r)["status"]

    def said(self):
        with open(self.err_path, encoding="utf-8", errors="replace") as f:
            return f.read()

    def close(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


async def machine_node(client, machine):
    """The namespace indexes (``own``: the machine's, ``mt``: Machine Tools,
    ``machinery``, ``di``, ``ua``: the base) and the machine's object: Objects / Machinery's
    Machines / MACHINE."""
    sp = {"own": await client.get_namespace_index(f"urn:kerf:{machine}"), "ua": 0}
    for key, uri in [("mt", "http://opcfoundation.org/UA/MachineTool/"),
                     ("machinery", "http://opcfoundation.org/UA/Machinery/"),
                     ("di", "http://opcfoundation.org/UA/DI/")]:
        sp[key] = await client.get_namespace_index(uri)
    objects = client.nodes.objects
    node = await objects.get_child([f"{sp['machinery']}:Machines", f"{sp['own']}:{machine}"])
    return sp, node


async def child(node, sp, path):
    """The node at ``path`` under ``node``: browse names with their namespace's key, as
    ``di:Identification/di:Manufacturer``."""
    names = []
    for step in path.split("/"):
        key, name = step.split(":")
        names.append(f"{sp[key]}:{name}")
    return await node.get_child(names)


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
            sp, machine = await machine_node(client, s.m.machine)
            at = lambda path: child(machine, sp, path)  # noqa: E731
            # Identification from the configuration (DI's browse names and types).
            self.assertEqual((await (await at("di:Identification/di:Manufacturer")).read_value()).Text,
                             "Test Works")
            self.assertEqual(await (await at("di:Identification/di:SerialNumber")).read_value(),
                             "SN-opcua")
            # The Machine Tools types, imported from the OPC Foundation's NodeSet2 files:
            # each object's type definition is the specification's, and resolves.
            for path, type_id, type_name in [
                    (None, 13, "MachineToolType"),
                    ("di:Identification", 11, "MachineToolIdentificationType"),
                    ("mt:Monitoring", 14, "MonitoringType"),
                    ("mt:Monitoring/mt:MachineTool", 26, "MachineOperationMonitoringType"),
                    ("mt:Monitoring/own:Channel1", 16, "ChannelMonitoringType"),
                    ("mt:Monitoring/own:Spindle", 22, "SpindleMonitoringType"),
                    ("mt:Production", 21, "ProductionType"),
                    ("mt:Production/mt:ActiveProgram", 32, "ProductionActiveProgramType"),
                    ("mt:Production/mt:ActiveProgram/mt:State", 15, "ProductionProgramStateMachineType"),
                    ("mt:Notification", 7, "NotificationType"),
                    ("mt:Equipment", 12, "EquipmentType")]:
                node = machine if path is None else await at(path)
                type_node = client.get_node(await node.read_type_definition())
                self.assertEqual(type_node.nodeid, ua.NodeId(type_id, sp["mt"]), path)
                self.assertEqual(await type_node.read_browse_name(),
                                 ua.QualifiedName(type_name, sp["mt"]), path)
            # Every node the documentation lists is there.
            for path in ["mt:Monitoring/mt:MachineTool/mt:OperationMode",
                         "mt:Monitoring/mt:MachineTool/mt:PowerOnDuration",
                         "mt:Monitoring/own:Channel1/mt:ChannelState",
                         "mt:Monitoring/own:Channel1/mt:FeedOverride",
                         "mt:Monitoring/own:Spindle/mt:Override",
                         "mt:Monitoring/own:Spindle/mt:IsRotating",
                         "mt:Monitoring/own:Y/own:ActualPosition",
                         "mt:Monitoring/own:Z/own:ActualPosition",
                         "mt:Production/mt:ActiveProgram/mt:Name",
                         "mt:Production/mt:ActiveProgram/own:Line",
                         "mt:Production/mt:ActiveProgram/own:Progress"]:
                await (await at(path)).read_value()
            # Idle: Manual (MachineOperationMode 0), the channel Reset (ChannelState 2).
            self.assertEqual(await (await at("mt:Monitoring/mt:MachineTool/mt:OperationMode")).read_value(), 0)
            self.assertEqual(await (await at("mt:Monitoring/own:Channel1/mt:ChannelState")).read_value(), 2)
            x = await at("mt:Monitoring/own:X/own:ActualPosition")
            state = await at("mt:Production/mt:ActiveProgram/mt:State/ua:CurrentState")
            self.assertEqual((await state.read_value()).Text, "Initializing")
            state_id = await state.get_child(["0:Id"])
            self.assertEqual(await state_id.read_value(), ua.NodeId(5039, sp["mt"]))
            self.assertEqual(await (await at("mt:Monitoring/own:Channel1/mt:FeedOverride")).read_value(),
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
            texts = lambda: [v.Text for v in handler.values.get(state.nodeid.to_string(), [])]  # noqa: E731
            while "Ended" not in texts():
                self.assertLess(time.monotonic(), deadline, f"never ended: {handler.values}")
                await asyncio.sleep(0.05)
            states = texts()
            self.assertIn("Running", states)
            self.assertEqual(states[-1], "Ended")
            positions = handler.values[x.nodeid.to_string()]
            self.assertGreater(len(set(positions)), 3, positions)
            self.assertGreater(max(positions), 10.0, positions)
            self.assertEqual(await x.read_value(), 0.0)
            name = await at("mt:Production/mt:ActiveProgram/mt:Name")
            self.assertEqual(await name.read_value(), "part.ngc")
            self.assertEqual(await state_id.read_value(), ua.NodeId(5038, sp["mt"]), "Ended")
            progress = await at("mt:Production/mt:ActiveProgram/own:Progress")
            self.assertEqual(await progress.read_value(), 100.0)
            await subscription.delete()

    def test_one_client_reads_two_machines_side_by_side(self):
        a, b = Served(self, "mill_a"), Served(self, "mill_b")
        asyncio.run(self.side_by_side(a, b))

    async def side_by_side(self, a, b):
        serials = {}
        for s in (a, b):
            async with Client(url=f"opc.tcp://{s.opcua}/", timeout=PATIENCE_S) as client:
                sp, machine = await machine_node(client, s.m.machine)
                serial = await child(machine, sp, "di:Identification/di:SerialNumber")
                x = await child(machine, sp, "mt:Monitoring/own:X/own:ActualPosition")
                serials[s.m.machine] = (await serial.read_value(), await x.read_value())
        self.assertEqual(serials, {a.m.machine: ("SN-mill_a", 0.0), b.m.machine: ("SN-mill_b", 0.0)})


def password_hash(password, iterations=10000):
    """``serve.opcua_users``' ``password_hash``, made with Python's hashlib (not Kerf's
    code): PBKDF2-HMAC-SHA256 over a random salt. 10,000 iterations, the fewest the
    configuration accepts, keep the test's logins quick."""
    salt = os.urandom(16)
    key = hashlib.pbkdf2_hmac("sha256", password.encode(), salt, iterations)
    return f"pbkdf2-sha256${iterations}${salt.hex()}${key.hex()}"


CLIENT_URI = "urn:kerf:test:opcua-client"


class SecureOpcUaTest(unittest.TestCase):
    def setUp(self):
        if Client is None:
            self.fail("Python asyncua is not installed: `pip install asyncua` (.ci/run does)")

    def test_with_a_certificate_operators_log_in_on_secure_endpoints_and_only_they_hold_override_and_resume(self):
        certs = {}

        def serve_lines(m):
            # The server's certificate and key, and this client's, made with asyncua's
            # helper (cryptography), as an administrator would with openssl.
            d = Path(m.dir)
            for who, uri, host, use in [
                ("server", f"urn:kerf:serve:{m.machine}", "localhost", ExtendedKeyUsageOID.SERVER_AUTH),
                ("client", CLIENT_URI, socket.gethostname(), ExtendedKeyUsageOID.CLIENT_AUTH),
            ]:
                key, cert = d / f"{who}-key.pem", d / f"{who}-cert.der"
                asyncio.run(setup_self_signed_certificate(
                    key, cert, uri, host, [use], {"commonName": f"kerf test {who}"}))
                certs[who] = (str(cert), str(key))
            return (f'opcua_certificate = "{certs["server"][0]}"\n'
                    f'opcua_private_key = "{certs["server"][1]}"\n'
                    f'opcua_pki_dir = "{d / "pki"}"\n'
                    f'opcua_users = [\n'
                    f'  {{ name = "op", password_hash = "{password_hash("operator-pass")}", role = "operator" }},\n'
                    f'  {{ name = "shop", password_hash = "{password_hash("viewer-pass")}", role = "viewer" }},\n'
                    f']\n')

        s = Served(self, "opcua_secure", serve_lines)
        asyncio.run(self.secure(s, certs["client"]))

    def secure_client(self, s, client_cert, user, password):
        client = Client(url=f"opc.tcp://{s.opcua}/", timeout=PATIENCE_S)
        client.application_uri = CLIENT_URI
        client.set_user(user)
        client.set_password(password)
        return client

    async def secure(self, s, client_cert):
        url = f"opc.tcp://{s.opcua}/"
        # The endpoints: None for anonymous reading, and signed and encrypted ones where
        # users log in; no user name on the None endpoint.
        async with Client(url=url, timeout=PATIENCE_S) as anonymous:
            endpoints = await anonymous.get_endpoints()
            offered = {(e.SecurityPolicyUri.split("#")[-1], e.SecurityMode.name,
                        tuple(sorted(t.TokenType.name for t in e.UserIdentityTokens)))
                       for e in endpoints}
            self.assertEqual(offered, {
                ("None", "None_", ("Anonymous",)),
                ("Basic256Sha256", "SignAndEncrypt", ("Anonymous", "UserName")),
                ("Aes128_Sha256_RsaOaep", "SignAndEncrypt", ("Anonymous", "UserName")),
                ("Aes256_Sha256_RsaPss", "SignAndEncrypt", ("Anonymous", "UserName")),
            })
            sp, machine = await machine_node(anonymous, s.m.machine)
            ns = sp["own"]
            control = await machine.get_child([f"{ns}:Control"])
            # Anonymous: reads, but may not call.
            with self.assertRaises(ua.UaStatusCodeError) as refused:
                await control.call_method(f"{ns}:Hold")
            self.assertEqual(refused.exception.code, ua.StatusCodes.BadUserAccessDenied)

        # The operator's first secure connection: this client's certificate is unknown, so
        # it is refused and lands in rejected/; trusted by an administrator, it connects.
        client = self.secure_client(s, client_cert, "op", "operator-pass")
        with self.assertRaises(Exception):
            await client.set_security(SecurityPolicyBasic256Sha256, client_cert[0], client_cert[1],
                                      mode=ua.MessageSecurityMode.SignAndEncrypt)
            await client.connect()
        client.disconnect_socket()
        pki = Path(s.m.dir) / "pki"
        rejected = list((pki / "rejected").glob("*.der"))
        self.assertEqual(len(rejected), 1, list(pki.rglob("*")))
        (pki / "trusted").mkdir(exist_ok=True)
        shutil.move(str(rejected[0]), str(pki / "trusted" / rejected[0].name))

        async def login(user, password):
            c = self.secure_client(s, client_cert, user, password)
            await c.set_security(SecurityPolicyBasic256Sha256, client_cert[0], client_cert[1],
                                 mode=ua.MessageSecurityMode.SignAndEncrypt)
            await c.connect()
            return c

        # A wrong password: refused, and logged.
        with self.assertRaises(Exception):
            bad = await login("op", "operator-pasS")
            await bad.disconnect()
        self.assertIn("refused the OPC UA login of `op`: wrong password", s.said())

        op = await login("op", "operator-pass")
        try:
            sp, machine = await machine_node(op, s.m.machine)
            ns = sp["own"]
            control = await machine.get_child([f"{ns}:Control"])
            feed = await child(machine, sp, "mt:Monitoring/own:Channel1/mt:FeedOverride")
            state = await child(machine, sp, "mt:Production/mt:ActiveProgram/mt:State/ua:CurrentState")
            answer = s.post_program("slow.ngc", "G21 G90\nG1 X30 F600\nG1 X0\nM2\n")
            self.assertTrue(answer["ok"], answer)

            async def until(what, predicate):
                deadline = time.monotonic() + PATIENCE_S
                while not await predicate():
                    self.assertLess(time.monotonic(), deadline, f"never {what}: {s.status()}")
                    await asyncio.sleep(0.02)

            await until("running", lambda: self._eq(state, "Running"))
            await until("moving", lambda: self._status_is(s, "running"))
            await control.call_method(f"{ns}:Hold")
            await until("held", lambda: self._status_is(s, "holding"))
            await until("interrupted", lambda: self._eq(state, "Interrupted"))
            x_held = s.status()["position"]["x"]
            self.assertGreater(x_held, 0.0)
            self.assertLess(x_held, 30.0)
            await control.call_method(f"{ns}:SetFeedOverride", ua.Variant(50.0, ua.VariantType.Double))
            await until("the override at 50 %", lambda: self._eq(feed, 50.0))
            with self.assertRaises(ua.UaStatusCodeError) as refused:
                await control.call_method(f"{ns}:SetFeedOverride", ua.Variant(250.0, ua.VariantType.Double))
            self.assertEqual(refused.exception.code, ua.StatusCodes.BadOutOfRange)
            # While a web client holds the control lease, the operator may only hold.
            code, lease = s.post_json("/api/v1/control/lease", {"action": "take"}, "page-opcuatest")
            self.assertEqual(code, 200, lease)
            with self.assertRaises(ua.UaStatusCodeError) as refused:
                await control.call_method(f"{ns}:Resume")
            self.assertEqual(refused.exception.code, ua.StatusCodes.BadInvalidState)
            self.assertIn("refused the OPC UA call Resume: the machine is controlled from", s.said())
            await control.call_method(f"{ns}:Hold")
            code, lease = s.post_json("/api/v1/control/lease", {"action": "release"}, "page-opcuatest")
            self.assertEqual(code, 200, lease)
            # Resumed by the operator, the program runs to its end.
            await control.call_method(f"{ns}:Resume")
            await until("ended", lambda: self._eq(state, "Ended"))
            # At the program's exact end: kerf serve's status is read from the daemon every
            # 50 ms, so it may still show the last millimetres of the motion just after the
            # job ended.
            await until("at X0", lambda: self._x_is(s, 0.0))
        finally:
            await op.disconnect()

        # A viewer logs in and reads, but may not call.
        shop = await login("shop", "viewer-pass")
        try:
            sp, machine = await machine_node(shop, s.m.machine)
            ns = sp["own"]
            control = await machine.get_child([f"{ns}:Control"])
            with self.assertRaises(ua.UaStatusCodeError) as refused:
                await control.call_method(f"{ns}:SetFeedOverride", ua.Variant(100.0, ua.VariantType.Double))
            self.assertEqual(refused.exception.code, ua.StatusCodes.BadUserAccessDenied)
        finally:
            await shop.disconnect()
        self.assertEqual(s.status()["override_pct"], 50.0, "the viewer changed nothing")

    @staticmethod
    async def _eq(node, value):
        v = await node.read_value()
        return (v.Text if isinstance(v, ua.LocalizedText) else v) == value

    @staticmethod
    async def _status_is(s, state):
        return s.status()["state"] == state

    @staticmethod
    async def _x_is(s, x):
        return s.status()["position"]["x"] == x


if __name__ == "__main__":
    unittest.main()
