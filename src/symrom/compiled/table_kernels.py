"""The term-table kernels themselves, compiled by numba at module level (``symrom.compiled.kernel``
reads the tables and calls them; see its docstring for what they compute).

They live at a module's top level so that numba's disk cache finds them in every process: a
function made inside another (a closure) over compiled functions is keyed by the pickled
closure, which names objects of the process that made it, so a new process never hit it and
compiled again. This module imports numba; ``kernel`` imports it only when a kernel runs.
"""

from __future__ import annotations

import numba
import numpy as np

njit = numba.njit(cache=True, fastmath=False)


@njit
def features(s, nu, terms, n_terms, kind, var, power, count, fv, dv, theta, dtheta, want_jac):
    """theta[t] and, if want_jac, dtheta[t] (2l,) for the ``n_terms`` terms t in
    ``terms`` at one state s (2l,), inputs nu (l,); fv, dv (F,) are scratch."""
    for a in range(n_terms):
        t = terms[a]
        val = 1.0
        for f in range(count[t]):
            k, i, e = kind[t, f], var[t, f], power[t, f]
            if k == 0:
                x = s[i]
                if e == 1:
                    fv[f], dv[f] = x, 1.0
                else:
                    xe = x ** (e - 1)
                    fv[f], dv[f] = xe * x, e * xe
            elif k == 1:
                fv[f] = np.sin(s[i])
                if want_jac:
                    dv[f] = np.cos(s[i])
            elif k == 2:
                fv[f] = np.cos(s[i])
                if want_jac:
                    dv[f] = -np.sin(s[i])
            else:
                fv[f], dv[f] = nu[i], 0.0
            val *= fv[f]
        theta[t] = val
        if want_jac:
            for d in range(dtheta.shape[1]):
                dtheta[t, d] = 0.0
            for f in range(count[t]):
                if kind[t, f] == 3:
                    continue
                other = 1.0
                for g in range(count[t]):
                    if g != f:
                        other *= fv[g]
                dtheta[t, var[t, f]] += other * dv[f]

@njit
def field(s, S, nu, ph, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
          theta, dtheta, fv, dv, ds, dS, want_sens):
    """ds (2l,) = f(s) and, if want_sens, dS (2l, n) = A S + B, in phase ph."""
    l = Xi.shape[2]
    features(s, nu, active[ph], n_active[ph], kind, var, power, count, fv, dv, theta, dtheta, want_sens)
    for j in range(l):
        ds[j] = s[l + j]
        acc = 0.0
        for a in range(n_active[ph]):
            q = active[ph, a]
            acc += theta[q] * Xi[ph, q, j]
        ds[l + j] = acc
    if not want_sens:
        return
    n = pk.shape[0]
    for j in range(l):
        for t in range(n):
            dS[j, t] = S[l + j, t]
    for j in range(l):
        for t in range(n):
            dS[l + j, t] = 0.0
        for d in range(2 * l):
            a_jd = 0.0
            for a in range(n_active[ph]):
                q = active[ph, a]
                a_jd += Xi[ph, q, j] * dtheta[q, d]
            if a_jd != 0.0:
                for t in range(n):
                    dS[l + j, t] += a_jd * S[d, t]
    for t in range(n):
        if pk[t] == ph:
            dS[l + pj[t], t] += theta[pp[t]]

@njit
def axpy(out, a, h, y):
    """out = a + h * y elementwise over 2-D arrays (no temporaries)."""
    for i in range(out.shape[0]):
        for t in range(out.shape[1]):
            out[i, t] = a[i, t] + h * y[i, t]

@njit
def copy2(out, a):
    """out[:, :] = a for 2-D arrays of one shape (a loop: numba's slice assignment compiles its
    shape check's error message, seconds of a cold start)."""
    for i in range(out.shape[0]):
        for t in range(out.shape[1]):
            out[i, t] = a[i, t]


@njit
def one_window(w, xi, dxi, nu, phase, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
               dt, substeps, limit, stride, want_sens, X, V, S_out, alive):
    L, l = xi.shape[1], xi.shape[2]
    p = kind.shape[0]
    n = pk.shape[0]
    h = dt / substeps
    theta = np.empty(p)
    dtheta = np.zeros((p, 2 * l))
    fv, dv = np.empty(kind.shape[1]), np.empty(kind.shape[1])
    s, st, s_new = np.empty(2 * l), np.empty(2 * l), np.empty(2 * l)
    S, Sst, S_new = np.zeros((2 * l, n)), np.zeros((2 * l, n)), np.zeros((2 * l, n))
    k1, k2, k3, k4 = np.empty(2 * l), np.empty(2 * l), np.empty(2 * l), np.empty(2 * l)
    K1, K2, K3, K4 = (np.zeros((2 * l, n)), np.zeros((2 * l, n)), np.zeros((2 * l, n)),
                      np.zeros((2 * l, n)))
    for j in range(l):
        s[j], s[l + j] = xi[w, 0, j], dxi[w, 0, j]
    ok = True
    for k in range(L):
        for j in range(l):
            X[w, k, j], V[w, k, j] = s[j], s[l + j]
        if want_sens and k % stride == 0:
            copy2(S_out[w, k // stride], S)
        alive[w, k] = ok
        if k == L - 1:
            break
        if not ok:  # left the bound: state held, sensitivities zero
            continue
        ph = phase[w, k]
        u = nu[w, k]
        for _ in range(substeps):
            field(s, S, u, ph, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                  theta, dtheta, fv, dv, k1, K1, want_sens)
            for d in range(2 * l):
                st[d] = s[d] + 0.5 * h * k1[d]
            if want_sens:
                axpy(Sst, S, 0.5 * h, K1)
            field(st, Sst, u, ph, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                  theta, dtheta, fv, dv, k2, K2, want_sens)
            for d in range(2 * l):
                st[d] = s[d] + 0.5 * h * k2[d]
            if want_sens:
                axpy(Sst, S, 0.5 * h, K2)
            field(st, Sst, u, ph, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                  theta, dtheta, fv, dv, k3, K3, want_sens)
            for d in range(2 * l):
                st[d] = s[d] + h * k3[d]
            if want_sens:
                axpy(Sst, S, h, K3)
            field(st, Sst, u, ph, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                  theta, dtheta, fv, dv, k4, K4, want_sens)
            good = True
            for d in range(2 * l):
                s_new[d] = s[d] + h / 6.0 * (k1[d] + 2.0 * k2[d] + 2.0 * k3[d] + k4[d])
                if not (np.abs(s_new[d]) <= limit[d]):  # also catches NaN
                    good = False
            if want_sens and good:
                for i in range(2 * l):
                    for t in range(n):
                        v = S[i, t] + h / 6.0 * (K1[i, t] + 2.0 * K2[i, t] + 2.0 * K3[i, t] + K4[i, t])
                        if not np.isfinite(v):
                            good = False
                        S_new[i, t] = v
            if good:
                for d in range(2 * l):
                    s[d] = s_new[d]
                if want_sens:
                    copy2(S, S_new)
            else:
                ok = False
                S[:, :] = 0.0
                break


@numba.njit(cache=True, parallel=True)
def rk4_windows(xi, dxi, nu, phase, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                dt, substeps, limit, stride, want_sens, X, V, S_out, alive):
    """Every window from its true start (windows in parallel threads)."""
    for w in numba.prange(xi.shape[0]):
        # the parallel loop's index is unsigned, the same body typed as a plain loop's signed: one
        # index type, else the window's routine compiles twice (a third of a cold build)
        one_window(np.int64(w), xi, dxi, nu, phase, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                   dt, substeps, limit, stride, want_sens, X, V, S_out, alive)

@numba.njit(cache=True, inline="always")
def program_accel(ph, s, val, fidx, nfac, coef, n_act, trig, acc):
    """acc (l,) = ddxi in phase ph at state s (2l,), by the phase's term program: val
    holds [1, s, sin s, cos s, nu] (the inputs already set), each active term a is the
    product of val[fidx[ph, a, :nfac[ph, a]]] (val[0] = 1 for the constant)."""
    n = s.shape[0]
    for i in range(n):
        x = s[i]
        val[1 + i] = x
        if trig[ph, i] & 1:
            val[1 + n + i] = np.sin(x)
        if trig[ph, i] & 2:
            val[1 + 2 * n + i] = np.cos(x)
    for j in range(acc.shape[0]):
        acc[j] = 0.0
    for a in range(n_act[ph]):
        th = val[fidx[ph, a, 0]]
        for f in range(1, nfac[ph, a]):
            th *= val[fidx[ph, a, f]]
        for j in range(acc.shape[0]):
            acc[j] += th * coef[ph, a, j]

@numba.njit(cache=True, fastmath=False, nogil=True)  # nogil: a batch's jumps run in threads (``batch``)
def rk4_rollout(x_true, v_true, nu, phase, lens, resets, fidx, nfac, coef, n_act, trig,
                dt, substeps, limit, X, V, div_at):
    """J jumps from their true start, reset to the truth where ``resets``; the
    semantics of ``symrom.rollout.integrate.integrate_rk4`` (NaN from the first
    bad sample on, whose index goes to div_at). The model is given as per-phase
    term programs (``term_programs``)."""
    J, _, l = x_true.shape
    h = dt / substeps
    val = np.ones(1 + 7 * l)
    s, st = np.empty(2 * l), np.empty(2 * l)
    k1, k2, k3, k4 = np.empty(l), np.empty(l), np.empty(l), np.empty(l)
    v2, v3 = np.empty(l), np.empty(l)
    for j in range(J):
        div_at[j] = -1
        for k in range(lens[j]):
            if k == 0 or resets[k]:
                for d in range(l):
                    s[d], s[l + d] = x_true[j, k, d], v_true[j, k, d]
            ok = True
            for d in range(2 * l):
                if not (np.abs(s[d]) <= limit[j, d]):
                    ok = False
            if not ok:
                div_at[j] = k
                break
            for d in range(l):
                X[j, k, d], V[j, k, d] = s[d], s[l + d]
            if k == lens[j] - 1:
                break
            ph = phase[j, k]
            for d in range(l):
                val[1 + 6 * l + d] = nu[j, k, d]
            for _ in range(substeps):
                program_accel(ph, s, val, fidx, nfac, coef, n_act, trig, k1)
                for d in range(l):
                    st[d] = s[d] + 0.5 * h * s[l + d]
                    st[l + d] = s[l + d] + 0.5 * h * k1[d]
                program_accel(ph, st, val, fidx, nfac, coef, n_act, trig, k2)
                for d in range(l):
                    v2[d] = st[l + d]
                    st[d] = s[d] + 0.5 * h * v2[d]
                    st[l + d] = s[l + d] + 0.5 * h * k2[d]
                program_accel(ph, st, val, fidx, nfac, coef, n_act, trig, k3)
                for d in range(l):
                    v3[d] = st[l + d]
                    st[d] = s[d] + h * v3[d]
                    st[l + d] = s[l + d] + h * k3[d]
                program_accel(ph, st, val, fidx, nfac, coef, n_act, trig, k4)
                for d in range(l):
                    v4 = st[l + d]
                    s[d] = s[d] + h / 6.0 * (s[l + d] + 2.0 * v2[d] + 2.0 * v3[d] + v4)
                    s[l + d] = s[l + d] + h / 6.0 * (k1[d] + 2.0 * k2[d] + 2.0 * k3[d] + k4[d])
