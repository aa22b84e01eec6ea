"""Shared fixtures: planted datasets made once per test session."""

from __future__ import annotations

import numpy as np
import pytest

from symrom.testing import make_planted_dataset


@pytest.fixture(scope="session")
def planted_axis():
    """Axis-aligned embedding: the exact solver must recover the planted equations."""
    return make_planted_dataset(n_jumps=24, n_samples=400, embedding="axis", noise=1e-4, seed=1)


@pytest.fixture(scope="session")
def planted_block():
    """Every configuration component driven by a latent: rollouts are checked on all 18."""
    return make_planted_dataset(n_jumps=20, n_samples=400, embedding="block", noise=1e-4, seed=2)


def normalised_mae(metrics: dict, ds, split: str = "test") -> dict[str, np.ndarray]:
    """Per horizon: MAE / spread of each component over the split (18,)."""
    spread = np.ptp(ds.q[ds.rows_of(split)], axis=0)
    return {h: np.array([v["components"][n]["mae"] for n in v["components"]]) / spread
            for h, v in metrics["horizons"].items()}


def one_line_error(result, *needles: str) -> str:
    """Assert a CLI run failed with exactly one line of output, no traceback, naming
    every ``needle``; return that line."""
    out = result.output
    assert result.exit_code != 0, out
    assert "Traceback" not in out
    lines = [line for line in out.splitlines() if line.strip()]
    assert len(lines) == 1, out
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]
