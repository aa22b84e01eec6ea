"""Sequentially thresholded least squares on the weighted SINDy objective.

For one phase the paper minimises
    ||ddxi - Theta Xi||^2 + ||ddq - W_d Theta Xi||^2
over Xi (p, l). With Z = Theta Xi this is ||(Z - Z*) G^(1/2)||^2 + const with
G = I + W_d^T W_d and Z* = (ddxi + ddq W_d) G^-1, so on a fixed support the
optimum solves the normal equations  (G kron Theta^T Theta) vec(Xi) =
vec(Theta^T Z* G)  restricted to the active entries. Sequential thresholding
(Brunton et al. 2016) alternates that exact solve with zeroing |Xi| < threshold,
the standard surrogate for the L1 penalty; it ends when the support stops
changing. No library solves this coupled (Kronecker) system with a support
mask, hence the few lines below; the linear algebra itself is SciPy's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg


_JITTER = 1e-10  # smallest ridge on the equilibrated normal equations
_NULL_FEATURE = 1e-10  # a column this small relative to the largest carries rounding only


@dataclass(frozen=True)
class STLSQConfig:
    """threshold: |Xi| below it is zeroed; ridge: Tikhonov weight relative to the
    mean diagonal of Theta^T Theta (0 = none); alpha: ridge on the standardised
    features (scikit-learn's and PySINDy's ``alpha`` with normalised columns), which
    keeps near-collinear pairs such as xi and sin(xi) from cancelling with huge
    coefficients (0 = a 1e-10 numerical jitter only); max_iter: thresholding rounds."""

    threshold: float = 0.01
    ridge: float = 0.0
    alpha: float = 0.0
    max_iter: int = 25


def weighted_targets(ddxi: np.ndarray, ddq: np.ndarray, W_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Z* (N, l) and G (l, l) of the weighted objective; ddxi (N, l), ddq (N, 18), W_d (18, l)."""
    G = np.eye(W_d.shape[1]) + W_d.T @ W_d
    Zs = np.linalg.solve(G, (ddxi + ddq @ W_d).T).T
    return Zs, G


def solve_support(A: np.ndarray, B: np.ndarray, G: np.ndarray, mask: np.ndarray,
                  ridge: float = 0.0, prior: np.ndarray | None = None, alpha: float = 0.0) -> np.ndarray:
    """Minimise tr(G (Theta Xi - Z)^T (Theta Xi - Z)) + r ||Xi - prior||^2
    + alpha sum_ij G_jj A_ii Xi_ij^2 with Xi zero off ``mask``, r = ridge * mean(diag A).

    A = Theta^T Theta (p, p), B = Theta^T Z G (p, l), G (l, l), mask (p, l) bool,
    prior (p, l) or None (= 0). Returns Xi (p, l).
    """
    p, l = mask.shape
    # A feature that is identically zero on this phase's rows up to rounding
    # (e.g. the latent ground force in flight) is not identifiable: its
    # equilibrated coefficient would be rounding noise divided by ~0.
    norms = np.sqrt(np.clip(np.diag(A), 0.0, None))
    mask = mask & (norms > _NULL_FEATURE * norms.max())[:, None]
    idx = np.flatnonzero(mask.T.ravel())  # column-major vec of Xi
    Xi = np.zeros((p, l))
    if idx.size == 0:
        return Xi
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
    try:
        x = scipy.linalg.cho_solve(scipy.linalg.cho_factor(Ks, check_finite=False), rhs / d,
                                   check_finite=False)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(Ks)
        keep = w > w.max() * 1e-13
        x = V[:, keep] @ ((V[:, keep].T @ (rhs / d)) / w[keep])
    x = x / d
    Xi.T.flat[idx] = x
    return Xi


def stlsq(Theta: np.ndarray, ddxi: np.ndarray, ddq: np.ndarray, W_d: np.ndarray,
          config: STLSQConfig = STLSQConfig(), prior: np.ndarray | None = None,
          mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sparse Xi (p, l) and its mask for one phase.

    Theta (N, p) features, ddxi (N, l) latent and ddq (N, 18) configuration
    accelerations, W_d (18, l) the frozen decoder. With ``prior`` (p, l) and
    ``config.ridge`` > 0 the coefficients are pulled towards the prior (used for
    fine-tuning); ``mask`` (p, l) restricts the starting support.
    """
    Zs, G = weighted_targets(ddxi, ddq, W_d)
    A = Theta.T @ Theta
    B = Theta.T @ Zs @ G
    mask = np.ones((Theta.shape[1], ddxi.shape[1]), dtype=bool) if mask is None else mask.copy()
    Xi = solve_support(A, B, G, mask, config.ridge, prior, config.alpha)
    for _ in range(config.max_iter):
        new_mask = mask & (np.abs(Xi) >= config.threshold)
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
