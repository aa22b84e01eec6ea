"""Rollout-aware refinement: coefficients fitted to the simulation error.

Least squares on accelerations (STLSQ) asks each sample's acceleration to be
right; a rollout asks the integrated path to stay right, and small biases in
the first (a phase-lagged filter, feedback hidden in the logged inputs) can
make the second diverge. ``Refine`` starts from another regressor's
coefficients and support (``initial``, STLSQ by default) and then fits the
active coefficients of all phases together to the latent rollout error over
the training jumps, by multiple shooting:

- the jumps are cut into windows of ``windows[0]`` s, each rolled out from its
  true encoded state with the logged inputs and phases held over each sample
  (``symrom.model.shooting``, RK4 with exact sensitivities);
- the residual is the error of xi (divided by each latent's spread over the
  training rows) and, weighted by ``velocity_weight``, of dxi, at every sample;
  plus the windows of the shortest length at every stage, so short-horizon
  accuracy is kept while the horizon grows;
- SciPy's trust-region least squares minimises it; then the windows grow
  (``windows``: 0.05 s, 0.1 s, 0.2 s, 0.4 s, 0.8 s, then the whole jump) and
  each stage starts from the last optimum. A window that leaves the bound
  counts as a large constant error from there on; a stage that ends with a
  higher cost, or with windows outside the bound, keeps the previous result
  and ends the schedule.

The support never changes: refinement moves the coefficients STLSQ chose,
never adds terms. ``max_jumps`` caps the training jumps used (evenly spaced).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from symrom.model.regressors.base import Coefficients, RegressionProblem, Regressor
from symrom.model.regressors.stlsq import STLSQ
from symrom.model.shooting import Parameters, Windows, cut_windows, simulate

# A sample after its window left the bound counts this many times the bound (in
# units of the spread): more than any sample still inside, so leaving is never a
# way to lower the cost, and finite, so the solver can go on.
DIVERGED_FACTOR = 2.0


@dataclass(frozen=True)
class Refine(Regressor):
    """initial: the regressor giving the start and the support; windows: the
    multiple-shooting schedule, s (None = whole jumps); velocity_weight: weight of
    the dxi error against the xi error; max_jumps: training jumps used at most;
    max_nfev: solver evaluations per stage; bound: divergence bound in units of
    the largest |xi|, |dxi| of the training jumps; substeps: RK4 steps per sample;
    stride: score every stride-th sample of a window."""

    initial: Regressor = field(default_factory=STLSQ)
    windows: tuple[float | None, ...] = (0.05, 0.1, 0.2, 0.4, 0.8, None)
    velocity_weight: float = 0.1
    max_jumps: int = 30
    max_nfev: int = 15
    bound: float = 5.0
    substeps: int = 1
    stride: int = 4

    needs_trajectories = True

    def __post_init__(self) -> None:
        if not self.velocity_weight > 0:
            raise ValueError(f"velocity_weight must be > 0, got {self.velocity_weight}")
        if not self.windows:
            raise ValueError("refinement needs at least one window length")

    @property
    def collinearity(self) -> float | None:  # the support is the initial regressor's
        return None

    def to_dict(self) -> dict[str, Any]:
        return {"name": "Refine", "initial": self.initial.to_dict(), "windows": list(self.windows),
                "velocity_weight": self.velocity_weight, "max_jumps": self.max_jumps,
                "max_nfev": self.max_nfev, "bound": self.bound, "substeps": self.substeps,
                "stride": self.stride}

    def _reduce(self, problem: RegressionProblem, allowed: np.ndarray,
                init: Coefficients | None) -> Coefficients:
        start = init if init is not None else self.initial.fit(problem)
        if not problem.trajectories:
            raise ValueError("refinement needs the training jumps (problem.trajectories)")
        trajs = problem.trajectories
        if len(trajs) > self.max_jumps:
            trajs = [trajs[i] for i in np.linspace(0, len(trajs) - 1, self.max_jumps).round().astype(int)]
        xi = np.concatenate([t.xi for t in trajs])
        dxi = np.concatenate([t.dxi for t in trajs])
        # dxi errors count velocity_weight times as much as xi errors, each per its spread.
        spread = np.r_[np.maximum(xi.std(0), 1e-12), np.maximum(dxi.std(0), 1e-12) / self.velocity_weight]
        limit = self.bound * np.maximum(np.r_[np.abs(xi).max(0), np.abs(dxi).max(0)], 1e-6)
        params = Parameters.of(start.mask)
        shape = start.Xi.shape
        theta = params.vector(start.Xi)
        lengths = [None if w is None else max(2, int(round(w / problem.dt))) for w in self.windows]
        short = cut_windows(trajs, lengths[0]) if lengths else None
        stages = []
        lib = problem.library
        for length in lengths:
            wins = [cut_windows(trajs, length)] + ([short] if length != lengths[0] else [])
            cache: dict[str, Any] = {}

            def evaluate(th, wins=wins, cache=cache):
                key = th.tobytes()
                if cache.get("key") != key:
                    res, jac, dead = [], [], 0
                    Xi = params.matrix(th, shape)
                    for win in wins:
                        r, J, d = _residuals(lib, Xi, params, win, problem.dt, limit, spread,
                                             self.substeps, self.stride)
                        res.append(r)
                        jac.append(J)
                        dead += d
                    cache.update(key=key, res=np.concatenate(res), jac=np.concatenate(jac), dead=dead)
                return cache

            first = evaluate(theta)
            record = {"window_s": None if length is None else length * problem.dt,
                      "cost_before": 0.5 * float(first["res"] @ first["res"]), "dead_before": first["dead"]}
            sol = least_squares(lambda th: evaluate(th)["res"], theta, jac=lambda th: evaluate(th)["jac"],
                                method="lm", x_scale="jac", max_nfev=self.max_nfev,
                                xtol=1e-8, ftol=1e-8, gtol=1e-8)
            after = evaluate(sol.x)
            if after["dead"] or not sol.cost <= record["cost_before"]:
                record["stopped"] = "no improvement without divergence; previous result kept"
                stages.append(record)
                break
            theta = sol.x
            record.update(cost_after=float(sol.cost), evaluations=int(sol.nfev))
            stages.append(record)
        Xi = params.matrix(theta, shape)
        report = {name: {**start.report.get(name, {}), "refinement": {"stages": stages, "jumps": len(trajs)}}
                  for name in problem.phase_names}
        return Coefficients(Xi, start.mask.copy(), report)


def _residuals(lib, Xi: np.ndarray, params: Parameters, win: Windows, dt: float, limit: np.ndarray,
               spread: np.ndarray, substeps: int, stride: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Normalised state errors of every ``stride``-th valid sample after a window's
    start, their Jacobian (m, n) and the number of windows that left the bound."""
    X, V, S, alive = simulate(lib, Xi, params, win, dt, limit, substeps, stride=stride)
    err = (np.concatenate([X - win.xi, V - win.dxi], axis=2) / spread)[:, ::stride]  # (W, L', 2l)
    J = S / spread[None, None, :, None]  # (W, L', 2l, n)
    use = win.valid[:, ::stride].copy()
    use[:, 0] = False  # the start is the truth
    n_dead = int((win.valid & ~alive).any(axis=1).sum())
    dead = use & ~alive[:, ::stride]
    err[dead] = DIVERGED_FACTOR * limit / spread
    J[dead] = 0.0
    return err[use].reshape(-1), J[use].reshape(-1, params.size), n_dead
