"""Smoke test of ``bench_warm_start.py --novel``: on a path the library does not hold, moving
at t = 0, the warm start does no harm against the model-only input (issue 9), neither over
the whole path nor past its start, which every input misses and which hid a 50x loss."""

from __future__ import annotations

import warnings

import numpy as np
from bench_import import benchmark_modules

from primlib.plant import Machine


def test_a_novel_path_is_warm_started_no_worse_than_by_the_model_alone():
    with benchmark_modules("bench_warm_start") as (w,):
        nominal = Machine.from_json(w.ROOT / "data" / "machines" / "xyz.json")
        true = w.true_machine(nominal, None)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lib, _ = w.learned_library(nominal, true)
            out = w.novel_rows(lib, nominal, true, 1)
    for label, r in out.items():
        # the stored inputs are learned on the machine; the refined model is its family, so
        # the model-only input is near the machine's own floor and the library can at best
        # tie it: 10 % is the "never does harm"
        assert r["warm"][0] <= 1.1 * r["model-only"][0], label
        assert r["warm after"][0] <= 1.1 * r["model-only after"][0], label
        # and both far below the nominal inverse (the model refined on the library's pairs)
        assert r["model-only"][0] < 0.01 * r["nominal"][0], label
        assert np.isfinite(r["refined"][0])
