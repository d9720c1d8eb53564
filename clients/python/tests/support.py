"""Shared pieces of the tests: paths, a real ``kerfd`` per test, ``kerf`` commands.

Every daemon test writes its own configuration, a copy of config/kerf.toml whose
``machine = "default"`` becomes ``py<pid>_<tag>``, so the iceoryx2 services
(``kerf/<machine>/...``) of tests never meet each other's or a real machine's. The daemon
is stopped (SIGTERM, then SIGKILL) and the scratch directory removed at the end of the
test, whatever happened (``KERF_TEST_KEEP=1`` keeps the directory of a failed test).

Binaries: ``KERFD`` and ``KERF`` (default ``target/debug/kerfd`` and ``target/debug/kerf``
of this checkout; build them with ``cargo build -p kerf -p kerfd --bins``).
"""

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE_ROOT = os.path.dirname(HERE)  # clients/python
REPO = os.path.dirname(os.path.dirname(PACKAGE_ROOT))
if PACKAGE_ROOT not in sys.path:
    sys.path.insert(0, PACKAGE_ROOT)

import kerf_client  # noqa: E402

KERFD = os.environ.get("KERFD", os.path.join(REPO, "target", "debug", "kerfd"))
KERF = os.environ.get("KERF", os.path.join(REPO, "target", "debug", "kerf"))
PROTOCOL_MD = os.path.join(REPO, "docs", "PROTOCOL.md")
CONFIG = os.path.join(REPO, "config", "kerf.toml")

#: Upper bound on any wait: a broken daemon fails a test instead of hanging it.
PATIENCE_S = 30.0


def need_binaries(test):
    for path in (KERFD, KERF):
        if not os.access(path, os.X_OK):
            test.fail(f"{path} is missing: build it with `cargo build -p kerf -p kerfd --bins` "
                      "(or point KERFD / KERF at the binaries)")


class Machine:
    """A scratch directory, a configuration with a unique machine name, and its daemon."""

    def __init__(self, test, tag):
        need_binaries(test)
        self.test = test
        self.machine = f"py{os.getpid()}_{tag}"
        self.dir = tempfile.mkdtemp(prefix=f"kerf-{self.machine}-")
        with open(CONFIG, encoding="utf-8") as f:
            text = f.read()
        needle = 'machine = "default"'
        assert needle in text, f"config/kerf.toml has no `{needle}`"
        text = text.replace(needle, f'machine = "{self.machine}"', 1)
        self.config = os.path.join(self.dir, "kerf.toml")
        with open(self.config, "w", encoding="utf-8") as f:
            f.write(text)
        self.daemon = None
        self.clients = []
        test.addCleanup(self.close)

    def path(self, name):
        return os.path.join(self.dir, name)

    def write(self, name, text):
        p = self.path(name)
        with open(p, "w", encoding="utf-8") as f:
            f.write(text)
        return p

    def daemon_stderr(self):
        try:
            with open(self.path("kerfd.stderr"), encoding="utf-8", errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    def start(self):
        """Starts ``kerfd --config FILE`` and returns a Client once its status answers."""
        with open(self.path("kerfd.stdout"), "wb") as out, \
                open(self.path("kerfd.stderr"), "wb") as err:
            self.daemon = subprocess.Popen(
                [KERFD, "--config", self.config],
                stdin=subprocess.DEVNULL, stdout=out, stderr=err,
            )
        deadline = time.monotonic() + PATIENCE_S
        last = None
        while time.monotonic() < deadline:
            if self.daemon.poll() is not None:
                self.test.fail(
                    f"kerfd exited at start ({self.daemon.returncode}): {self.daemon_stderr()}"
                )
            try:
                c = self.client()
                c.status()
                self.home(c)
                return c
            except kerf_client.KerfError as e:
                last = e
                time.sleep(0.05)
        self.test.fail(f"kerfd never answered ({last}): {self.daemon_stderr()}")

    def home(self, c):
        """Homes every axis (the bundled machine refuses programs until it is homed) as
        a client does: REQUEST_HOME once the drives are enabled, then the status until
        every axis is homed."""
        deadline = time.monotonic() + PATIENCE_S
        while c.status().status.drives == kerf_client.DRIVES_ENABLING:
            if time.monotonic() > deadline:
                self.test.fail(f"the drives never enabled: {self.daemon_stderr()}")
            time.sleep(0.02)
        mask = c.status().status.axes_mask & 0b111111
        r = c.home(mask)
        self.test.assertTrue(r.accepted, r.message)
        while True:
            s = c.status().status
            if s.homing & mask == 0:
                self.test.assertEqual(s.homed & mask, mask, s.fault_text)
                return
            if time.monotonic() > deadline:
                self.test.fail(f"homing never ended: {s.home_phase}")
            time.sleep(0.02)

    def client(self):
        c = kerf_client.Client(self.machine)
        self.clients.append(c)
        return c

    def kerf(self, *args, check=True):
        """``kerf SUBCOMMAND --config FILE ARGS...`` to completion."""
        cmd = [KERF, args[0], "--config", self.config, *args[1:]]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=PATIENCE_S * 4)
        if check and r.returncode != 0:
            self.test.fail(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr}")
        return r

    def close(self):
        for c in self.clients:
            try:
                c.close()
            except Exception:  # noqa: BLE001 - clean-up goes on
                pass
        self.clients = []
        if self.daemon is not None and self.daemon.poll() is None:
            self.daemon.send_signal(signal.SIGTERM)
            try:
                self.daemon.wait(5)
            except subprocess.TimeoutExpired:
                self.daemon.kill()
                self.daemon.wait()
        self.daemon = None
        failed = _test_failed(self.test)
        if failed and os.environ.get("KERF_TEST_KEEP"):
            print(f"kept {self.dir}", file=sys.stderr)
        else:
            shutil.rmtree(self.dir, ignore_errors=True)


def _test_failed(test):
    outcome = getattr(test, "_outcome", None)
    return outcome is not None and not getattr(outcome, "success", True)


class Collector:
    """Reads a SetpointStream on a thread (so that no sample is lost however long the
    test takes) into ``samples``."""

    def __init__(self, stream):
        self.stream = stream
        self.samples = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.is_set():
            got = self.stream.drain()
            if got:
                with self._lock:
                    self.samples.extend(got)
            else:
                time.sleep(0.002)

    def snapshot(self):
        with self._lock:
            return list(self.samples)

    def stop(self):
        self._stop.set()
        self._thread.join()
        self.samples.extend(self.stream.drain())
        return self.samples


def wait_until(what, predicate, timeout_s=PATIENCE_S, poll_s=0.005):
    """Polls ``predicate()`` until it returns a true value (returned); fails after the
    time-out with AssertionError."""
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        last = predicate()
        if last:
            return last
        time.sleep(poll_s)
    raise AssertionError(f"timed out waiting for {what} (last: {last!r})")


def read_csv(path):
    """``kerf sim``'s CSV: the header and the rows as lists of strings."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:] if line]
