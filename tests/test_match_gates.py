"""Which windows of an index query can hold a stored copy (``_gates.Gates``)."""

import numpy as np

from primlib.match import BankIndex
from primlib.match._gates import Gates
from primlib.match._index_search import IndexSearch
from primlib.match._options import PathPiece, SearchOptions
from primlib.store import Bank


def _query():
    t = np.linspace(0, 1, 1500)[:, None]
    helix = np.hstack([np.cos(6 * t), np.sin(6 * t), t]) * 40
    line = np.hstack([t, 2 * t, -t]) * 60
    bank = BankIndex(Bank.from_samples([helix, line], 0.01))
    path = PathPiece(helix[200:900].copy(), 7.0)
    return IndexSearch(bank, SearchOptions()).arc_query(path, 0.0, 1.0, 0.05)


def test_valid_windows_and_over_are_those_with_the_arc_the_piece_needs_left():
    # valid: inside the primitive; over: running past its last point (test_match_ends)
    aq = _query()
    gates = Gates.of(aq, 0.05)
    left = np.asarray(aq.level.left)[: aq.n_windows]
    valid = gates.valid((0, aq.n_windows))
    valid[gates.over[gates.over < aq.n_windows]] = True
    np.testing.assert_array_equal(valid, left >= gates.need)
    some = np.arange(0, aq.n_windows, 7)
    got = gates.valid(some) | np.isin(some, gates.over)
    np.testing.assert_array_equal(got, left[some] >= gates.need)
    # a piece fits at a primitive's start, not at its last point
    end = int(aq.level.start[1]) - 1
    assert gates.valid((0, 1))[0] and not gates.valid(np.array([end]))[0]


def test_valid_hands_out_an_array_of_its_own():
    # the search narrows what valid returns in place (ok &= ...): that must not change the
    # next answer
    aq = _query()
    gates = Gates.of(aq, 0.05)
    ok = gates.valid((0, aq.n_windows))
    before = ok.copy()
    ok &= False
    np.testing.assert_array_equal(gates.valid((0, aq.n_windows)), before)
