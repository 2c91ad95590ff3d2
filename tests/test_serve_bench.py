"""Smoke run of benchmarks/bench_serve.py: a short load on a small library must pass its
own checks (no failed request, every acknowledged ingest kept, HTTP == in-process)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from serve_helpers import ROOT


@pytest.mark.slow
def test_bench_serve_smoke():
    cmd = [sys.executable, str(ROOT / "benchmarks" / "bench_serve.py"), "--duration", "3",
           "--primitives", "6", "--clients", "2", "--samples", "400", "--repeat", "1"]  # fmt: skip
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[-1] == "OK"
    assert any(ln.startswith("warm start over HTTP p99 [s]") for ln in lines)
    failed = [ln for ln in lines if ln.startswith("failed requests")]
    assert failed and failed[0].split()[-1] == "0"
