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

from symrom.compiled.batch import rollout_jumps
from symrom.compiled.dynamics import TermLibrary
from symrom.execution import kernel_threads

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


_KERNELS: dict[str, object] = {}


def kernels():
    """The compiled routines (``table_kernels``: compiled once per installation and loaded from
    numba's disk cache by later processes)."""
    if not _KERNELS:
        from symrom.compiled import table_kernels as tk

        _KERNELS.update(rk4_windows=tk.rk4_windows, rk4_rollout=tk.rk4_rollout)
    return _KERNELS


def routines() -> list:
    """The numba dispatchers of this package that every model with a term table runs: the
    table kernels (refinement windows, rollouts) and the autoencoder's maps (for
    ``symrom.experiments.warm``, which makes them ready ahead)."""
    from symrom.compiled.codec import _kernels

    return [*kernels().values(), *_kernels().values()]


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
        X, V = np.full(x_true.shape, np.nan), np.full(x_true.shape, np.nan)
        return X, V, rollout_jumps(k, x_true, v_true, drive, lens, resets, limit, dt, substeps, X, V, program)

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
    import numba

    numba.set_num_threads(min(kernel_threads(), numba.config.NUMBA_NUM_THREADS))  # the process's share
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


def warm_windows() -> None:
    """Compile (or load from numba's disk cache) the refinement's window kernel for the argument
    types ``rollout_windows`` passes it, on one window of two samples; one process at a time
    (``execution.compile_lock``): a helper started while another compiles it waits and loads."""
    from symrom.execution import compile_lock

    f, i = np.zeros, np.int64
    one = np.zeros(1, dtype=i)
    k = kernels()["rk4_windows"]
    with compile_lock(k):
        k(f((1, 2, 1)), f((1, 2, 1)), f((1, 2, 1)), np.zeros((1, 2), dtype=i), f((1, 1, 1)),
          np.zeros((1, 1), dtype=i), np.zeros((1, 1), dtype=i), np.ones((1, 1), dtype=i), one, one, one, one,
          np.zeros((1, 1), dtype=i), np.ones(1, dtype=i), 0.002, 1, np.ones(2), 1, True, f((1, 2, 1)), f((1, 2, 1)),
          f((1, 2, 2, 1)), np.zeros((1, 2), dtype=np.bool_))


def start_windows_helper():
    """A process compiling the window kernel into numba's disk cache, so that the refinements'
    workers load it instead of each compiling it, as a ``subprocess.Popen``; None where the cache
    already holds it (the workers load it; a process would only start and wait) or no process can
    be started."""
    from symrom.execution import in_disk_cache, start_helper

    if in_disk_cache(kernels()["rk4_windows"]):
        return None
    return start_helper("from symrom.compiled.kernel import warm_windows; warm_windows()")
