"""The flight polish's weight benchmark (``benchmarks/polish_weight.py``) on a small planted case.

Its logged accelerations lag the motion (a causal filter), so the exact fit's flight equations
read the lag as negative damping; the benchmark's polish (the flight phase refined again alone on
rollouts) must repair them, keep the support and the other phases, and its choice of weight must
be the variant val puts furthest under the yardstick. The committed record of the real run is
checked for its provenance in tests/test_benchmark_records.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from symrom.experiments.select import SelectionConfig
from symrom.learn.training import TrainConfig, train
from symrom.testing import make_lagged_dataset

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import polish_weight as bench  # noqa: E402

sys.path.pop(0)

@pytest.fixture(scope="module")
def lagged_model():
    ds, _ = make_lagged_dataset(10, 400)  # accelerations lagging by 20 ms
    return ds, train(ds, TrainConfig(latent_dim=2, poly_order=1))


def _row(name, w, model, ds):
    return bench.score_variant(name, w, model, ds, SelectionConfig().yardstick(ds), 2, 0.0)


def test_the_polish_repairs_the_flight_alone_and_the_best_weight_is_chosen(lagged_model):
    ds, exact = lagged_model
    flight = exact.phase_names.index("flight")
    rows = [_row("exact", None, exact, ds)]
    for w in (1.0, 100.0):
        polished = bench.polish_alone(exact, ds, w)
        np.testing.assert_array_equal(polished.mask, exact.mask)  # the support: the budget holds
        for k in range(len(exact.phase_names)):  # the other phases as they were
            if k != flight:
                np.testing.assert_array_equal(polished.Xi[k], exact.Xi[k])
        assert not np.array_equal(polished.Xi[flight], exact.Xi[flight])
        rows.append(_row(f"flight polished, weight {w:g}", w, polished, ds))
    ratio = {r["polish_weight"]: bench.worst_ratio(r) for r in rows}
    assert min(ratio[1.0], ratio[100.0]) < ratio[None]  # the polish makes val better than the exact fit
    best = bench.best_weight(rows)
    assert best in (1.0, 100.0) and ratio[best] == min(ratio.values())


def test_best_weight_ranks_a_diverged_variant_last_and_breaks_ties_to_the_smaller_weight():
    def row(w, full, short):
        return {"polish_weight": w, "horizons": {"full": {"worst": full}, "0.1": {"worst": short}}}

    rows = [row(None, 1.2, 0.9), row(1.0, 0.8, 0.95), row(10.0, None, 0.1), row(100.0, 0.9, 0.7)]
    assert bench.worst_ratio(rows[2]) == float("inf")  # diverged at the full horizon: last
    assert bench.best_weight(rows) == 100.0  # worst 0.9 against 0.95 and 1.2
    rows[1]["horizons"]["0.1"]["worst"] = 0.9  # a tie at 0.9: the smaller weight
    assert bench.best_weight(rows) == 1.0
    assert bench.best_weight([row(100.0, 0.5, 0.5), row(None, 0.5, 0.5)]) is None  # no gain: no polish
