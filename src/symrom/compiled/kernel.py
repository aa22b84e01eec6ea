"""Compiled evaluation of the latent dynamics (numba), from the terms' factor table.

Every term of the paper's library is a product of simple factors of one
variable: a power of a state variable, sin or cos of one, or an input. The
term table reads those factors off each term's sympy form (``TermLibrary``, the
one place a library states its terms), so any library made of such terms is
evaluated by one compiled routine, whatever its blocks; a library with other
terms (``Custom`` expressions beyond products of these factors) has no table
and runs on the NumPy path.

``table_integrator`` (the ``table`` backend of the rollouts, the default) reads the
table as per-phase term programs (``term_programs``): each active term is the
list of its factors' places in [1, s, sin s, cos s, nu], the sines and cosines a
phase uses are evaluated once per stage, and the coefficients are stored by
active term. ``rollout_windows`` rolls many windows of the hybrid latent model out at once
with classical Runge-Kutta, optionally with the exact parameter
sensitivities (see ``symrom.learn.shooting``, whose NumPy implementation is
the reference this kernel is tested against). Functions are compiled on first
use and cached on disk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy

from symrom.compiled.dynamics import TermLibrary

STATE_POWER, SIN, COS, INPUT = 0, 1, 2, 3


@dataclass(frozen=True)
class TermTable:
    """Factors of each of the p terms: kind (p, F) of ``STATE_POWER``, ``SIN``, ``COS``,
    ``INPUT``; var (p, F) index into s = [xi, dxi] (or into nu for inputs); power
    (p, F); count (p,) factors used (0 for the constant)."""

    kind: np.ndarray
    var: np.ndarray
    power: np.ndarray
    count: np.ndarray


_TABLES: dict[str, TermTable | None] = {}  # identity of a term library -> its table (read once)
TABLES_KEPT = 64


def term_table(terms: TermLibrary) -> TermTable | None:
    """The factor table of ``terms``, or None if a term is not a product of simple factors
    (kept for the last ``TABLES_KEPT`` libraries: reading it walks every term's sympy form)."""
    if terms.identity in _TABLES:
        return _TABLES[terms.identity]
    table = _read_table(terms)
    if len(_TABLES) >= TABLES_KEPT:
        _TABLES.pop(next(iter(_TABLES)))
    _TABLES[terms.identity] = table
    return table


def _read_table(terms: TermLibrary) -> TermTable | None:
    s_index = {v: i for i, v in enumerate(terms.state)}
    nu_index = {v: i for i, v in enumerate(terms.inputs)}
    rows = []
    for expr in terms.features:
        factors = []
        coeff, parts = expr.as_coeff_mul()
        if coeff != 1:
            return None
        for f in parts:
            base, exp = f.as_base_exp()
            if base in s_index and exp.is_Integer and exp > 0:
                factors.append((STATE_POWER, s_index[base], int(exp)))
            elif base in nu_index and exp == 1:
                factors.append((INPUT, nu_index[base], 1))
            elif isinstance(f, (sympy.sin, sympy.cos)) and f.args[0] in s_index:
                factors.append((SIN if isinstance(f, sympy.sin) else COS, s_index[f.args[0]], 1))
            else:
                return None
        rows.append(factors)
    F = max(1, max(len(r) for r in rows))
    p = len(rows)
    kind, var, power = (np.zeros((p, F), dtype=np.int64) for _ in range(3))
    count = np.array([len(r) for r in rows], dtype=np.int64)
    for t, r in enumerate(rows):
        for f, (k, v, e) in enumerate(r):
            kind[t, f], var[t, f], power[t, f] = k, v, e
    return TermTable(kind, var, power, count)


def _numba():
    import numba

    return numba


_KERNELS: dict[str, object] = {}


def kernels():
    """The compiled routines (compiled once per process, cached on disk)."""
    if _KERNELS:
        return _KERNELS
    numba = _numba()
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
                S_out[w, k // stride] = S
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
                    s[:] = s_new
                    if want_sens:
                        S[:, :] = S_new
                else:
                    ok = False
                    S[:, :] = 0.0
                    break

    @numba.njit(cache=True, parallel=True)
    def rk4_windows(xi, dxi, nu, phase, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
                    dt, substeps, limit, stride, want_sens, X, V, S_out, alive):
        """Every window from its true start (windows in parallel threads)."""
        for w in numba.prange(xi.shape[0]):
            one_window(w, xi, dxi, nu, phase, Xi, kind, var, power, count, pk, pp, pj, active, n_active,
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

    @njit
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

    _KERNELS.update(features=features, rk4_windows=rk4_windows, rk4_rollout=rk4_rollout)
    return _KERNELS


def term_programs(table: TermTable, Xi: np.ndarray) -> tuple[np.ndarray, ...]:
    """The model as per-phase programs for the compiled RK4: every active term as the
    list of its factors, indices into v = [1, s (2l), sin s (2l), cos s (2l), nu (l)].

    Returns fidx (P, A, W) factor indices (0, the constant 1, pads), nfac (P, A) factors
    per term, coef (P, A, l) the terms' coefficients, n_act (P,) active terms per phase
    and trig (P, 2l) which sin (bit 1) and cos (bit 2) each phase uses.
    """
    P, p, l = Xi.shape
    n = 2 * l
    active, n_act = active_terms(Xi != 0)
    lists = []
    for t in range(p):
        f = []
        for c in range(table.count[t]):
            kind, var, power = table.kind[t, c], table.var[t, c], table.power[t, c]
            if kind == STATE_POWER:
                f += [1 + var] * int(power)
            elif kind == SIN:
                f.append(1 + n + var)
            elif kind == COS:
                f.append(1 + 2 * n + var)
            else:
                f.append(1 + 3 * n + var)
        lists.append(f or [0])
    A = max(1, int(n_act.max()))
    W = max(len(f) for f in lists)
    fidx = np.zeros((P, A, W), dtype=np.int64)
    nfac = np.zeros((P, A), dtype=np.int64)
    coef = np.zeros((P, A, l))
    trig = np.zeros((P, n), dtype=np.int64)
    for ph in range(P):
        for a in range(n_act[ph]):
            t = active[ph, a]
            fidx[ph, a, :len(lists[t])] = lists[t]
            nfac[ph, a] = len(lists[t])
            coef[ph, a] = Xi[ph, t]
            for c in lists[t]:
                if 1 + n <= c < 1 + 2 * n:
                    trig[ph, c - 1 - n] |= 1
                elif 1 + 2 * n <= c < 1 + 3 * n:
                    trig[ph, c - 1 - 2 * n] |= 2
    return fidx, nfac, coef, n_act, trig


_PROGRAMS: dict = {}  # (identity of the terms, Xi bytes) -> integrator: a path's set-up made once
PROGRAMS_KEPT = 32


def table_integrator(terms: TermLibrary, Xi: np.ndarray):
    """An integrator of the hybrid latent model with coefficients Xi (P, p, l) over ``terms``
    for ``symrom.rollout.integrate`` (``RolloutSystem.compiled``), or None if the terms
    have no table or numba is not installed. Kept for the last ``PROGRAMS_KEPT`` (terms,
    Xi): setting the programs up costs more than a short path (``predict_path``) takes to
    integrate."""
    key = (terms.identity, np.ascontiguousarray(Xi, dtype=float).tobytes())
    if key in _PROGRAMS:
        return _PROGRAMS[key]
    fn = _table_integrator(terms, Xi)
    if len(_PROGRAMS) >= PROGRAMS_KEPT:
        _PROGRAMS.pop(next(iter(_PROGRAMS)))
    _PROGRAMS[key] = fn
    return fn


def _table_integrator(terms: TermLibrary, Xi: np.ndarray):
    table = term_table(terms)
    if table is None:
        return None
    try:
        k = kernels()["rk4_rollout"]
    except ImportError:
        return None
    program = term_programs(table, np.ascontiguousarray(Xi, dtype=float))

    def integrate(x_true, v_true, drive, lens, resets, limit, dt, substeps):
        """Padded (J, n_max, l) truth, drive {nu (J, n_max, l), phase (J, n_max)} ->
        X, V (J, n_max, l) with NaN after a divergence, div_at (J,)."""
        J, n_max, l = x_true.shape
        X, V = np.full((J, n_max, l), np.nan), np.full((J, n_max, l), np.nan)
        div_at = np.full(J, -1, dtype=np.int64)
        k(np.ascontiguousarray(x_true, dtype=float), np.ascontiguousarray(v_true, dtype=float),
          np.ascontiguousarray(drive["nu"], dtype=float), np.ascontiguousarray(drive["phase"], dtype=np.int64),
          np.asarray(lens, dtype=np.int64), np.asarray(resets, dtype=np.bool_), *program, float(dt),
          int(substeps), np.ascontiguousarray(np.broadcast_to(limit, (J, 2 * l)), dtype=float), X, V, div_at)
        return X, V, div_at

    return integrate


@dataclass(frozen=True)
class WindowRollout:
    """W windows of at most L samples rolled out from their true starts: X, V (W, L, l);
    S (W, ceil(L / stride), 2l, n) the sensitivities of [xi, dxi] to the n parameters at
    every ``stride``-th sample (None unless asked for); alive (W, L) bool: False from the
    first sample at which a window left its bound (its state then held, its S zeroed)."""

    X: np.ndarray
    V: np.ndarray
    S: np.ndarray | None
    alive: np.ndarray


def rollout_windows(terms: TermLibrary, Xi: np.ndarray, phase: np.ndarray, term: np.ndarray, latent: np.ndarray,
                    xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray, window_phase: np.ndarray, dt: float,
                    limit: np.ndarray, substeps: int = 1, sensitivities: bool = True,
                    stride: int = 1) -> WindowRollout | None:
    """Every window from its true start by the term-table kernel, or None if ``terms`` have
    no table.

    Xi (P, p, l): every coefficient (nonzero entries outside the parameters act, held
    fixed); phase, term, latent (n,): the parameters' places in Xi; xi, dxi (W, L, l): the
    true latent state (sample 0 starts the window); nu (W, L, l) and window_phase (W, L):
    the drive held over each sample; dt: s; limit (2l,): bound on |[xi, dxi]|; substeps:
    RK4 steps per sample; stride: samples between stored sensitivities."""
    table = term_table(terms)
    if table is None:
        return None
    k = kernels()["rk4_windows"]
    W, L, l = np.shape(xi)
    n = len(phase)
    X, V = np.zeros((W, L, l)), np.zeros((W, L, l))
    S = np.zeros((W, -(-L // stride), 2 * l, n))
    alive = np.zeros((W, L), dtype=np.bool_)
    support = np.asarray(Xi) != 0  # coefficients held fixed (not parameters) act too
    support[phase, term, latent] = True  # a coefficient at 0.0 still needs its term
    active, n_active = active_terms(support)
    k(np.ascontiguousarray(xi), np.ascontiguousarray(dxi), np.ascontiguousarray(nu),
      np.ascontiguousarray(window_phase, dtype=np.int64), np.ascontiguousarray(Xi, dtype=float),
      table.kind, table.var, table.power, table.count, np.asarray(phase).astype(np.int64),
      np.asarray(term).astype(np.int64), np.asarray(latent).astype(np.int64), active, n_active,
      float(dt), int(substeps), np.asarray(limit, dtype=float), int(stride), bool(sensitivities),
      X, V, S, alive)
    return WindowRollout(X, V, S if sensitivities else None, alive)


def active_terms(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per phase the terms with any nonzero coefficient: (P, p) indices, (P,) counts."""
    used = mask.any(axis=2)
    P, p = used.shape
    active = np.zeros((P, p), dtype=np.int64)
    n = np.zeros(P, dtype=np.int64)
    for k in range(P):
        idx = np.flatnonzero(used[k])
        active[k, :idx.size] = idx
        n[k] = idx.size
    return active, n
