"""Sequentially thresholded least squares (STLSQ) on the weighted SINDy objective.

For one phase the paper minimises
    ||ddxi - Theta Xi||^2 + ||ddq - W_d Theta Xi||^2
over Xi (p, l). With Z = Theta Xi this is ||(Z - Z*) G^(1/2)||^2 + const with
G = I + W_d^T W_d and Z* = (ddxi + ddq W_d) G^-1, so on a fixed support the
optimum solves the normal equations  (G kron Theta^T Theta) vec(Xi) =
vec(Theta^T Z* G)  restricted to the active entries. Sequential thresholding
(Brunton et al. 2016) alternates that exact solve with dropping small terms,
the standard surrogate for the L1 penalty; it ends when the support stops
changing. No library solves this coupled (Kronecker) system with a support
mask, hence the few lines below; the linear algebra itself is SciPy's.

What "small" means is the ``measure``:
- ``coefficient``: |Xi_pj| < threshold, the paper's rule. It depends on the
  units of each term: a ground-force input in N has coefficients near 1/m and
  is the first to go, however much of the motion it explains.
- ``contribution``: |Xi_pj| rms(Theta_p) / spread(ddxi_j) < threshold, the
  term's typical size in the equation of ddxi_j relative to the spread of that
  latent acceleration over all training rows. Scale-free, but blind to
  cancellation: two large terms that cancel on the data both look important.
- ``explained``: the share of the target's spread that the term explains and
  no other term can: the increase of the loss when the term is removed and
  the others refit, x_i^2 / (K^-1)_ii for the normal matrix K, over
  N G_jj spread(ddxi_j)^2. Terms are removed one at a time, the least
  explaining first, and the rest refit, until every remaining term explains at
  least ``threshold``; a term whose effect another can take over (one of a
  cancelling pair) explains nothing of its own and goes first.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import scipy.linalg

from symrom.learn.audit import negligible
from symrom.learn.regressors.base import Coefficients, PhaseData, RegressionProblem, Regressor

_JITTER = 1e-10  # smallest ridge on the equilibrated normal equations
MEASURES = ("coefficient", "contribution", "explained")


def check_measure(measure: str) -> None:
    """ValueError unless ``measure`` is a sparsity measure: the one check of it."""
    if measure not in MEASURES:
        raise ValueError(f"unknown sparsity measure {measure!r}; choose from {', '.join(MEASURES)}")


@dataclass(frozen=True)
class STLSQConfig:
    """threshold: terms below it (in ``measure``) are dropped; ridge: Tikhonov weight
    relative to the mean diagonal of Theta^T Theta (0 = none); alpha: ridge on the
    standardised features (scikit-learn's and PySINDy's ``alpha`` with normalised
    columns), which keeps near-collinear pairs such as xi and sin(xi) from
    cancelling with huge coefficients (0 = a 1e-10 numerical jitter only);
    max_iter: thresholding rounds; measure: ``coefficient``, ``contribution`` or
    ``explained``; target_spread (l,): standard deviation of each latent
    acceleration over all training rows, for the scale-free measures."""

    threshold: float = 0.01
    ridge: float = 0.0
    alpha: float = 0.0
    max_iter: int = 25
    measure: str = "coefficient"
    target_spread: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        check_measure(self.measure)


def weighted_targets(ddxi: np.ndarray, ddq: np.ndarray, W_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Z* (N, l) and G (l, l) of the weighted objective; ddxi (N, l), ddq (N, 18), W_d (18, l)."""
    G = np.eye(W_d.shape[1]) + W_d.T @ W_d
    Zs = np.linalg.solve(G, (ddxi + ddq @ W_d).T).T
    return Zs, G


def _scaled_system(A: np.ndarray, B: np.ndarray, G: np.ndarray, mask: np.ndarray, ridge: float,
                   prior: np.ndarray | None, alpha: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The normal equations of the active entries of ``mask``, equilibrated and regularised:
    (idx, Ks, rhs / d, d) with idx the column-major positions of the active entries in
    Xi, Ks = D^-1 K D^-1 + max(alpha, jitter) I and d = sqrt(diag K) (see ``solve_support``)."""
    # A term that is zero on this phase's rows up to rounding (e.g. the latent ground
    # force in flight) is not identifiable: its equilibrated coefficient would be
    # rounding noise divided by ~0.
    p = mask.shape[0]
    mask = mask & ~negligible(np.sqrt(np.clip(np.diag(A), 0.0, None)))[:, None]
    idx = np.flatnonzero(mask.T.ravel())  # column-major vec of Xi
    feat, col = idx % p, idx // p
    K = G[np.ix_(col, col)] * A[np.ix_(feat, feat)]  # rows/cols of G kron A
    rhs = B[feat, col]
    if ridge > 0:
        r = ridge * np.mean(np.diag(A))
        K = K + r * np.eye(idx.size)
        if prior is not None:
            rhs = rhs + r * prior[feat, col]
    # Equilibrate (features differ in scale by orders of magnitude), then add the
    # standardised ridge alpha, at least a vanishing jitter: near-collinear features
    # (x and sin x on a small range) make the system numerically singular, and the
    # jittered Cholesky factorisation gives the minimum-norm optimum at a fraction
    # of the cost of an SVD.
    d = np.sqrt(np.clip(np.diag(K), 1e-300, None))
    Ks = K / d[:, None] / d[None, :]
    Ks[np.diag_indices_from(Ks)] += max(alpha, _JITTER)
    return idx, Ks, rhs / d, d


def _inverse(Ks: np.ndarray) -> np.ndarray:
    """Ks^-1 of a symmetric positive (semi)definite matrix: Cholesky, else the
    pseudo-inverse of its well-conditioned part."""
    try:
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(Ks, check_finite=False), np.eye(len(Ks)),
                                      check_finite=False)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(Ks)
        keep = w > w.max() * 1e-13
        return (V[:, keep] / w[keep]) @ V[:, keep].T


def solve_support(A: np.ndarray, B: np.ndarray, G: np.ndarray, mask: np.ndarray,
                  ridge: float = 0.0, prior: np.ndarray | None = None, alpha: float = 0.0) -> np.ndarray:
    """Minimise tr(G (Theta Xi - Z)^T (Theta Xi - Z)) + r ||Xi - prior||^2
    + alpha sum_ij G_jj A_ii Xi_ij^2 with Xi zero off ``mask``, r = ridge * mean(diag A).

    A = Theta^T Theta (p, p), B = Theta^T Z G (p, l), G (l, l), mask (p, l) bool,
    prior (p, l) or None (= 0). Returns Xi (p, l).
    """
    p, l = mask.shape
    idx, Ks, rhs, d = _scaled_system(A, B, G, mask, ridge, prior, alpha)
    Xi = np.zeros((p, l))
    if idx.size == 0:
        return Xi
    try:
        x = scipy.linalg.cho_solve(scipy.linalg.cho_factor(Ks, check_finite=False), rhs, check_finite=False)
    except np.linalg.LinAlgError:
        x = _inverse(Ks) @ rhs
    Xi.T.flat[idx] = x / d
    return Xi


def term_sizes(Xi: np.ndarray, theta_rms: np.ndarray, config: STLSQConfig) -> np.ndarray:
    """(p, l) the size of every term in ``config.measure`` (``coefficient`` or
    ``contribution``); theta_rms (p,) rms of each column."""
    if config.measure == "coefficient":
        return np.abs(Xi)
    spread = np.asarray(config.target_spread, dtype=float)
    return np.abs(Xi) * theta_rms[:, None] / np.maximum(spread, 1e-300)[None, :]


REFRESH = 25  # removals between fresh inversions of the normal matrix (downdates drift)


def _backward_elimination(A: np.ndarray, B: np.ndarray, G: np.ndarray, mask: np.ndarray, n_rows: int,
                          config: STLSQConfig, prior: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The ``explained`` measure: drop the least explaining term until all explain enough.

    The share of entry i is x_i^2 / (K^-1)_ii over n_rows G_jj spread_j^2 (its
    column j): the loss increase if it were removed and the rest refit. Removing an
    entry downdates the optimum and the inverse (the Schur complement), so each
    removal costs O(n^2) instead of a new factorisation; a fresh inversion every
    ``REFRESH`` removals bounds the drift.
    """
    p, l = mask.shape
    spread = np.asarray(config.target_spread, dtype=float)
    norm = n_rows * np.diag(G) * np.maximum(spread, 1e-300) ** 2  # (l,)
    removed = 0
    while True:
        idx, Ks, rhs, d = _scaled_system(A, B, G, mask, config.ridge, prior, config.alpha)
        if idx.size == 0:
            return np.zeros((p, l)), mask & False
        M = _inverse(Ks)
        x = M @ rhs
        keep = np.ones(idx.size, dtype=bool)
        for _ in range(REFRESH):
            live = np.flatnonzero(keep)
            share = x[live] ** 2 / np.maximum(np.diag(M)[live], 1e-300) / norm[idx[live] // p]
            k = int(np.argmin(share))
            if share[k] >= config.threshold:
                Xi = np.zeros((p, l))
                Xi.T.flat[idx[keep]] = x[keep] / d[keep]
                out = np.zeros(p * l, dtype=bool)
                out[idx[keep]] = True
                return Xi, out.reshape(l, p).T.copy()
            i = live[k]
            mi = M[:, i].copy()
            x -= mi * (x[i] / M[i, i])
            M -= np.outer(mi, mi) / M[i, i]
            keep[i] = False
            x[i] = 0.0
            removed += 1
            if not keep.any():
                break
        mask = mask.copy()
        mask.T.flat[idx[~keep]] = False


def stlsq(Theta: np.ndarray, ddxi: np.ndarray, ddq: np.ndarray, W_d: np.ndarray,
          config: STLSQConfig = STLSQConfig(), prior: np.ndarray | None = None,
          mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sparse Xi (p, l) and its mask for one phase.

    Theta (N, p) features, ddxi (N, l) latent and ddq (N, 18) configuration
    accelerations, W_d (18, l) the frozen decoder. With ``prior`` (p, l) and
    ``config.ridge`` > 0 the coefficients are pulled towards the prior (used for
    fine-tuning); ``mask`` (p, l) restricts the starting support.
    """
    if config.measure != "coefficient" and config.target_spread is None:
        raise ValueError(f"the {config.measure} measure needs the latent accelerations' target_spread")
    Zs, G = weighted_targets(ddxi, ddq, W_d)
    A = Theta.T @ Theta
    B = Theta.T @ Zs @ G
    theta_rms = np.sqrt(np.diag(A) / max(Theta.shape[0], 1))
    mask = np.ones((Theta.shape[1], ddxi.shape[1]), dtype=bool) if mask is None else mask.copy()
    mask &= ~negligible(np.sqrt(np.diag(A)))[:, None]
    if config.measure == "explained":
        return _backward_elimination(A, B, G, mask, Theta.shape[0], config, prior)
    Xi = solve_support(A, B, G, mask, config.ridge, prior, config.alpha)
    for _ in range(config.max_iter):
        new_mask = mask & (term_sizes(Xi, theta_rms, config) >= config.threshold)
        if np.array_equal(new_mask, mask):
            break
        mask = new_mask
        Xi = solve_support(A, B, G, mask, config.ridge, prior, config.alpha)
    return Xi * mask, mask


def weighted_loss(Theta: np.ndarray, Xi: np.ndarray, ddxi: np.ndarray, ddq: np.ndarray,
                  W_d: np.ndarray) -> float:
    """The paper's SINDy loss (sum over samples) at Xi: ||ddxi - Z||^2 + ||ddq - Z W_d^T||^2."""
    Z = Theta @ Xi
    return float(np.sum((ddxi - Z) ** 2) + np.sum((ddq - Z @ W_d.T) ** 2))


def acceleration_error(ph: PhaseData, Xi: np.ndarray, target_spread: np.ndarray) -> float:
    """Mean over the l latent accelerations of rms(ddxi - Theta Xi) / target_spread on ``ph``."""
    res = ph.ddxi - ph.theta @ Xi
    return float(np.mean(np.sqrt(np.mean(res ** 2, axis=0)) / np.maximum(target_spread, 1e-300)))


@dataclass(frozen=True)
class STLSQ(Regressor):
    """The exact solver of step (c): STLSQ per phase (see the module docstring).

    threshold, measure, alpha, ridge, max_iter: as in ``STLSQConfig``;
    collinearity: leave out near-collinear terms first (``Regressor``).
    The defaults are the paper's: |Xi| < 0.01 dropped, no ridge, every term kept.
    """

    kind: ClassVar[str] = "stlsq"
    threshold: float = 0.01
    measure: str = "coefficient"
    alpha: float = 0.0
    ridge: float = 0.0
    collinearity: float | None = None
    max_iter: int = 25

    def __post_init__(self) -> None:
        check_measure(self.measure)
        for name in ("threshold", "alpha", "ridge"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name}={getattr(self, name):g}: must be >= 0")
        if self.collinearity is not None and not 0 < self.collinearity <= 1:
            raise ValueError(f"collinearity={self.collinearity:g}: must lie in (0, 1]")

    def config(self, target_spread: np.ndarray) -> STLSQConfig:
        return STLSQConfig(threshold=self.threshold, ridge=self.ridge, alpha=self.alpha, max_iter=self.max_iter,
                           measure=self.measure, target_spread=tuple(float(s) for s in target_spread))

    def _reduce(self, problem: RegressionProblem, allowed: np.ndarray,
                init: Coefficients | None) -> Coefficients:
        P, p, l = problem.shape
        Xi, mask = np.zeros((P, p, l)), np.zeros((P, p, l), dtype=bool)
        cfg = self.config(problem.target_spread)
        for k, ph in enumerate(problem.phases):
            if ph is None:
                continue
            start = np.repeat(allowed[k][:, None], l, axis=1)
            Xi[k], mask[k] = stlsq(ph.theta, ph.ddxi, ph.ddq, ph.W_d, cfg, mask=start)
        return Coefficients(Xi, mask)

    def path(self, problem: RegressionProblem, thresholds: tuple[float, ...]) -> dict[str, list[dict]]:
        """Per phase name, the sparsity path: for each threshold (in this regressor's
        measure) the active terms and, if ``problem.validation`` is given, the
        validation error of the latent accelerations (``acceleration_error``)."""
        out: dict[str, list[dict]] = {n: [] for n in problem.phase_names}
        for t in sorted(thresholds):
            fit = replace(self, threshold=float(t)).fit(problem)
            for k, name in enumerate(problem.phase_names):
                if problem.phases[k] is None:
                    continue
                val = problem.validation[k] if problem.validation is not None else None
                out[name].append({"threshold": float(t), "active_terms": int(fit.mask[k].sum()),
                                  "val_error": None if val is None or val.n_rows == 0 else
                                  acceleration_error(val, fit.Xi[k], problem.target_spread)})
        return out
