import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib import InputError
from primlib.cli import main
from primlib.plant import Machine
from primlib.reproduce._cee_mfac import PAPER_TABLE2, cee_mfac_study, linear_motor

JSON = Path(__file__).resolve().parents[1] / "data" / "machines" / "linear-motor.json"


def test_study_machine_is_the_data_file():
    m = Machine.from_json(JSON)
    assert linear_motor().motors == m.motors
    assert linear_motor().dt == m.dt and linear_motor().substeps == m.substeps


def test_cli_json_smoke(tmp_path):
    res = CliRunner().invoke(
        main, ["reproduce", "cee-mfac", "--json", "--duration", "0.4", "--plot", str(tmp_path)]
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    for case in ("C1", "C2", "C3", "C4"):
        m = out[case]
        assert 0 < m["e_mad"] <= m["e_max"] < 200.0  # µm, bounded over the start transient
        assert np.isfinite(m["e_max_estimated"])
    assert out["paper"] == PAPER_TABLE2
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["cee-fig4-contour.png", "cee-fig5-tip.png", "cee-fig6-error.png"]
    assert all((tmp_path / n).stat().st_size > 1000 for n in names)


def test_cli_table_and_bad_input():
    res = CliRunner().invoke(main, ["reproduce", "cee-mfac", "--duration", "0.1"])
    assert res.exit_code == 0, res.output
    assert "C3" in res.stdout and "paper e_max" in res.stdout
    res = CliRunner().invoke(main, ["reproduce", "cee-mfac", "--duration", "-1"])
    assert res.exit_code == 2


def test_exact_estimator_in_the_loop_is_the_true_error():
    st = cee_mfac_study(duration=0.3, cases=("C3", "C4"))
    for case in ("C3", "C4"):
        np.testing.assert_allclose(st.runs[case].estimate, st.true_error[case], atol=1e-12)


def test_study_bad_input():
    with pytest.raises(InputError, match="cases: expected among C1, C2, C3, C4, got 'C5'"):
        cee_mfac_study(cases=("C5",))
    with pytest.raises(InputError, match="duration: expected more than two samples"):
        cee_mfac_study(duration=0.001)
    with pytest.raises(InputError, match="ccc_gain: expected a number >= 0"):
        cee_mfac_study(duration=0.1, ccc_gain=-1.0)


@pytest.mark.slow
def test_cli_sweep_smoke(tmp_path):
    # issue 12: a sweep over feed speed, where the estimators part; progress on stderr
    res = CliRunner().invoke(
        main,
        [
            "reproduce", "cee-mfac", "--sweep", "--speeds", "12,20", "--revolutions", "1.5",
            "--json", "--plot", str(tmp_path),
        ],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["feed_mm_per_s"] == [120.0, 200.0]
    for name in ("linear", "circular", "exact"):
        m = out[name]
        assert all(0 < a <= b for a, b in zip(m["e_mad"], m["e_max"], strict=True))
        assert all(lag > 50.0 for lag in m["lag"])  # µm: the loop lags at these feeds
    # the estimators' own errors: exact none, circular below linear, linear ~ kappa a^2 / 2
    assert max(out["exact"]["estimate_error_max"]) < 1e-9
    lin, circ = out["linear"]["estimate_error_max"], out["circular"]["estimate_error_max"]
    assert circ[1] < lin[1] and lin[0] < lin[1]
    assert "cee-mfac sweep runs (speed x estimator): 6/6" in res.stderr
    assert (tmp_path / "cee-sweep.png").stat().st_size > 1000


def test_cli_sweep_options_are_checked():
    for args, msg in (
        (["--sweep", "--duration", "1"], "--duration: not used with --sweep"),
        (["--speeds", "1,2"], "--speeds: only used with --sweep"),
        (["--sweep", "--speeds", "1,-2"], "expected positive rates"),
    ):
        res = CliRunner().invoke(main, ["reproduce", "cee-mfac", *args])
        assert res.exit_code == 2 and msg in res.output, res.output
