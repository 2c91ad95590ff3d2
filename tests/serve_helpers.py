"""A real ``primlib serve`` process for the tests: a free loopback port, a log file, stop."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """``python -m primlib serve --db DB --port P ARGS`` as a child process."""

    def __init__(self, db: Path, *args: str, log: Path | None = None) -> None:
        self.db = Path(db)
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log = log or self.db.with_suffix(f".{self.port}.log")
        env = dict(
            os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
        )
        cmd = [sys.executable, "-m", "primlib", "serve", "--db", str(db), "--port", str(self.port)]
        self._fh = open(self.log, "wb")
        self.proc = subprocess.Popen(
            [*cmd, *args], stdout=self._fh, stderr=subprocess.STDOUT, env=env
        )
        self.wait_ready()

    def wait_ready(self, timeout: float = 120.0) -> None:
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited {self.proc.returncode}: {self.log.read_text()}")
            try:
                with urllib.request.urlopen(self.url + "/health", timeout=5) as r:
                    if r.status == 200:
                        return
            except (urllib.error.URLError, OSError):
                time.sleep(0.2)
        self.stop()
        raise RuntimeError(f"server not ready after {timeout} s: {self.log.read_text()}")

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 120.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            rc = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            rc = self.proc.wait()
        self._fh.close()
        return rc

    def call(self, method: str, path: str, body=None, token: str | None = None,
             content_type: str = "application/json", accept: str = "application/json",
             raw: bytes | None = None) -> tuple[int, object, dict]:  # fmt: skip
        """(status, decoded body, headers); the body is JSON-decoded when it is JSON."""
        data = raw
        if body is not None:
            data = body.encode() if isinstance(body, str) else json.dumps(body).encode()
        headers = {"Content-Type": content_type, "Accept": accept}
        if token is not None:
            headers["Authorization"] = f"Bearer {token}"
        req = urllib.request.Request(self.url + path, data=data, headers=headers, method=method)
        try:
            with urllib.request.urlopen(req, timeout=300) as r:
                status, text, hdrs = r.status, r.read(), dict(r.headers)
        except urllib.error.HTTPError as exc:
            status, text, hdrs = exc.code, exc.read(), dict(exc.headers)
        kind = hdrs.get("content-type", "")
        return status, json.loads(text) if "json" in kind else text.decode(), hdrs


def machine_dict() -> dict:
    return json.loads((DATA / "machines" / "xyz.json").read_text())


def stored(stem: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, points, signal) of one of data/library's primitives."""
    from primlib.io import read_path_csv, read_signal_csv

    t, p = read_path_csv(DATA / "library" / f"{stem}.csv")
    _, u = read_signal_csv(DATA / "library" / f"{stem}.signal.csv")
    return t, p, u


def moved(points: np.ndarray, degrees: float = 30.0, shift=(5.0, -3.0, 1.0)) -> np.ndarray:
    """Points rotated about z and translated: a new path the matcher finds in the library."""
    a = np.radians(degrees)
    r = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return points @ r.T + np.asarray(shift)
