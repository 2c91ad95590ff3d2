"""Smoke tests of ``primlib reproduce pdccilc`` (few iterations; the full study is the CLI's)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib._errors import InputError
from primlib.cli import main
from primlib.plant import Machine
from primlib.reproduce import pdccilc_study
from primlib.reproduce._pdccilc import CONTOURS, contour_reference, paper_machine

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"


def test_paper_machine_is_the_bundled_one():
    assert (
        paper_machine().to_dict()["plants"]
        == Machine.from_json(DATA / "xy-pdccilc.json").to_dict()["plants"]
    )
    assert paper_machine().feedback == Machine.from_json(DATA / "xy-pdccilc.json").feedback


@pytest.mark.parametrize("name", CONTOURS)
def test_contours_start_at_the_origin_on_the_paper_grid(name):
    r = contour_reference(name)
    assert r.shape == (2401, 2)
    np.testing.assert_allclose(r[0], 0.0, atol=1e-12)
    assert np.max(np.ptp(r, axis=0)) >= 10.0


def test_master_rests_and_reverses_where_the_position_domain_must_cope():
    semi = contour_reference("semicircle")
    assert abs(semi[1, 0] - semi[0, 0]) < 1e-4 and abs(semi[-1, 0] - semi[-2, 0]) < 1e-4
    spiral = contour_reference("spiral")
    assert np.count_nonzero(np.diff(np.sign(np.diff(spiral[:, 0])))) >= 4
    with pytest.raises(InputError, match=r"contour: expected one of semicircle, parabola, spiral"):
        contour_reference("circle")


def test_study_with_few_iterations_learns_and_checks_convergence():
    study = pdccilc_study(iterations=3, contours=("semicircle",), laws=("tdilc", "pdccilc"))
    rms = study.rms_contour["semicircle"]
    assert set(rms) == {"TDILC", "PDCCILC"} and rms["PDCCILC"].shape == (4,)
    assert rms["PDCCILC"][-1] < rms["PDCCILC"][0]
    conv = study.convergence["semicircle"]["PDCCILC"]
    assert conv["spectral_radius_exact"] is False  # Q-filter: a certified bound
    assert 0 < conv["spectral_radius"] <= conv["max_singular_value"] * (1 + 1e-9)
    assert 0 < conv["asymptotic_rms_contour"] < rms["PDCCILC"][0]
    doc = json.loads(json.dumps(study.to_json()))
    assert doc["contours"]["semicircle"]["TDILC"]["rms_contour"] == pytest.approx(
        list(rms["TDILC"])
    )
    with pytest.raises(InputError, match=r"iterations: expected an integer >= 1, got 0"):
        pdccilc_study(iterations=0)


def test_cli_json_and_plots(tmp_path):
    runner = CliRunner()
    result = runner.invoke(
        main,
        [
            "reproduce",
            "pdccilc",
            "--iterations",
            "2",
            "--no-convergence",
            "--json",
            "--plot",
            str(tmp_path / "figs"),
        ],
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert set(doc["contours"]) == set(CONTOURS)
    for contour in CONTOURS:
        laws = doc["contours"][contour]
        assert set(laws) == {"TDILC", "TDCCILC", "PDILC", "PDCCILC"}
        assert all(len(v["rms_contour"]) == 3 for v in laws.values())
        # the coupled laws act on the contour error at once
        assert laws["PDCCILC"]["rms_contour"][2] < laws["PDCCILC"]["rms_contour"][0]
    pngs = sorted(p.name for p in (tmp_path / "figs").iterdir())
    assert pngs == sorted(f"pdccilc-{c}-{k}.png" for c in CONTOURS for k in ("rms", "steady"))
    assert all((tmp_path / "figs" / p).stat().st_size > 10_000 for p in pngs)


def test_cli_table_and_bad_option():
    runner = CliRunner()
    result = runner.invoke(main, ["reproduce", "pdccilc", "--iterations", "1", "--no-convergence"])
    assert result.exit_code == 0, result.output
    assert "paper: PDCCILC best, 93 % reduction" in result.output
    raw = runner.invoke(
        main,
        ["reproduce", "pdccilc", "--iterations", "1", "--no-convergence", "--no-q-filter"]
        + ["--json"],
    )
    assert raw.exit_code == 0, raw.output
    assert json.loads(raw.stdout)["settings"]["q_cutoff_hz"] is None
    bad = runner.invoke(main, ["reproduce", "pdccilc", "--iterations", "0"])
    assert bad.exit_code == 2
    assert "--iterations" in bad.output


def test_reproduce_pdccilc_prints_progress_on_stderr():
    # 12 cases of about a second each: the user sees them counted, stdout stays JSON
    result = CliRunner().invoke(
        main, ["reproduce", "pdccilc", "--iterations", "1", "--no-convergence", "--json"]
    )
    assert result.exit_code == 0, result.output
    lines = result.stderr.splitlines()
    assert lines == [f"pdccilc cases (contour x law): {k}/12" for k in range(1, 13)]
    json.loads(result.stdout)


def test_study_reports_progress_per_case():
    calls = []
    pdccilc_study(
        iterations=1,
        contours=("semicircle", "spiral"),
        laws=("tdilc",),
        convergence=False,
        progress=lambda done, total: calls.append((done, total)),
    )
    assert calls == [(1, 2), (2, 2)]
