"""Starts a real ism-server on 127.0.0.1 for the client and scale-out tests.

The gRPC port is chosen by the server (--listen 127.0.0.1:0, read back from its log line
"listening on ... (port N)"), so tests never race each other for it. The metrics port is
found free first; in the rare case another process takes it in between, the server exits and
start() tries again with another.
"""
import os
import re
import socket
import subprocess
import threading
import time
import urllib.request

SERVER_BIN = os.environ.get("ISM_SERVER_BIN", "")
MODEL_DIR = os.environ.get("ISM_TEST_MODEL_DIR", "")
_LISTENING = re.compile(r"listening on \S+ \(port (\d+)[,)]")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ServerProcess:
    """One ism-server process; `address` is "127.0.0.1:PORT", `log()` its output so far."""

    def __init__(self, model_dir: str = MODEL_DIR, threads: int = 2, extra_args=()):
        if not SERVER_BIN:
            raise RuntimeError("ISM_SERVER_BIN is not set (ctest sets it to the ism-server binary)")
        self.model_dir, self.threads, self.extra_args = model_dir, threads, list(extra_args)
        self.process = None
        self.port = self.metrics_port = None
        self._log = []

    @property
    def address(self) -> str:
        return f"127.0.0.1:{self.port}"

    def log(self) -> str:
        return "".join(self._log)

    def start(self, timeout: float = 30.0, attempts: int = 3):
        for _ in range(attempts):
            if self._start_once(timeout):
                return self
        raise RuntimeError(f"ism-server did not start:\n{self.log()}")

    def _start_once(self, timeout: float) -> bool:
        self.metrics_port = free_port()
        self._log.clear()
        self.process = subprocess.Popen(
            [SERVER_BIN, "--listen", "127.0.0.1:0", "--metrics-listen", f"127.0.0.1:{self.metrics_port}",
             "--models", self.model_dir, "--threads", str(self.threads), *self.extra_args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        found = threading.Event()

        def pump():  # keeps the pipe drained for the server's whole life
            for line in self.process.stdout:
                self._log.append(line)
                match = _LISTENING.search(line)
                if match and not found.is_set():
                    self.port = int(match.group(1))
                    found.set()

        self._pump = threading.Thread(target=pump, daemon=True)
        self._pump.start()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.process.poll() is None:
            if found.wait(0.05):
                return True
        self.stop()
        return False

    def metrics(self) -> str:
        with urllib.request.urlopen(f"http://127.0.0.1:{self.metrics_port}/metrics", timeout=5) as r:
            return r.read().decode()

    def requests_served(self, rpc: str) -> float:
        """ism_requests_total for `rpc`, summed over status codes."""
        total = 0.0
        for line in self.metrics().splitlines():
            if line.startswith("ism_requests_total{") and f'rpc="{rpc}"' in line:
                total += float(line.rsplit(" ", 1)[1])
        return total

    def kill(self):
        """SIGKILL: the replica vanishes without draining, as a crashed pod would."""
        self.process.kill()
        self.process.wait(10)
        self._close_pipe()

    def _close_pipe(self):
        self._pump.join(5)  # ends at EOF, once the process is gone
        self.process.stdout.close()

    def stop(self):
        if self.process and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(5)
        if self.process and not self.process.stdout.closed:
            self._close_pipe()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
