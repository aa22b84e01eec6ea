"""What every regressor shares: the problem it is given, the result it returns,
and the common preparation of each phase's candidate terms.

A regressor finds the coefficient matrices Xi (P, p, l) of the latent
dynamics ddxi = Theta(xi, dxi, nu) Xi_k, one per phase k, with the
autoencoder frozen (step (c) of the paper's training). ``Regressor.fit`` does
the shared work, then calls the subclass's ``_reduce``:

- it checks the problem (shapes, at least one phase with rows);
- per phase, it leaves out terms that are zero up to rounding on that phase's
  rows (the latent ground force in flight) and, with ``collinearity`` set,
  every term that is near-collinear with a simpler one there
  (``symrom.learn.audit``), recording what it left out and why;
- ``_reduce(problem, allowed)`` then returns Xi and the active mask, never
  using a term outside ``allowed``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from symrom.learn.audit import audit_collinearity, null_terms
from symrom.learn.shooting import Trajectory
from symrom.model.library import Library


@dataclass
class PhaseData:
    """The rows of one phase, encoded: theta (N, p) library values, ddxi (N, l) latent
    accelerations, ddq (N, 18) configuration accelerations and W_d (18, l) the decoder,
    both already scaled by sqrt(decoded_weight) of the SINDy loss."""

    theta: np.ndarray
    ddxi: np.ndarray
    ddq: np.ndarray
    W_d: np.ndarray

    @property
    def n_rows(self) -> int:
        return int(self.theta.shape[0])


@dataclass
class RegressionProblem:
    """Everything a regressor may use, for a library of p terms and P phases.

    phases: per phase its training rows (None: the data holds no row of it);
    target_spread (l,): standard deviation of each latent acceleration over all training rows,
    the yardstick of scale-free sparsity; trajectories: the training jumps for
    rollout-based regressors, sampled every ``dt`` s; validation: per phase its
    validation rows (for the sparsity path), or None; excluded (p,) bool: terms no phase
    may use, ``excluded_reason`` saying why (the reports name it).
    """

    library: Library
    phase_names: list[str]
    phases: list[PhaseData | None]
    target_spread: np.ndarray
    dt: float
    trajectories: list[Trajectory] = field(default_factory=list)
    validation: list[PhaseData | None] | None = None
    excluded: np.ndarray | None = None
    excluded_reason: str = ""

    @property
    def shape(self) -> tuple[int, int, int]:
        """(P, p, l)."""
        return len(self.phase_names), self.library.n_features, self.library.latent_dim


@dataclass
class Coefficients:
    """A regressor's result: Xi (P, p, l), mask (P, p, l) bool of active terms, and
    per phase name a JSON-ready report (terms left out and why, paths, refinement);
    unpruned: for a regressor that pruned its result to a term budget, the result before
    the pruning (what it fits without the budget), else None."""

    Xi: np.ndarray
    mask: np.ndarray
    report: dict[str, dict[str, Any]] = field(default_factory=dict)
    unpruned: Coefficients | None = field(default=None, repr=False)


class Regressor(ABC):
    """Base of the sparse regressors. Subclasses implement ``_reduce``.

    collinearity: |correlation| on a phase's rows above which the more complex
    of two terms is left out of that phase (None: keep every term).
    """

    collinearity: float | None = None
    kind: ClassVar[str] = ""  # the registry's name of a concrete regressor

    def fit(self, problem: RegressionProblem, init: Coefficients | None = None) -> Coefficients:
        """Coefficients for ``problem``; ``init`` is a starting or prior solution
        for regressors that use one (fine-tuning, refinement)."""
        P, p, l = problem.shape
        if len(problem.phases) != P:
            raise ValueError(f"{len(problem.phases)} phase data for {P} phase names")
        if all(ph is None for ph in problem.phases):
            raise ValueError("no training rows in any phase")
        for name, ph in zip(problem.phase_names, problem.phases):
            if ph is not None and (ph.theta.shape[1] != p or ph.ddxi.shape != (ph.n_rows, l)):
                raise ValueError(f"phase {name!r}: theta {ph.theta.shape} and ddxi {ph.ddxi.shape} "
                                 f"do not match a library of {p} terms and l = {l}")
        if init is not None and np.shape(init.Xi) != (P, p, l):
            raise ValueError(f"initial coefficients: shape {np.shape(init.Xi)}, expected {(P, p, l)}")
        if problem.excluded is not None and np.shape(problem.excluded) != (p,):
            raise ValueError(f"excluded: shape {np.shape(problem.excluded)}, expected ({p},)")
        allowed = np.zeros((P, p), dtype=bool)
        report: dict[str, dict[str, Any]] = {}
        names, ranks = problem.library.feature_names, problem.library.feature_ranks
        for k, (name, ph) in enumerate(zip(problem.phase_names, problem.phases)):
            if ph is None:  # no evidence: only a starting solution (init) can fill it
                allowed[k] = True if problem.excluded is None else ~problem.excluded
                report[name] = {"trained": False, "dropped": []}
                continue
            null = null_terms(ph.theta)
            keep, dropped = ~null, [{"term": names[i], "reason": "zero on this phase's rows"}
                                    for i in np.flatnonzero(null)]
            if problem.excluded is not None:
                out = problem.excluded & keep
                keep = keep & ~problem.excluded
                dropped += [{"term": names[i], "reason": problem.excluded_reason} for i in np.flatnonzero(out)]
            if self.collinearity is not None:
                more_keep, more = audit_collinearity(ph.theta, names, ranks, self.collinearity, keep)
                keep, dropped = more_keep, dropped + more
            allowed[k] = keep
            report[name] = {"trained": True, "n_rows": ph.n_rows, "dropped": dropped}
        result = self._reduce(problem, allowed, init)
        for res in (result, result.unpruned):
            if res is None:
                continue
            if np.any(res.mask & ~allowed[:, :, None]):
                raise RuntimeError(f"{type(self).__name__} used a term outside the allowed set")
            full = {name: dict(r) for name, r in report.items()}
            for name, extra in res.report.items():
                full.setdefault(name, {}).update(extra)
            res.report = full
        return result

    @abstractmethod
    def _reduce(self, problem: RegressionProblem, allowed: np.ndarray,
                init: Coefficients | None) -> Coefficients:
        """Xi and mask for ``problem`` using only the terms ``allowed`` (P, p) per phase."""

    def to_dict(self) -> dict[str, Any]:
        """The regressor's configuration, ``{"kind": ..., settings...}``, JSON-ready (recorded
        in the model file; ``symrom.learn.plugins.regressor_from_dict`` reads it back)."""
        from dataclasses import asdict, is_dataclass

        body = asdict(self) if is_dataclass(self) else {}
        return {"kind": self.kind, **body}
