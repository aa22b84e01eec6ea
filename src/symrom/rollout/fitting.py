"""Fitting a few parameters of a model to its rollout error (multiple shooting).

For baselines with a handful of physical parameters (the aSLIP's spring), the
trajectory, not the acceleration residual, is what a reduced-order model is
judged on. ``fit_to_rollouts`` minimises the squared error of the predicted
components over the given jumps, rolled out with resets every ``L`` s: with a
reset period L the rollout is multiple shooting over windows of length L, each
starting from the true state. The windows grow stage by stage (e.g. 0.1 s,
0.3 s, then the whole jump), each stage starting from the previous optimum, so
a poor first guess never has to survive a whole jump. SciPy's
``least_squares`` (trust-region reflective, bounds allowed) does each stage
with a finite-difference Jacobian.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from symrom.data.dataset import Dataset
from symrom.names import Q_NAMES
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.rollout.system import Rollable

# A diverged sample's residual, in units of the component's spread: large enough
# that a step into divergence is never taken, finite so the solver can go on.
DIVERGED_RESIDUAL = 10.0


@dataclass
class RolloutFit:
    """theta: the fitted parameters; stages: per reset period (None = whole jump) the
    cost (half the sum of squared normalised residuals) before and after, the
    solver's evaluations and its status message."""

    theta: np.ndarray
    stages: list[dict]


def rollout_residuals(model: Rollable, ds: Dataset, jumps: np.ndarray, reset: float | None,
                      spread: np.ndarray, stride: int = 1, substeps: int = 2) -> np.ndarray:
    """Normalised errors (predicted - true) / spread of the model's components over
    ``jumps``, every ``stride``-th sample; diverged samples count ``DIVERGED_RESIDUAL``."""
    ro = rollout(model, ds, jumps, RolloutOptions("rk4", reset=reset, substeps=substeps))
    cols = [Q_NAMES.index(c) for c in ro.components]
    bounds = ds.jump_bounds()
    out = []
    for i, j in enumerate(jumps):
        err = (ro.q_pred[i] - ds.q[slice(*bounds[j])][:, cols])[::stride] / spread
        out.append(np.where(np.isfinite(err), err, DIVERGED_RESIDUAL).ravel())
    return np.concatenate(out)


def fit_to_rollouts(make: Callable[[np.ndarray], Rollable], theta0: np.ndarray, ds: Dataset,
                    jumps: np.ndarray, bounds: tuple[Sequence[float], Sequence[float]],
                    resets: Sequence[float | None] = (0.1, 0.3, None), stride: int = 2,
                    x_scale: np.ndarray | None = None) -> RolloutFit:
    """Parameters minimising the rollout error of ``make(theta)`` over ``jumps`` of ``ds``.

    theta0 (k,) start; bounds: (lower, upper) per parameter; resets: the
    multiple-shooting stages, shortest first; stride: use every stride-th sample.
    """
    from scipy.optimize import least_squares  # here: scipy.optimize is slow to import

    comps = tuple(make(np.asarray(theta0, float)).components)
    cols = [Q_NAMES.index(c) for c in comps]
    rows = np.isin(ds.jump, jumps)
    spread = np.maximum(ds.q[rows][:, cols].std(axis=0), 1e-6)
    theta = np.asarray(theta0, dtype=float)
    stages = []
    for reset in resets:
        def fun(th, reset=reset):
            return rollout_residuals(make(th), ds, jumps, reset, spread, stride)

        before = 0.5 * float(np.sum(fun(theta) ** 2))
        sol = least_squares(fun, theta, bounds=bounds, x_scale=x_scale if x_scale is not None else 1.0,
                            diff_step=1e-4, xtol=1e-10, ftol=1e-10, max_nfev=60)
        theta = sol.x
        stages.append({"reset_s": reset, "cost_before": before, "cost_after": float(sol.cost),
                       "evaluations": int(sol.nfev), "message": str(sol.message)})
    return RolloutFit(theta, stages)
