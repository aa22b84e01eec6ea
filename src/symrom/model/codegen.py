"""Per-model compiled rollouts: the model's equations written out as code, compiled by numba.

``symrom.model.kernel`` evaluates any model of simple-factor terms with one
compiled routine that reads a term table: no compilation per model, which is
what a selection over hundreds of candidates needs. For one model rolled out
many times (evaluation, a planner, the benchmark) this module writes the
model's equations themselves as straight-line code (sympy's Python printer,
common subexpressions shared, only the active terms, each phase its own
branch), so a step costs a few dozen floating-point operations and the trig
functions it really uses. Compiling takes about a second per model; the
result is cached per model (its library and coefficients) in this process.

``generated_integrator(model)`` has the interface of
``symrom.model.kernel.compiled_rollout`` (``RolloutSystem.compiled``), with
the semantics of ``symrom.rollout.integrate.integrate_rk4``;
``generated_rhs(model)`` is the right-hand side for SciPy's LSODA.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections import OrderedDict

import numpy as np
import sympy
from sympy.printing.pycode import PythonCodePrinter

from symrom.model.export import dynamics_expressions
from symrom.model.hybrid import HybridModel
from symrom.model.library import symbols

_CACHE: OrderedDict[str, dict] = OrderedDict()
CACHE_SIZE = 16  # compiled models kept per process

_RK4 = '''
def rollout(x_true, v_true, nu, phase, lens, resets, dt, substeps, limit, X, V, div_at):
    J, n_max, l = x_true.shape
    h = dt / substeps
    s = np.empty(2 * l)
    k1, k2, k3, k4 = np.empty(l), np.empty(l), np.empty(l), np.empty(l)
    st = np.empty(2 * l)
    for j in range(J):
        div_at[j] = -1
        for k in range(lens[j]):
            if k == 0 or resets[k]:
                for d in range(l):
                    s[d] = x_true[j, k, d]
                    s[l + d] = v_true[j, k, d]
            ok = True
            for d in range(2 * l):
                if not (abs(s[d]) <= limit[j, d]):  # also catches NaN
                    ok = False
            if not ok:
                div_at[j] = k
                break
            for d in range(l):
                X[j, k, d] = s[d]
                V[j, k, d] = s[l + d]
            if k == lens[j] - 1:
                break
            ph = phase[j, k]
            u = nu[j, k]
            for _ in range(substeps):
                # classical RK4 on (x, v): the position stages use the velocity stages
                accel(ph, s, u, k1)
                for d in range(l):
                    st[d] = s[d] + 0.5 * h * s[l + d]
                    st[l + d] = s[l + d] + 0.5 * h * k1[d]
                accel(ph, st, u, k2)
                for d in range(l):
                    st[d] = s[d] + 0.5 * h * (s[l + d] + 0.5 * h * k1[d])
                    st[l + d] = s[l + d] + 0.5 * h * k2[d]
                accel(ph, st, u, k3)
                for d in range(l):
                    st[d] = s[d] + h * (s[l + d] + 0.5 * h * k2[d])
                    st[l + d] = s[l + d] + h * k3[d]
                accel(ph, st, u, k4)
                for d in range(l):
                    v = s[l + d]
                    s[d] = s[d] + h / 6.0 * (v + 2.0 * (v + 0.5 * h * k1[d]) + 2.0 * (v + 0.5 * h * k2[d])
                                            + (v + h * k3[d]))
                    s[l + d] = v + h / 6.0 * (k1[d] + 2.0 * k2[d] + 2.0 * k3[d] + k4[d])


def rhs(y, t, ph, u):
    l = u.shape[0]
    out = np.empty(2 * l)
    out[:l] = y[l:]
    accel(ph, y, u, out[l:])
    return out
'''


def model_source(model: HybridModel) -> str:
    """Python source of ``accel(ph, s, nu, out)``: ddxi (l,) into ``out`` for phase index
    ``ph`` at state s = [xi, dxi] (2l,) and inputs nu (l,); then the RK4 rollout and
    the LSODA right-hand side that call it."""
    l = model.latent_dim
    s, nu = symbols(l)
    sub = {v: sympy.Symbol(f"s{i}") for i, v in enumerate(s)} | {v: sympy.Symbol(f"u{i}") for i, v in enumerate(nu)}
    printer = PythonCodePrinter({"fully_qualified_modules": True})
    lines = ["def accel(ph, s, nu, out):"]
    lines += [f"    s{i} = s[{i}]" for i in range(2 * l)] + [f"    u{i} = nu[{i}]" for i in range(l)]
    for k, rows in enumerate(dynamics_expressions(model)):
        repl, reduced = sympy.cse([e.xreplace(sub) for e in rows], symbols=sympy.numbered_symbols("c"))
        lines.append(f"    {'if' if k == 0 else 'elif'} ph == {k}:  # {model.phase_names[k]}")
        lines += [f"        {v} = {printer.doprint(e)}" for v, e in repl]
        lines += [f"        out[{j}] = {printer.doprint(e)}" for j, e in enumerate(reduced)]
    return "\n".join(lines) + "\n" + _RK4


def _key(model: HybridModel) -> str:
    h = hashlib.sha256(repr(model.library.to_dict()).encode())
    h.update(np.ascontiguousarray(model.Xi, dtype=float).tobytes())
    return h.hexdigest()


def _compiled(model: HybridModel) -> dict:
    """The compiled functions of ``model`` (cached) and the seconds the compilation took."""
    key = _key(model)
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    import numba

    t0 = time.perf_counter()
    ns: dict = {"math": math, "np": np}
    exec(compile(model_source(model), f"<symrom model {key[:12]}>", "exec"), ns)  # noqa: S102 - our own source
    accel = numba.njit(ns["accel"])
    ns["accel"] = accel
    rollout, rhs = numba.njit(ns["rollout"]), numba.njit(ns["rhs"])
    l = model.latent_dim
    z = np.zeros((1, 2, l))
    # Compile for the argument types the integrators pass, so that the first real call is fast.
    rollout(z, z, z, np.zeros((1, 2), np.int64), np.array([2], np.int64), np.ones(2, np.bool_), 0.002, 1,
            np.ones((1, 2 * l)), z.copy(), z.copy(), np.zeros(1, np.int64))
    rhs(np.zeros(2 * l), 0.0, 0, np.zeros(l))
    entry = {"rollout": rollout, "rhs": rhs, "compile_s": time.perf_counter() - t0}
    _CACHE[key] = entry
    while len(_CACHE) > CACHE_SIZE:
        _CACHE.popitem(last=False)
    return entry


def compile_seconds(model: HybridModel) -> float:
    """Seconds the compilation of ``model`` took (compiling it now if needed)."""
    return _compiled(model)["compile_s"]


def generated_integrator(model: HybridModel):
    """An RK4 integrator of ``model`` with the interface of ``kernel.compiled_rollout``."""
    fn = _compiled(model)["rollout"]

    def integrate(x_true, v_true, drive, lens, resets, limit, dt, substeps):
        J, n_max, l = x_true.shape
        X, V = np.full((J, n_max, l), np.nan), np.full((J, n_max, l), np.nan)
        div_at = np.full(J, -1, dtype=np.int64)
        fn(np.ascontiguousarray(x_true, dtype=float), np.ascontiguousarray(v_true, dtype=float),
           np.ascontiguousarray(drive["nu"], dtype=float), np.ascontiguousarray(drive["phase"], dtype=np.int64),
           np.asarray(lens, dtype=np.int64), np.asarray(resets, dtype=np.bool_), float(dt), int(substeps),
           np.ascontiguousarray(np.broadcast_to(limit, (J, 2 * l)), dtype=float), X, V, div_at)
        return X, V, div_at

    return integrate


def generated_rhs(model: HybridModel):
    """``rhs(y (2l,), t, phase index, nu (l,)) -> dy/dt (2l,)``, compiled, for SciPy's LSODA."""
    return _compiled(model)["rhs"]
