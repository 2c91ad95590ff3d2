"""BankIndex: primitives that cannot be matched are skipped with the reason, so one bad
stored primitive cannot break matching against the others."""

import numpy as np
import pytest
from test_match_segment import DT, _compose, _library

from primlib import NoMatchError
from primlib.match import BankIndex, segment_path
from primlib.store import Bank


def _with(bad: np.ndarray):
    good = _library(4, 300, seed=2)
    pieces = [good.points_of(i) for i in range(good.k)]
    bank = Bank.from_samples([pieces[0], bad, *pieces[1:]], DT, ids=[10, 11, 12, 13, 14])
    return good, BankIndex(bank)


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        (1e308, "coordinates beyond 1e+09 (largest magnitude 1e+308)"),
        (1e50, "coordinates beyond 1e+09 (largest magnitude 1e+50)"),
        (np.inf, "non-finite coordinates (nan or inf)"),
        (np.nan, "non-finite coordinates (nan or inf)"),
    ],
)
def test_a_stored_primitive_with_huge_values_is_skipped_and_the_others_still_match(value, reason):
    bad = _library(4, 300, seed=2).points_of(1).copy()
    bad[100, 1] = value
    good, index = _with(bad)
    assert index.skipped == {11: reason}
    assert index.k == 4 and list(index.ids) == [10, 12, 13, 14]
    pts, _ = _compose(good, [(2, 0.1, 0.5, 1.0)], seed=4)
    with np.errstate(all="raise"):  # no overflow anywhere
        segs, info = segment_path(index, pts, DT, 0.05)
    assert [s.primitive for s in segs] == [13] and info["skipped"] == 1


def test_a_bank_of_only_bad_primitives_says_why_nothing_can_match():
    bank = Bank.from_samples([np.full((50, 3), 1e300), np.ones((1, 3))], DT, machine="xyz")
    index = BankIndex(bank)
    assert index.skipped == {
        0: "coordinates beyond 1e+09 (largest magnitude 1e+300)",
        1: "1 sample(s), 2 needed",
    }
    with pytest.raises(NoMatchError, match=r"machine 'xyz': no usable primitive, nothing to "
                       r"match against \(2 skipped; #0: coordinates beyond 1e\+09"):  # fmt: skip
        segment_path(index, np.random.default_rng(0).normal(size=(20, 3)), DT, 0.1)


def test_the_index_is_built_once_and_kept_on_the_bank_index():
    index = _library(3, 300, seed=1)
    pts, _ = _compose(index, [(1, 0.1, 0.5, 1.0)], seed=2)
    segs, info = segment_path(index, pts, DT, 0.05)
    arc = index.arc_index()
    assert info["index_seconds"] > 0
    segs2, info2 = segment_path(index, pts, DT, 0.05)
    assert index.arc_index() is arc and info2["index_seconds"] == 0.0
    assert [(s.end, s.primitive) for s in segs] == [(s.end, s.primitive) for s in segs2]
