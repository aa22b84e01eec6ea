"""LSODA driven from compiled code: the reference integrator without Python in its loop.

SciPy's ``odeint`` calls back into Python for every right-hand-side evaluation
and is entered from Python once per sample interval (the input is held over
each interval, so LSODA restarts there). Here the loop over the intervals is
compiled by numba and calls numbalsoda's LSODA (a C++ port of the same
Hindmarsh-Petzold solver) with the model's right-hand side as a C callback
(``symrom.compiled.generated``, its ``c_rhs``). Same tolerances, step budget,
restarts, resets and divergence rule as ``integrate_lsoda``; given the same
right-hand side the two LSODA implementations give the same paths bit for bit.

numbalsoda is an optional extra (``pip install 'symrom[lsoda]'``); it builds
from source and needs a Fortran compiler (Debian: ``apt-get install gfortran``).
"""

from __future__ import annotations

import functools

import numpy as np

INSTALL_HINT = ("the compiled LSODA needs numbalsoda: pip install 'symrom[lsoda]' "
                "(it builds from source with a Fortran compiler, e.g. apt-get install gfortran)")

def available() -> bool:
    """Whether numbalsoda can be imported."""
    try:
        import numbalsoda  # noqa: F401
    except ImportError:
        return False
    return True


@functools.cache
def _driver():
    """The compiled loop over one jump's sample intervals (built once per process)."""
    try:
        import numba
        from numbalsoda import lsoda
    except ImportError as e:
        raise ImportError(INSTALL_HINT) from e

    @numba.njit
    def run(fp, x_true, v_true, params, resets, limit, dt, max_steps, rtol, atol, X, V):
        n, d = x_true.shape
        y = np.empty(2 * d)
        p = np.empty(params.shape[1])  # the callback's data, held over the interval
        te = np.array([0.0, dt])
        for k in range(n):
            if k == 0 or resets[k]:
                y[:d] = x_true[k]
                y[d:] = v_true[k]
            for i in range(2 * d):
                if not abs(y[i]) <= limit[i]:  # False for NaN too
                    return k
            X[k] = y[:d]
            V[k] = y[d:]
            if k == n - 1:
                break
            p[:] = params[k]
            sol, ok = lsoda(fp, y, te, p, rtol, atol, max_steps)
            if not ok:
                return k + 1
            y[:] = sol[1]
        return -1

    return run


def integrate(c_rhs: int, x_true: np.ndarray, v_true: np.ndarray, params: np.ndarray,
              resets: np.ndarray, limit: np.ndarray, dt: float, max_steps: int, rtol: float,
              atol: float) -> tuple[np.ndarray, np.ndarray, int]:
    """One jump, as ``integrate_lsoda``: c_rhs the address of the C right-hand side
    ``f(t, y, dy, p)``; x_true, v_true (n, d) start and reset states; params (n, m) the
    data p held over each sample (``GeneratedCode.c_params``); resets (n,) bool;
    limit (2d,). Returns X, V (n, d), NaN from the first bad sample on, and that
    sample's index (-1 if none)."""
    n, d = x_true.shape
    X, V = np.full((n, d), np.nan), np.full((n, d), np.nan)
    k = _driver()(c_rhs, np.ascontiguousarray(x_true, dtype=float), np.ascontiguousarray(v_true, dtype=float),
                  np.ascontiguousarray(params, dtype=float),
                  np.ascontiguousarray(resets, dtype=np.bool_), np.ascontiguousarray(limit, dtype=float),
                  float(dt), int(max_steps), float(rtol), float(atol), X, V)
    return X, V, int(k)
