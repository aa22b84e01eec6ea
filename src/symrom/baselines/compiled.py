"""The aSLIP's fixed-step RK4 rollout, compiled by numba (the ``compiled`` integrator of its
``RolloutSystem``, see ``symrom.rollout.system``).

The rollout fit of the aSLIP (``fit_aslip_rollout``) integrates every training jump a few hundred
times; from NumPy each RK4 stage is a call over all jumps at once, so the fit spends its time in
the interpreter. This kernel does the same arithmetic in the same order as
``aslip_acceleration`` inside ``symrom.rollout.integrate.integrate_rk4``, jump by jump, and
gives the same paths bit for bit (``tests/test_baselines.py``). numba is imported with this
module only, and its disk cache keeps the compiled code between processes.
"""

from __future__ import annotations

import numba
import numpy as np

njit = numba.njit(cache=True, fastmath=False)


@njit
def _acceleration(k_m, l_0, g, x, pivot, u, contact, out):
    """out (3,) m/s^2: the aSLIP's b'' at CoM x (3,) m, as ``aslip_acceleration`` computes it;
    k_m = k_s / m (1/s^2), g (3,) m/s^2."""
    l0, l1, l2 = x[0] - pivot[0], x[1] - pivot[1], x[2] - pivot[2]
    r = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    rr = max(r, 1e-9)
    s = k_m * abs(l_0 - r)
    c = 1.0 if contact else 0.0
    out[0] = g[0] + c * (s * (l0 / rr) + u[0])
    out[1] = g[1] + c * (s * (l1 / rr) + u[1])
    out[2] = g[2] + c * (s * (l2 / rr) + u[2])


@njit
def aslip_rk4(k_m, l_0, g, x_true, v_true, u, pivot, contact, lens, resets, limit, dt, substeps):
    """J jumps of the aSLIP with classical RK4, ``substeps`` steps per sample period dt (s).

    x_true, v_true (J, n_max, 3) padded start and reset states (m, m/s); u, pivot (J, n_max, 3),
    contact (J, n_max) bool, the drive held over each sample; lens (J,); resets (n_max,) bool;
    limit (J, 6). Returns X, V (J, n_max, 3), NaN from the first sample out of bounds on (and past
    each jump's length), and that sample per jump (J,), -1 if none."""
    J, n_max = x_true.shape[0], x_true.shape[1]
    X = np.full((J, n_max, 3), np.nan)
    V = np.full((J, n_max, 3), np.nan)
    div_at = np.full(J, -1)
    h = dt / substeps
    h2, h6 = h / 2, h / 6
    x, v = np.empty(3), np.empty(3)
    xs, vs = np.empty(3), np.empty(3)
    k1x, k2x, k3x, k4x = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    k1v, k2v, k3v, k4v = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for j in range(J):
        for a in range(3):
            x[a], v[a] = x_true[j, 0, a], v_true[j, 0, a]
        for k in range(lens[j]):
            if resets[k]:
                for a in range(3):
                    x[a], v[a] = x_true[j, k, a], v_true[j, k, a]
            ok = True
            for a in range(3):
                if not (np.isfinite(x[a]) and np.isfinite(v[a]) and abs(x[a]) <= limit[j, a]
                        and abs(v[a]) <= limit[j, 3 + a]):
                    ok = False
            if not ok:
                div_at[j] = k
                break
            for a in range(3):
                X[j, k, a], V[j, k, a] = x[a], v[a]
            if k == lens[j] - 1:
                break
            p, f, c = pivot[j, k], u[j, k], contact[j, k]
            for _ in range(substeps):
                _acceleration(k_m, l_0, g, x, p, f, c, k1v)
                for a in range(3):
                    k1x[a] = v[a]
                    xs[a], vs[a] = x[a] + h2 * k1x[a], v[a] + h2 * k1v[a]
                _acceleration(k_m, l_0, g, xs, p, f, c, k2v)
                for a in range(3):
                    k2x[a] = v[a] + h2 * k1v[a]
                    xs[a], vs[a] = x[a] + h2 * k2x[a], v[a] + h2 * k2v[a]
                _acceleration(k_m, l_0, g, xs, p, f, c, k3v)
                for a in range(3):
                    k3x[a] = v[a] + h2 * k2v[a]
                    xs[a] = x[a] + h * k3x[a]
                _acceleration(k_m, l_0, g, xs, p, f, c, k4v)
                for a in range(3):
                    k4x[a] = v[a] + h * k3v[a]
                    x[a] = x[a] + h6 * (k1x[a] + 2 * k2x[a] + 2 * k3x[a] + k4x[a])
                    v[a] = v[a] + h6 * (k1v[a] + 2 * k2v[a] + 2 * k3v[a] + k4v[a])
    return X, V, div_at
