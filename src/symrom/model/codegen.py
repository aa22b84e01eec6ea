"""Per-model compiled rollouts: the model's equations written out as code, compiled by numba.

``symrom.model.kernel`` evaluates any model of simple-factor terms with one
compiled routine that reads a term table: no compilation per model, which is
what a selection over hundreds of candidates needs. For one model rolled out
many times (evaluation, a planner, the benchmark) this module writes the
model's equations themselves as straight-line code (sympy's Python printer,
common subexpressions shared, only the active terms, each phase its own
branch, the latent state held in scalar variables), so a step costs a few dozen
floating-point operations and the trig functions it really uses. Compiling takes about a second per model; the
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

def _rk4_source(l: int) -> str:
    """Python source of ``rollout`` (the RK4 integrator of ``generated_integrator``) and
    ``rhs`` (LSODA's right-hand side) for latent dimension l: the state is held in 2l
    scalar variables and every loop over it is written out, so that the compiled step
    is straight-line code."""
    n = 2 * l
    S = [f"s{i}" for i in range(n)]
    U = [f"u{i}" for i in range(l)]
    T = [f"t{i}" for i in range(n)]

    def call(args: list[str], out: str) -> str:
        lhs = ", ".join(f"{out}{d}" for d in range(l)) + ("," if l == 1 else "")
        return f"{lhs} = accel_s(ph, {', '.join(args + U)})"

    # classical RK4 on (x, v): k1 = (v, a), k2 = (w, b), k3 = (y, c), k4 = (v + h c, e)
    step = [call(S, "a")]
    step += [f"t{d} = s{d} + 0.5 * h * s{l + d}" for d in range(l)]
    step += [f"t{l + d} = s{l + d} + 0.5 * h * a{d}" for d in range(l)]
    step += [call(T, "b")] + [f"w{d} = t{l + d}" for d in range(l)]
    step += [f"t{d} = s{d} + 0.5 * h * w{d}" for d in range(l)]
    step += [f"t{l + d} = s{l + d} + 0.5 * h * b{d}" for d in range(l)]
    step += [call(T, "c")] + [f"y{d} = t{l + d}" for d in range(l)]
    step += [f"t{d} = s{d} + h * y{d}" for d in range(l)]
    step += [f"t{l + d} = s{l + d} + h * c{d}" for d in range(l)]
    step += [call(T, "e")]
    step += [f"s{d} = s{d} + h / 6.0 * (s{l + d} + 2.0 * w{d} + 2.0 * y{d} + t{l + d})" for d in range(l)]
    step += [f"s{l + d} = s{l + d} + h / 6.0 * (a{d} + 2.0 * b{d} + 2.0 * c{d} + e{d})" for d in range(l)]
    ind = " " * 16
    bound = " and ".join(f"abs(s{i}) <= limit[j, {i}]" for i in range(n))  # False for NaN too
    nl = "\n"
    return f"""
def rollout(x_true, v_true, nu, phase, lens, resets, dt, substeps, limit, X, V, div_at):
    h = dt / substeps
    for j in range(x_true.shape[0]):
        div_at[j] = -1
        {" = ".join(S)} = 0.0
        for k in range(lens[j]):
            if k == 0 or resets[k]:
{nl.join(f"{ind}s{d} = x_true[j, k, {d}]" for d in range(l))}
{nl.join(f"{ind}s{l + d} = v_true[j, k, {d}]" for d in range(l))}
            if not ({bound}):
                div_at[j] = k
                break
{nl.join(f"            X[j, k, {d}] = s{d}" for d in range(l))}
{nl.join(f"            V[j, k, {d}] = s{l + d}" for d in range(l))}
            if k == lens[j] - 1:
                break
            ph = phase[j, k]
{nl.join(f"            u{d} = nu[j, k, {d}]" for d in range(l))}
            for _ in range(substeps):
{nl.join(ind + line for line in step)}


def accel(ph, s, nu, out):
    r = accel_s(ph, {", ".join(f"s[{i}]" for i in range(n))}, {", ".join(f"nu[{d}]" for d in range(l))})
{nl.join(f"    out[{d}] = r[{d}]" for d in range(l))}


def rhs(y, t, ph, u):
    out = np.empty({n})
{nl.join(f"    out[{d}] = y[{l + d}]" for d in range(l))}
    accel(ph, y, u, out[{l}:])
    return out
"""


def model_source(model: HybridModel) -> str:
    """Python source of ``accel_s(ph, s0, ..., s_{2l-1}, u0, ..., u_{l-1})``: the tuple
    ddxi (l,) in phase index ``ph`` at the state s = [xi, dxi] with inputs nu (NaN for
    an unknown phase), ``accel(ph, s, nu, out)`` writing it into ``out``, then the RK4
    rollout and the LSODA right-hand side that call it."""
    l = model.latent_dim
    s, nu = symbols(l)
    sub = {v: sympy.Symbol(f"s{i}") for i, v in enumerate(s)} | {v: sympy.Symbol(f"u{i}") for i, v in enumerate(nu)}
    printer = PythonCodePrinter({"fully_qualified_modules": True})
    tail = "," if l == 1 else ""
    lines = [f"def accel_s(ph, {', '.join([f's{i}' for i in range(2 * l)] + [f'u{i}' for i in range(l)])}):"]
    for k, rows in enumerate(dynamics_expressions(model)):
        repl, reduced = sympy.cse([e.xreplace(sub) for e in rows], symbols=sympy.numbered_symbols("c"))
        lines.append(f"    {'if' if k == 0 else 'elif'} ph == {k}:  # {model.phase_names[k]}")
        lines += [f"        {v} = {printer.doprint(e)}" for v, e in repl]
        lines.append(f"        return {', '.join(f'float({printer.doprint(e)})' for e in reduced)}{tail}")
    lines.append(f"    return {', '.join(['math.nan'] * l)}{tail}")
    return "\n".join(lines) + "\n" + _rk4_source(l)


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
    for name in ("accel_s", "accel"):  # compiled before the functions that call them
        ns[name] = numba.njit(ns[name])
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
