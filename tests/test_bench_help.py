"""Every benchmark script answers ``--help`` with its usage (argparse formats each help text
with %: a bare % in one made ``bench_match_real.py --help`` print a traceback)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
SCRIPTS = sorted(p.name for p in BENCH.glob("bench_*.py"))


def test_there_are_benchmark_scripts():
    assert "bench_match_real.py" in SCRIPTS and len(SCRIPTS) >= 10


@pytest.mark.parametrize("script", SCRIPTS)
def test_help_prints_the_usage(script):
    run = subprocess.run([sys.executable, str(BENCH / script), "--help"], capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.startswith("usage:") and run.stderr == ""


def test_a_baseline_git_cannot_give_stops_with_one_sentence_and_status_2(tmp_path):
    # a revision that does not exist (or a snapshot that is no checkout): no traceback
    run = subprocess.run([sys.executable, str(BENCH / "bench_match_novel.py"), "--paths", "1",
                          "--baseline", "no-such-revision"], capture_output=True, text=True,
                         timeout=120)  # fmt: skip
    assert run.returncode == 2
    assert "baseline 'no-such-revision': cannot extract it from" in run.stderr
    assert "--no-baseline" in run.stderr and "Traceback" not in run.stderr
