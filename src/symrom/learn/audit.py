"""Which candidate terms a phase's rows can tell apart.

Over the small range a latent coordinate spans in one phase, ``xi`` and
``sin(xi)`` are nearly the same column, and ``cos(xi)`` nearly the constant.
Least squares then splits one effect between such a pair with large
coefficients of opposite sign that cancel on the data and mean nothing. The
audit keeps one term of every near-collinear pair, the simpler one by the
library's ranks (constant, single state variable, input, monomial, trig,
custom), and records each term left out with the term it duplicates.

Correlation between two columns is Pearson's (centred) when both vary, and the
uncentred cosine when one is constant: |cos| between c and the constant is
mean(c) / rms(c), above 0.995 when c varies by less than 10 % of its size.
"""

from __future__ import annotations

import numpy as np

NULL_TERM = 1e-10  # a column this small relative to the largest carries rounding only


def negligible(norms: np.ndarray) -> np.ndarray:
    """(p,) bool: column norms (p,) that are rounding next to the largest."""
    norms = np.asarray(norms, dtype=float)
    return norms <= NULL_TERM * max(float(norms.max()), 1e-300)


def null_terms(theta: np.ndarray) -> np.ndarray:
    """(p,) bool: columns of theta (N, p) that are zero up to rounding."""
    return negligible(np.sqrt(np.mean(np.square(theta), axis=0)))


def correlations(theta: np.ndarray) -> np.ndarray:
    """(p, p) |correlation| of the columns of theta (N, p); see the module docstring."""
    theta = np.asarray(theta, dtype=float)
    rms = np.sqrt(np.mean(theta ** 2, axis=0))
    std = theta.std(axis=0)
    varies = std > 1e-9 * np.maximum(rms, 1e-300)
    safe_rms = np.where(rms > 0, rms, 1.0)
    cos = np.abs(theta.T @ theta) / theta.shape[0] / np.outer(safe_rms, safe_rms)
    centred = (theta - theta.mean(axis=0)) / np.where(varies, std, 1.0)
    pearson = np.abs(centred.T @ centred) / theta.shape[0]
    both = np.outer(varies, varies)
    return np.clip(np.where(both, pearson, cos), 0.0, 1.0)


def audit_collinearity(theta: np.ndarray, names: list[str], ranks: np.ndarray, threshold: float,
                       keep: np.ndarray | None = None) -> tuple[np.ndarray, list[dict]]:
    """Leave out every term near-collinear (|corr| > threshold) with a simpler kept one.

    theta (N, p) on one phase's rows; ranks (p,) preference (lower kept first);
    keep (p,) bool: terms still candidates (default all). Returns the new keep
    mask and one record per term left out: its name, the kept term it
    duplicates and their correlation.
    """
    p = theta.shape[1]
    keep = np.ones(p, dtype=bool) if keep is None else keep.copy()
    corr = correlations(theta)
    kept: list[int] = []
    dropped = []
    for i in sorted(np.flatnonzero(keep), key=lambda i: (ranks[i], i)):
        twin = next((k for k in kept if corr[i, k] > threshold), None)
        if twin is None:
            kept.append(i)
            continue
        keep[i] = False
        dropped.append({"term": names[i], "reason": "near-collinear", "with": names[twin],
                        "correlation": round(float(corr[i, twin]), 6)})
    return keep, dropped
