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
  (``symrom.learn.shooting``, RK4 with exact sensitivities);
- the residual is the error of xi (divided by each latent's spread over the
  training rows) and, weighted by ``velocity_weight``, of dxi, at every sample;
  plus the windows of the shortest length at every stage, so short-horizon
  accuracy is kept while the horizon grows;
- Levenberg-Marquardt minimises it (``levenberg_marquardt`` below), then the windows grow
  (``windows``: 0.05 s, 0.1 s, 0.2 s, 0.4 s, 0.8 s, then the whole jump) and
  each stage starts from the last optimum. A window that leaves the bound
  counts as a large constant error from there on; a stage that ends with a
  higher cost, or with windows outside the bound, keeps the previous result
  and ends the schedule.

Refinement moves the coefficients STLSQ chose and never adds terms. With a
term budget, ``max_terms``, it then removes terms while the model has more:
``prune_share`` of them at a time (never below the budget), the least needed
first by their saliency on the rollout costs (``prune``), and refines again from there
(the result before the pruning is kept as ``Coefficients.unpruned``: what the refinement
without the budget fits). ``after_pruning`` says how: ``last``, from the last stage whose
result was kept onward (the pruned coefficients start where the schedule left the
full model, and the removal already moved the rest to make up for what went), or
``schedule``, the whole schedule again from the shortest windows (six times the work
per pruning; a record without the setting was fitted so). ``max_jumps`` caps the training jumps used (evenly spaced).
``hold`` names phases whose coefficients are held at the start's values: they act
in every rollout but are not fitted (a flight phase whose gravity must stay).
``short_weight`` weighs the shortest windows' error against the longer windows' in
the stages they join (1: every sample alike; more: short-horizon accuracy first,
the whole jump still kept in view).

``keep`` names phases the pruning leaves whole: their refined coefficients are held while
the others are pruned until the whole model is within the budget (the kept phases' terms
count) and refined again. A froggy jump's flight, pruned with the rest, lost the touchdown
its unpruned refinement predicted (docs/results.md); kept, it keeps it. If the kept phases alone
fill the budget, every phase is pruned as without ``keep``.

``polish`` names phases refined once more after the schedule and the pruning, one
at a time in that order, each alone with every other phase held, on the windows
``polish_windows`` with the shortest weighted ``polish_weight`` (the support is
kept). Pruning to a budget costs short-horizon accuracy; in a phase whose
coefficients the joint fit trades against the others' (a froggy jump's flight),
a pass on that phase alone can get it back (SIM A1: docs/results.md).

The rollouts alone would trade the accelerations for the path: a short phase
(a froggy jump's rear-only push, a few rows a jump) takes coefficients that
make it stiff, and a flight can stop falling at g, while the rollout error
still drops. ``acceleration_weight`` keeps the acceleration fit: each training
row's latent acceleration error (per latent, over its spread) counts that many
times its rise from the start, which is the least-squares fit
(``acceleration_prior``; half the squared rise, with exact derivatives, beside
the rollout residuals); 0 by default (the rollouts alone; recorded only when
set, so a model file without it reads as it was fitted), 1 in the validation
selection's refinements (``SelectionConfig.acceleration_weight``). ``momentum_weight`` (0 by
default) adds the rise of each phase's mean acceleration error over its rows:
the momentum balance of the phase as a whole. The validation selection checks
both on every candidate whatever the weights (``symrom.evaluate.usability``).

``backend`` says what rolls the windows out (``symrom.learn.shooting.simulate``):
``table``, the compiled kernel (compiled once per installation, then loaded from
numba's disk cache); ``numpy``, the reference; ``auto`` (default), the kernel
whenever the library has a term table, else NumPy. The choice depends on the
library alone, so a refinement gives the same coefficients wherever it runs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
import scipy.linalg

from symrom.learn.regressors.base import Coefficients, RegressionProblem, Regressor
from symrom.learn.regressors.stlsq import STLSQ
from symrom.learn.shooting import BACKENDS as SHOOTING_BACKENDS
from symrom.learn.shooting import Parameters, Windows, cut_windows, simulate

# A sample after its window left the bound counts this many times the bound (in
# units of the spread): more than any sample still inside, so leaving is never a
# way to lower the cost, and finite, so the solver can go on.
DIVERGED_FACTOR = 2.0
AFTER_PRUNING = ("last", "schedule")

@dataclass(frozen=True)
class Refine(Regressor):
    """initial: the regressor giving the start and the support; windows: the
    multiple-shooting schedule, s (None = whole jumps); velocity_weight: weight of
    the dxi error against the xi error; max_jumps: training jumps used at most;
    max_nfev: solver evaluations per stage; bound: divergence bound in units of
    the largest |xi|, |dxi| of the training jumps; substeps: RK4 steps per sample;
    stride: score every stride-th sample of a window; hold: names of phases whose
    coefficients are kept as the start has them (simulated, not fitted); short_weight:
    weight of the shortest windows' squared error in the stages they join; keep: phases the
    pruning leaves whole (module docstring); polish: phases
    refined again, each alone, after the schedule and pruning, on ``polish_windows`` (s)
    with the shortest weighted ``polish_weight``; backend: ``auto``, ``table`` or ``numpy``
    (module docstring); acceleration_weight: weight of the acceleration fit kept (module
    docstring; 0: rollouts alone, as a record without it means)."""

    kind: ClassVar[str] = "refine"
    initial: Regressor = field(default_factory=STLSQ)
    windows: tuple[float | None, ...] = (0.05, 0.1, 0.2, 0.4, 0.8, None)
    velocity_weight: float = 0.1
    max_jumps: int = 30
    max_nfev: int = 15
    bound: float = 5.0
    substeps: int = 1
    stride: int = 4
    max_terms: int | None = None
    prune_share: float = 0.25
    after_pruning: str = "last"
    hold: tuple[str, ...] = ()
    keep: tuple[str, ...] = ()
    short_weight: float = 1.0
    polish: tuple[str, ...] = ()
    polish_windows: tuple[float | None, ...] = (0.1, None)
    polish_weight: float = 100.0
    backend: str = "auto"
    acceleration_weight: float = 0.0
    momentum_weight: float = 0.0

    needs_trajectories = True

    def __post_init__(self) -> None:
        if not self.velocity_weight > 0:
            raise ValueError(f"velocity_weight must be > 0, got {self.velocity_weight}")
        if not self.windows:
            raise ValueError("refinement needs at least one window length")
        if self.max_terms is not None and self.max_terms < 1:
            raise ValueError(f"max_terms must be at least 1, got {self.max_terms}")
        if not self.short_weight > 0:
            raise ValueError(f"short_weight must be > 0, got {self.short_weight}")
        if not self.polish_weight > 0:
            raise ValueError(f"polish_weight must be > 0, got {self.polish_weight}")
        if not self.polish_windows:
            raise ValueError("polish needs at least one window length")
        if set(self.polish) & set(self.hold):
            raise ValueError(f"polish: phase(s) {sorted(set(self.polish) & set(self.hold))} are held")
        if set(self.keep) & set(self.hold):
            raise ValueError(f"keep: phase(s) {sorted(set(self.keep) & set(self.hold))} are held")
        if self.keep and self.max_terms is None:
            raise ValueError(f"keep={','.join(self.keep)}: a rule of the pruning; needs max_terms=N")
        if not 0 < self.prune_share <= 1:
            raise ValueError(f"prune_share must lie in (0, 1], got {self.prune_share}")
        if self.after_pruning not in AFTER_PRUNING:
            raise ValueError(f"after_pruning must be one of {AFTER_PRUNING}, got {self.after_pruning!r}")
        if not self.acceleration_weight >= 0:
            raise ValueError(f"acceleration_weight must be >= 0, got {self.acceleration_weight}")
        if self.backend not in SHOOTING_BACKENDS:
            raise ValueError(f"backend must be one of {SHOOTING_BACKENDS}, got {self.backend!r}")

    def polish_stage(self, phase: str, phase_names: list[str]) -> Refine:
        """The refinement that polishes ``phase`` alone: on ``polish_windows``, the shortest
        weighted ``polish_weight``, every other of ``phase_names`` held, no budget."""
        return replace(self, windows=self.polish_windows, short_weight=self.polish_weight, max_terms=None,
                       polish=(), keep=(), hold=tuple(n for n in phase_names if n != phase))

    @property
    def collinearity(self) -> float | None:  # the support is the initial regressor's
        return None

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "initial": self.initial.to_dict(), "windows": list(self.windows),
                "velocity_weight": self.velocity_weight, "max_jumps": self.max_jumps,
                "max_nfev": self.max_nfev, "bound": self.bound, "substeps": self.substeps,
                "stride": self.stride, "max_terms": self.max_terms, "prune_share": self.prune_share,
                **({"after_pruning": self.after_pruning} if self.max_terms is not None else {}),
                **({"hold": list(self.hold)} if self.hold else {}),
                **({"keep": list(self.keep)} if self.keep else {}),
                **({"short_weight": self.short_weight} if self.short_weight != 1.0 else {}),
                **({"polish": list(self.polish), "polish_windows": list(self.polish_windows),
                    "polish_weight": self.polish_weight} if self.polish else {}),
                **({"backend": self.backend} if self.backend != "auto" else {}),
                **({"acceleration_weight": self.acceleration_weight} if self.acceleration_weight else {}),
                **({"momentum_weight": self.momentum_weight} if self.momentum_weight else {})}

    def _reduce(self, problem: RegressionProblem, allowed: np.ndarray,
                init: Coefficients | None) -> Coefficients:
        start = init if init is not None else self.initial.fit(problem)
        if not problem.trajectories:
            raise ValueError("refinement needs the training jumps (problem.trajectories)")
        for key in ("hold", "keep", "polish"):
            unknown = sorted(set(getattr(self, key)) - set(problem.phase_names))
            if unknown:
                raise ValueError(f"{key}: no phase named {unknown} (the phases are {list(problem.phase_names)})")
        trajs = problem.trajectories
        if len(trajs) > self.max_jumps:
            trajs = [trajs[i] for i in np.linspace(0, len(trajs) - 1, self.max_jumps).round().astype(int)]
        xi = np.concatenate([t.xi for t in trajs])
        dxi = np.concatenate([t.dxi for t in trajs])
        # dxi errors count velocity_weight times as much as xi errors, each per its spread.
        spread = np.r_[np.maximum(xi.std(0), 1e-12), np.maximum(dxi.std(0), 1e-12) / self.velocity_weight]
        limit = self.bound * np.maximum(np.r_[np.abs(xi).max(0), np.abs(dxi).max(0)], 1e-6)
        lengths = [None if w is None else max(2, int(round(w / problem.dt))) for w in self.windows]
        short = cut_windows(trajs, lengths[0])
        # (windows, weight) of each stage: its own, and the shortest ones weighted by short_weight
        windows = [[(cut_windows(trajs, n), 1.0)] + ([(short, self.short_weight)] if n != lengths[0] else [])
                   for n in lengths]

        held = np.array([name in self.hold for name in problem.phase_names])
        fixed = np.where(held[:, None, None], start.Xi * start.mask, 0.0)  # the held phases' coefficients

        def cost(mask: np.ndarray, wins: list[tuple[Windows, float]]):
            """normal(th, sens) -> (cost, dead windows, J^T J, J^T r) of the parameters of
            ``mask`` on ``wins`` (the held phases' coefficients fixed); the last two only with
            ``sens``."""
            params = Parameters.of(mask)

            def normal(th, sens):
                Xi = fixed + params.matrix(th, mask.shape)
                parts = [(c, _normal_equations(problem.library, Xi, params, w, problem.dt, limit, spread,
                                               self.substeps, self.stride, sens, backend)) for w, c in wins]
                out = (sum(c * p[0] for c, p in parts), sum(p[1] for _, p in parts),
                       sum(c * p[2] for c, p in parts) if sens else None,
                       sum(c * p[3] for c, p in parts) if sens else None)
                if prior is None:
                    return out
                pc, pA, pg = prior(Xi, params, sens)
                return (out[0] + pc, out[1], out[2] + pA if sens else None, out[3] + pg if sens else None)
            return normal

        prior = (acceleration_prior(problem, start.Xi * start.mask, self.acceleration_weight, self.momentum_weight)
                 if self.acceleration_weight > 0 or self.momentum_weight > 0 else None)
        mask = start.mask & ~held[:, None, None]
        backend = self.backend
        Xi = start.Xi * mask
        Xi, stages, last = self._schedule(Xi, mask, windows, lengths, problem.dt, cost)
        unpruned = None
        if self.max_terms is not None and mask.sum() > self.max_terms:  # the result without the budget
            unpruned = Coefficients(Xi + fixed, mask | (start.mask & held[:, None, None]), {
                name: {**start.report.get(name, {}), "refinement": {"stages": list(stages), "jumps": len(trajs)}}
                for name in problem.phase_names})
        prunings = []
        budget, whole = self.max_terms, np.zeros_like(mask)
        kept = np.array([name in self.keep for name in problem.phase_names])[:, None, None] & mask
        if budget is not None and mask.sum() > budget and 0 < kept.sum() < budget:
            # the kept phases join the held ones (``cost`` reads ``fixed`` when called)
            fixed, whole = fixed + Xi * kept, kept
            mask, Xi, budget = mask & ~kept, Xi * (mask & ~kept), budget - int(kept.sum())
        while budget is not None and mask.sum() > budget:
            n = int(mask.sum())
            drop = min(n - budget, max(1, int(np.ceil(self.prune_share * n))))
            Xi, mask, record = prune(Xi, mask, [cost(mask, [w]) for w in windows[last]], drop)
            first = last if self.after_pruning == "last" else 0
            Xi, more, last = self._schedule(Xi, mask, windows, lengths, problem.dt, cost, first)
            prunings.append({**record, "stages": more})
        Xi, mask = Xi + fixed, mask | whole | (start.mask & held[:, None, None])
        report = {name: {**start.report.get(name, {}), "refinement": {
            "stages": stages, "jumps": len(trajs), **({"prunings": prunings} if self.max_terms is not None else {})}}
            for name in problem.phase_names}
        for name in self.polish:
            if not mask[problem.phase_names.index(name)].any():  # pruned away: nothing to polish
                report[name]["refinement"]["polish"] = []
                continue
            done = self.polish_stage(name, problem.phase_names)._reduce(problem, allowed, Coefficients(Xi, mask))
            Xi, mask = done.Xi, done.mask
            report[name]["refinement"]["polish"] = done.report[name]["refinement"]["stages"]
        return Coefficients(Xi, mask, report, unpruned)

    def _schedule(self, Xi: np.ndarray, mask: np.ndarray, windows: list[list[tuple[Windows, float]]], lengths: list,
                  dt: float, cost, first: int = 0) -> tuple[np.ndarray, list[dict], int]:
        """The growing-window schedule from ``Xi`` on the support ``mask``, from stage ``first``
        on: the result, a record per stage and the index of the last stage whose result was
        kept (``first`` if none)."""
        params = Parameters.of(mask)
        theta = params.vector(Xi)
        stages, last = [], first
        for i, (length, wins) in enumerate(zip(lengths, windows)):
            if i < first:
                continue
            record = {"window_s": None if length is None else length * dt}
            new, info = levenberg_marquardt(cost(mask, wins), theta, self.max_nfev)
            record.update(info)
            if info["dead_after"] or not info["cost_after"] <= info["cost_before"]:
                record["stopped"] = "no improvement without divergence; previous result kept"
                stages.append(record)
                break
            theta, last = new, i
            stages.append(record)
        return params.matrix(theta, mask.shape), stages, last


def acceleration_prior(problem: RegressionProblem, Xi0: np.ndarray, weight: float, momentum: float = 0.0):
    """prior(Xi, params, sens) -> (cost, J^T J, J^T r) of keeping the acceleration fit: half of
    ``weight`` times the rise of the squared latent acceleration error over the training rows,
    each latent per its spread (``problem.target_spread``), from the start's Xi0 (P, p, l):
    sum over phases k and latents j of (Xi - Xi0)_kj^T Theta_k^T Theta_k (Xi - Xi0)_kj / s_j^2,
    which is the whole rise while the start is the least-squares fit on its support (STLSQ's,
    up to its small ridge) and the refinement moves within that support."""
    s2 = np.asarray(problem.target_spread, dtype=float) ** 2
    grams = []
    for ph in problem.phases:
        if ph is None:
            grams.append(None)
            continue
        mean = ph.theta.mean(axis=0)
        grams.append(weight * (ph.theta.T @ ph.theta) + momentum * ph.n_rows * np.outer(mean, mean))
    weight = 1.0

    def prior(Xi: np.ndarray, params: Parameters, sens: bool):
        D = Xi - Xi0  # (P, p, l)
        cost, GD = 0.0, np.zeros_like(D)
        for k, G in enumerate(grams):
            if G is None:
                continue
            GD[k] = G @ D[k] / s2
            cost += 0.5 * weight * float(np.sum(D[k] * GD[k]))
        if not sens:
            return cost, None, None
        g = weight * GD[params.phase, params.term, params.latent]
        same = (params.phase[:, None] == params.phase[None, :]) & (params.latent[:, None] == params.latent[None, :])
        A = np.zeros((params.size, params.size))
        for k, G in enumerate(grams):
            if G is None:
                continue
            on = params.phase == k
            sub = G[np.ix_(params.term[on], params.term[on])] / s2[params.latent[on]][:, None]
            A[np.ix_(on, on)] = weight * np.where(same[np.ix_(on, on)], sub, 0.0)
        return cost, A, g

    return prior


def prune(Xi: np.ndarray, mask: np.ndarray, normals: list, drop: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """Remove ``drop`` active coefficients of ``Xi`` (P, p, l) on ``mask``, the least
    needed first, by their saliency on rollout costs ``normals`` (each as
    ``levenberg_marquardt`` takes it: the stage's windows, and its shortest windows).
    With H = sum_k J_k^T J_k / c_k (each cost relative to its value, so that the short
    windows count as much as the long ones), the relative cost rises by about
    theta_i^2 / (2 (H^-1)_ii) when entry i goes and the rest move to make up for it
    (optimal brain surgeon: the ``explained`` measure of STLSQ, on the rollout error).
    One at a time, each removal updating the others and H^-1 (the Schur complement).
    Returns the new Xi and mask and a record (costs before, terms removed, predicted rise)."""
    params = Parameters.of(mask)
    theta = params.vector(Xi)
    parts = [normal(theta, True) for normal in normals]
    H = sum(A / max(c, 1e-300) for c, _, A, _ in parts)
    d = np.sqrt(np.maximum(np.diag(H), 1e-300))
    Hs = H / d[:, None] / d[None, :] + 1e-10 * np.eye(theta.size)  # equilibrated, as STLSQ's
    M = np.linalg.pinv(Hs, hermitian=True) / d[:, None] / d[None, :]
    keep = np.ones(theta.size, dtype=bool)
    rise = 0.0
    for _ in range(drop):
        live = np.flatnonzero(keep)
        sal = theta[live] ** 2 / np.maximum(np.diag(M)[live], 1e-300) / 2
        i = live[int(np.argmin(sal))]
        rise += float(sal.min())
        mi = M[:, i].copy()
        theta = theta - mi * (theta[i] / M[i, i])
        M = M - np.outer(mi, mi) / M[i, i]
        keep[i], theta[i] = False, 0.0
    new_mask = mask.copy()
    new_mask[params.phase[~keep], params.term[~keep], params.latent[~keep]] = False
    out = np.zeros_like(Xi)
    out[new_mask] = Parameters.of(mask).matrix(theta, mask.shape)[new_mask]
    return out, new_mask, {"costs_before": [float(c) for c, *_ in parts],
                           "dead_before": int(sum(d for _, d, *_ in parts)), "removed": int(drop),
                           "active_after": int(new_mask.sum()), "predicted_rise": rise}


def levenberg_marquardt(normal, theta: np.ndarray, max_evaluations: int,
                        tol: float = 1e-8) -> tuple[np.ndarray, dict]:
    """Minimise a sum of squares given ``normal(theta, sens) -> (cost, dead, J^T J, J^T r)``.

    Levenberg-Marquardt with Marquardt's diagonal scaling, on the normal equations:
    the residuals here number ~1e5 and the parameters ~1e2, so forming J^T J once
    per accepted step (BLAS) is far cheaper than the QR or SVD of J that SciPy's
    solvers repeat at every step; a trial step needs only the cost (a rollout
    without sensitivities). Returns the best theta and a record of the run.
    """
    cost, dead, A, g = normal(theta, True)
    record = {"cost_before": float(cost), "dead_before": int(dead)}
    lam, evaluations = 1e-3, 1
    while evaluations < max_evaluations:
        d = np.maximum(np.diag(A), 1e-12 * max(float(np.diag(A).max()), 1e-300))
        try:
            step = -scipy.linalg.cho_solve(scipy.linalg.cho_factor(A + lam * np.diag(d), check_finite=False),
                                           g, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            lam *= 10.0
            continue
        trial_cost, trial_dead, _, _ = normal(theta + step, False)
        evaluations += 1
        if np.isfinite(trial_cost) and trial_cost < cost:
            small = cost - trial_cost <= tol * cost or np.abs(step).max() <= tol * (np.abs(theta).max() + tol)
            theta = theta + step
            cost, dead, A, g = normal(theta, True)
            evaluations += 1
            lam = max(lam / 3.0, 1e-9)
            if small:
                break
        else:
            lam *= 4.0
            if lam > 1e12:
                break
    record.update(cost_after=float(cost), dead_after=int(dead), evaluations=evaluations)
    return theta, record


def _normal_equations(lib, Xi: np.ndarray, params: Parameters, win: Windows, dt: float, limit: np.ndarray,
                      spread: np.ndarray, substeps: int, stride: int, sens: bool, backend: str = "auto"
                      ) -> tuple[float, int, np.ndarray | None, np.ndarray | None]:
    """Half the squared normalised state error of every ``stride``-th valid sample after a
    window's start (a sample after its window left the bound counts ``DIVERGED_FACTOR``
    times the bound), the number of windows that left it and, with ``sens``, J^T J and J^T r."""
    X, V, S, alive = simulate(lib, Xi, params, win, dt, limit, substeps, sensitivities=sens, stride=stride,
                              backend=backend)
    err = (np.concatenate([X - win.xi, V - win.dxi], axis=2) / spread)[:, ::stride]  # (W, L', 2l)
    use = win.valid[:, ::stride].copy()
    use[:, 0] = False  # the start is the truth
    n_dead = int((win.valid & ~alive).any(axis=1).sum())
    dead = use & ~alive[:, ::stride]
    err[dead] = DIVERGED_FACTOR * limit / spread
    err[~use] = 0.0
    cost = 0.5 * float(np.sum(err ** 2))
    if not sens:
        return cost, n_dead, None, None
    live = (use & ~dead)[:, :, None] / spread  # (W, L', 2l): weight of each sensitivity row
    J = (S * live[..., None]).reshape(-1, params.size)
    return cost, n_dead, J.T @ J, J.T @ err.reshape(-1)
