"""The paper's published numbers (arXiv 2508.06538), as data to compare against.

``PAPER_TABLE2[experiment][horizon][component] = (mean, std)``: the signed
prediction error predicted - true over the test split, as printed in Table 2
(joint angles in rad, CoM position in m, CoM orientation in rad). The paper's
columns ``fl hz``/``rr hz`` are the knees, ``fl_kn``/``rr_kn`` here.
Experiments: ``go1_sim`` (SIM Go1, pronk), ``a1_sim`` (SIM A1, froggy) and
``go1_proxy``, our stand-in for the paper's Real Go1 row.

``PAPER_ASLIP[component] = {"learned": ..., "aslip": ...}``: the full-horizon
mean absolute CoM error (m) of the learned 2-D Go1 model and of the aSLIP
baseline (Results, Go1 simulation).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from symrom.names import TABLE2_COMPONENTS

_COLUMNS = TABLE2_COMPONENTS  # fl_hx fl_hy fl_kn rr_hx rr_hy rr_kn x y z roll pitch yaw


def _row(*pairs: tuple[float, float]) -> dict[str, tuple[float, float]]:
    assert len(pairs) == len(_COLUMNS)
    return dict(zip(_COLUMNS, pairs))


PAPER_TABLE2: dict[str, dict[str, dict[str, tuple[float, float]]]] = {
    "go1_sim": {
        "full": _row((1.3e-2, 1.5e-2), (-8.0e-2, 0.11), (7.5e-2, 0.18),
                     (2.3e-2, 7.6e-2), (-5.4e-2, 0.13), (3.7e-2, 0.22),
                     (-2.2e-2, 5.0e-2), (4.4e-3, 1.3e-3), (4.1e-2, 5.0e-2),
                     (-9.8e-3, 1.8e-3), (3.0e-2, 6.4e-2), (-1.5e-4, 8.1e-4)),
        "0.1": _row((5.0e-3, 7.6e-3), (-4.1e-3, 9.4e-2), (-2.1e-2, 0.17),
                    (4.4e-3, 8.5e-2), (-5.4e-3, 0.11), (-2.5e-2, 0.21),
                    (8.9e-3, 4.6e-3), (4.3e-3, 1.3e-3), (5.4e-4, 9.4e-3),
                    (-9.3e-3, 2.6e-3), (3.8e-2, 6.1e-2), (-1.5e-4, 8.1e-4)),
    },
    "a1_sim": {
        "full": _row((1.0e-10, 1.1e-10), (0.19, 0.16), (-0.30, 0.34),
                     (1.0e-10, 1.1e-10), (0.26, 0.20), (-0.32, 0.36),
                     (-3.5e-2, 5.1e-2), (-8.0e-3, 1.5e-3), (-6.1e-2, 5.8e-2),
                     (2.4e-3, 4.7e-3), (0.10, 8.3e-2), (-8.7e-4, 3.6e-3)),
        "0.1": _row((1.0e-10, 2.6e-10), (2.8e-3, 3.9e-2), (-3.0e-2, 0.16),
                    (1.0e-10, 2.6e-10), (1.4e-2, 5.2e-2), (-3.9e-2, 0.23),
                    (-7.9e-3, 1.2e-3), (-8.0e-3, 1.5e-3), (-2.9e-3, 2.0e-3),
                    (2.4e-3, 4.7e-3), (9.8e-3, 5.6e-2), (-8.7e-4, 3.6e-3)),
    },
    "go1_proxy": {
        "full": _row((-3.7e-2, 2.6e-2), (0.22, 0.15), (-0.35, 0.39),
                     (-4.2e-2, 4.7e-2), (0.34, 0.18), (-0.65, 0.49),
                     (7.5e-2, 7.0e-2), (-9.6e-4, 9.6e-3), (-8.1e-2, 7.7e-2),
                     (3.3e-2, 2.2e-2), (-0.14, 9.2e-2), (0.1, 7.8e-2)),
        "0.1": _row((-4.6e-3, 2.3e-2), (1.7e-2, 8.3e-2), (3.8e-2, 0.19),
                    (-7.5e-2, 5.1e-2), (0.12, 5.6e-2), (-0.21, 0.17),
                    (1.2e-3, 3.1e-3), (-7.1e-3, 5.4e-3), (1.2e-3, 3.4e-3),
                    (2.9e-2, 1.9e-2), (-0.10, 5.9e-2), (0.12, 8.9e-2)),
    },
}

# Row labels of Table 2 and the motion each row is about.
PAPER_LABELS: dict[str, str] = {
    "go1_sim": "SIM Go1 (pronk)",
    "a1_sim": "SIM A1 (froggy)",
    "go1_proxy": "Real Go1 (pronk); ours: a hardware-like proxy",
}

PAPER_ASLIP: dict[str, dict[str, float]] = {
    "x": {"learned": 1.6e-2, "aslip": 5.7e-2},
    "z": {"learned": 4.0e-2, "aslip": 9.5e-2},
}

# The trade-off analysis (Fig. "trade-off"): L_mod = 2 E_dec + 2 lambda log|Xi|.
PAPER_LAMBDA = 1e-3
PAPER_BEST_DIMS = (4, 6)  # "optimal performance with 4-6 latent dimensions"


def implied_rmse(mean: float, std: float) -> float:
    """RMSE of a signed error with the given mean and (population) std: sqrt(mean^2 + std^2)."""
    return math.sqrt(mean * mean + std * std)


def paper_row(experiment: str, horizon: str) -> dict[str, tuple[float, float]] | None:
    """The paper's (mean, std) per component for ``experiment`` at ``horizon``, or None."""
    return PAPER_TABLE2.get(experiment, {}).get(horizon)


def paper_rmse(experiment: str, horizon: str) -> dict[str, float] | None:
    """The paper's implied RMSE per Table 2 component for ``experiment`` at ``horizon``, or None."""
    row = paper_row(experiment, horizon)
    return None if row is None else {c: implied_rmse(*row[c]) for c in TABLE2_COMPONENTS}


def at_or_below_paper(experiment: str, horizon: str, rmse: Mapping[str, float | None]) -> list[str] | None:
    """The Table 2 components (in Table 2's order) whose ``rmse`` (per component, in its unit;
    None or absent: not scored) is at or below the paper's implied RMSE at ``horizon``; None when
    the paper has no such row."""
    ref = paper_rmse(experiment, horizon)
    if ref is None:
        return None
    return [c for c in TABLE2_COMPONENTS if rmse.get(c) is not None and rmse[c] <= ref[c]]
