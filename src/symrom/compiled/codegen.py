"""Per-model compiled rollouts: the model's equations written out as code, compiled by numba.

``symrom.compiled.kernel`` evaluates any model of simple-factor terms with one
compiled routine that reads a term table: no compilation per model, which is
what a selection over hundreds of candidates needs. For one model rolled out
many times (evaluation, a planner, the benchmark) this module writes the
model's equations themselves as straight-line code (sympy's Python printer,
common subexpressions shared, only the active terms, each phase its own
branch, the latent state held in scalar variables), so a step costs a few dozen
floating-point operations. Compiling costs far more than a rollout on the
term table (docs/benchmarks.md); the result is cached per model (its
library's identity and coefficients, ``LatentDynamics.key``) in this process
and on disk (``cache_dir``): the source is written as a module there and
compiled by numba with its own disk cache, so a later process loads the
machine code instead of compiling it. The module is written by this process
only, and rewritten whenever its text differs from the model's source, so
nothing is run that this code did not generate. ``has_build(dynamics)`` says
whether a build is at hand (``symrom.rollout.integrate``'s ``auto`` backend
uses the generated code then).

Sines and cosines of state variables dominate a step's cost. The first RK4 step
of a sample evaluates them once, at its start, with ``math.sin``/``math.cos``;
its three later stages, and the sample's later steps (``substeps``), sit within
h |ds/dt| of a state whose sines and cosines are known and get theirs from the
angle sum formulas with a Taylor polynomial of the small shift (``shift``: exact
to rounding while the shift stays below ``SHIFT_MAX``, ``math`` beyond it). The
arithmetic may be contracted into fused multiply-adds and reassociated
(``FASTMATH``), never assumed free of NaN or infinity, so the divergence
checks stand.

``generated(dynamics)`` gives the model's ``GeneratedFunctions``: an RK4
integrator with the interface of ``symrom.compiled.kernel.table_integrator``
(``RolloutSystem.compiled``) and the semantics of
``symrom.rollout.integrate.integrate_rk4``, the right-hand side for SciPy's
LSODA and the same as a C function, for the compiled LSODA. The model comes
as a ``LatentDynamics``: its terms, coefficients, phase names and exact
right-hand sides.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import os
import sys
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy
from sympy.printing.pycode import PythonCodePrinter

from symrom.compiled.batch import rollout_jumps
from symrom.compiled.dynamics import LatentDynamics

_CACHE: OrderedDict[str, dict] = OrderedDict()
CACHE_SIZE = 16  # compiled models kept per process
CACHE_ENV = "SYMROM_CACHE_DIR"  # the disk cache's folder; "off" (or "") for none
# LLVM's fast-math flags without nnan/ninf: a NaN or an overflow must still fail the bound test.
FASTMATH = {"contract", "arcp", "nsz", "reassoc"}
# Largest shift |t - s| for which ``shift`` uses its polynomials: the first dropped terms,
# d^11/11! and d^10/10!, are then below 3e-17.
SHIFT_MAX = 0.1

SHIFT_SOURCE = f"""
def shift(t, s, sin_s, cos_s):
    d = t - s
    if abs(d) < {SHIFT_MAX!r}:
        d2 = d * d
        sd = d * (1.0 + d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0 + d2 * (1.0 / 362880.0)))))
        cd = 1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0 + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0))))
        return sin_s * cd + cos_s * sd, cos_s * cd - sin_s * sd
    return math.sin(t), math.cos(t)
"""

def _rk4_source(l: int, trig: list[int]) -> str:
    """Python source of ``rollout`` (the RK4 integrator of ``generated_integrator``) and
    ``rhs`` (LSODA's right-hand side) for latent dimension l: the state is held in 2l
    scalar variables and every loop over it is written out, so that the compiled step
    is straight-line code. ``trig``: the state variables whose sine and cosine
    ``accel_s`` takes (see the module's note)."""
    n = 2 * l
    S = [f"s{i}" for i in range(n)]
    U = [f"u{i}" for i in range(l)]
    T = [f"t{i}" for i in range(n)]
    SC = [f"{f}{i}" for i in trig for f in ("S", "C")]  # at the step's start
    PQ = [f"{f}{i}" for i in trig for f in ("P", "Q")]  # at a later stage

    def call(out: str) -> str:
        """accel_s at a later stage (the state in t0..), its trig shifted from the step's start."""
        lhs = ", ".join(f"{out}{d}" for d in range(l)) + ("," if l == 1 else "")
        moved = [f"P{i}, Q{i} = shift(t{i}, s{i}, S{i}, C{i})" for i in trig]
        return "\n".join(moved + [f"{lhs} = accel_s(ph, {', '.join(T + U + PQ)})"])

    # A sample's first step takes its sines and cosines from ``math``; a later step (of
    # ``substeps``) shifts them from the previous step's start (r), as a stage does.
    first = [f"S{i} = math.sin(s{i})\nC{i} = math.cos(s{i})" for i in trig]
    step = [f"if m > 0:\n    S{i}, C{i} = shift(s{i}, r{i}, S{i}, C{i})\nr{i} = s{i}" for i in trig]
    # classical RK4 on (x, v): k1 = (v, a), k2 = (w, b), k3 = (y, c), k4 = (v + h c, e)
    step += [f"{', '.join(f'a{d}' for d in range(l))}{',' if l == 1 else ''} = accel_s(ph, {', '.join(S + U + SC)})"]
    step += [f"t{d} = s{d} + 0.5 * h * s{l + d}" for d in range(l)]
    step += [f"t{l + d} = s{l + d} + 0.5 * h * a{d}" for d in range(l)]
    step += [call("b")] + [f"w{d} = t{l + d}" for d in range(l)]
    step += [f"t{d} = s{d} + 0.5 * h * w{d}" for d in range(l)]
    step += [f"t{l + d} = s{l + d} + 0.5 * h * b{d}" for d in range(l)]
    step += [call("c")] + [f"y{d} = t{l + d}" for d in range(l)]
    step += [f"t{d} = s{d} + h * y{d}" for d in range(l)]
    step += [f"t{l + d} = s{l + d} + h * c{d}" for d in range(l)]
    step += [call("e")]
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
{nl.join(ind[4:] + line for text in first for line in text.split(nl))}
{ind[4:]}{" = ".join([f"r{i}" for i in trig] + ["0.0"]) if trig else "pass"}
            for m in range(substeps):
{nl.join(ind + line for text in step for line in text.split(nl))}
        stop = lens[j] if div_at[j] < 0 else div_at[j]
        X[j, stop:] = math.nan  # after the path: NaN (X, V come uninitialised)
        V[j, stop:] = math.nan


def rhs(y, t, ph, u):
    out = np.empty({n})
{nl.join(f"    out[{d}] = y[{l + d}]" for d in range(l))}
    r = accel_ref(ph, {", ".join([f"y[{i}]" for i in range(n)] + [f"u[{d}]" for d in range(l)])})
{nl.join(f"    out[{l + d}] = r[{d}]" for d in range(l))}
    return out


def c_rhs(t, y, dy, p):
{nl.join(f"    dy[{d}] = y[{l + d}]" for d in range(l))}
    {", ".join(f"a{d}" for d in range(l))}{"," if l == 1 else ""} = accel_ref(int(p[0]), {", ".join(
        [f"y[{i}]" for i in range(n)] + [f"p[{d + 1}]" for d in range(l)])})
{nl.join(f"    dy[{l + d}] = a{d}" for d in range(l))}
"""


def model_source(dynamics: LatentDynamics) -> str:
    """Python source of ``accel_s(ph, s0, ..., s_{2l-1}, u0, ..., u_{l-1}, S_i, C_i, ...)``:
    the tuple ddxi (l,) in phase index ``ph`` at the state s = [xi, dxi] with inputs nu
    (NaN for an unknown phase), given S_i = sin(s_i) and C_i = cos(s_i) for each state
    variable whose sine or cosine the model uses; then ``shift``, the RK4 rollout and
    the LSODA right-hand sides.

    LSODA's right-hand sides (``rhs``, ``c_rhs``) call ``accel_ref`` instead: the same
    terms in the library's order, summed one by one as NumPy's reference does, and
    compiled without fast-math, so that they round as it does (LSODA's step choices
    follow the last bits of its right-hand side)."""
    l, names = dynamics.latent_dim, dynamics.phase_names
    s, nu = dynamics.terms.state, dynamics.terms.inputs
    sub = {v: sympy.Symbol(f"s{i}") for i, v in enumerate(s)} | {v: sympy.Symbol(f"u{i}") for i, v in enumerate(nu)}
    exprs = [[e.xreplace(sub) for e in rows] for rows in dynamics.right_hand_sides()]
    state = {sympy.Symbol(f"s{i}"): i for i in range(2 * l)}
    atoms = set().union(*(e.atoms(sympy.sin, sympy.cos) for rows in exprs for e in rows))
    trig = sorted({state[a.args[0]] for a in atoms if a.args[0] in state})
    named = {f(sympy.Symbol(f"s{i}")): sympy.Symbol(f"{c}{i}") for i in trig
             for f, c in ((sympy.sin, "S"), (sympy.cos, "C"))}
    printer = PythonCodePrinter({"fully_qualified_modules": True})
    tail = "," if l == 1 else ""
    args = [f"s{i}" for i in range(2 * l)] + [f"u{i}" for i in range(l)] + [f"{c}{i}" for i in trig for c in "SC"]
    lines = [f"def accel_s(ph, {', '.join(args)}):"]
    for k, rows in enumerate(exprs):
        repl, reduced = sympy.cse([e.xreplace(named) for e in rows], symbols=sympy.numbered_symbols("c"))
        lines.append(f"    {'if' if k == 0 else 'elif'} ph == {k}:  # {names[k]}")
        lines += [f"        {v} = {printer.doprint(e)}" for v, e in repl]
        lines.append(f"        return {', '.join(f'float({printer.doprint(e)})' for e in reduced)}{tail}")
    lines.append(f"    return {', '.join(['math.nan'] * l)}{tail}")
    lines += [f"def accel_ref(ph, {', '.join(args[:3 * l])}):"]
    feats = [printer.doprint(f.xreplace(sub)) for f in dynamics.terms.features]
    for k in range(len(names)):
        lines.append(f"    {'if' if k == 0 else 'elif'} ph == {k}:  # {names[k]}")
        for j in range(l):
            lines.append(f"        a{j} = 0.0")
            lines += [f"        a{j} = a{j} + {feat} * {float(c)!r}"
                      for feat, c in zip(feats, dynamics.Xi[k][:, j]) if c != 0]
        lines.append(f"        return {', '.join(f'a{j}' for j in range(l))}{tail}")
    lines.append(f"    return {', '.join(['math.nan'] * l)}{tail}")
    return "\n".join(lines) + "\n" + SHIFT_SOURCE + _rk4_source(l, trig)


def cache_dir() -> Path | None:
    """The folder of the generated code's disk cache: ``$SYMROM_CACHE_DIR`` if set ("off" or
    empty: no disk cache), else ``$XDG_CACHE_HOME/symrom/generated`` (default
    ``~/.cache/symrom/generated``)."""
    env = os.environ.get(CACHE_ENV)
    if env is not None:
        return None if env.strip().lower() in ("", "off") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "symrom" / "generated"


# The module written to the disk cache: the model's source, then its compilation with
# numba's own disk cache (LSODA's right-hand sides without fast-math, as in ``_compiled``).
_MODULE_HEAD = "import math\n\nimport numba\nimport numpy as np\n\n"
_MODULE_TAIL = f"""
FASTMATH = {sorted(FASTMATH)!r}
shift = numba.njit(fastmath=set(FASTMATH), cache=True)(shift)
accel_s = numba.njit(fastmath=set(FASTMATH), cache=True)(accel_s)
accel_ref = numba.njit(cache=True)(accel_ref)
rollout = numba.njit(fastmath=set(FASTMATH), cache=True, nogil=True)(rollout)
rhs = numba.njit(cache=True)(rhs)
"""


def _stamp(text: str) -> str:
    """What a build on disk depends on: its module's text (hashed), numba, Python and numba's
    cache folder."""
    import numba

    return json.dumps({"module_sha256": hashlib.sha256(text.encode()).hexdigest(), "numba": numba.__version__,
                       "python": sys.version.split()[0], "numba_cache_dir": os.environ.get("NUMBA_CACHE_DIR", "")})


def _module_path(key: str) -> Path | None:
    folder = cache_dir()
    return None if folder is None else folder / f"symrom_model_{key[:32]}.py"


def has_build(dynamics: LatentDynamics) -> bool:
    """Whether the generated code of ``dynamics`` is compiled in this process or on disk."""
    key = dynamics.key
    if key in _CACHE:
        return True
    path = _module_path(key)
    if path is None:
        return False
    try:
        return path.with_suffix(".built").read_text() == _stamp(path.read_text())
    except OSError:
        return False


def _load_module(dynamics: LatentDynamics, key: str) -> tuple[dict, Path, str] | None:
    """The model's compiled namespace from the disk cache (written first if missing or
    different), or None when there is no usable cache folder."""
    from symrom.atomic import write_text_atomic

    path = _module_path(key)
    if path is None:
        return None
    text = _MODULE_HEAD + model_source(dynamics) + _MODULE_TAIL
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.is_file() or path.read_text() != text:
            path.with_suffix(".built").unlink(missing_ok=True)
            write_text_atomic(path, text)
    except OSError:
        return None
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module  # numba's cache finds the module's globals by its name
    spec.loader.exec_module(module)
    return vars(module), path, text


def _compiled(dynamics: LatentDynamics) -> dict:
    """The compiled functions of ``dynamics`` (cached) and the seconds the compilation took."""
    key = dynamics.key
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    import numba

    t0 = time.perf_counter()
    loaded = _load_module(dynamics, key)
    if loaded is not None:
        ns, path, text = loaded
        rollout, rhs = ns["rollout"], ns["rhs"]
    else:
        path = None
        ns = {"math": math, "np": np}
        exec(compile(model_source(dynamics), f"<symrom model {key[:12]}>", "exec"), ns)  # noqa: S102 - our own source
        for name in ("shift", "accel_s"):  # compiled before the functions that call them
            ns[name] = numba.njit(fastmath=FASTMATH)(ns[name])
        ns["accel_ref"] = numba.njit(ns["accel_ref"])  # LSODA's: rounded as NumPy's reference
        rollout, rhs = numba.njit(fastmath=FASTMATH, nogil=True)(ns["rollout"]), numba.njit(ns["rhs"])
    l = dynamics.latent_dim
    z, limit = np.zeros((1, 2, l)), np.ones((1, 2 * l))
    limit.setflags(write=False)  # as ``batch.rollout_jumps`` passes it
    # Compile for the argument types the integrators pass, so that the first real call is fast.
    # LSODA's ``rhs`` compiles at its first call: most models never run SciPy's LSODA, and it
    # was about a quarter of a build.
    rollout(z, z, z, np.zeros((1, 2), np.int64), np.array([2], np.int64), np.ones(2, np.bool_), 0.002, 1,
            limit, z.copy(), z.copy(), np.zeros(1, np.int64))
    if path is not None:
        try:
            from symrom.atomic import write_text_atomic

            write_text_atomic(path.with_suffix(".built"), _stamp(text))
        except OSError:
            pass
    entry = {"rollout": rollout, "rhs": rhs, "c_rhs": ns["c_rhs"], "compile_s": time.perf_counter() - t0}
    _CACHE[key] = entry
    while len(_CACHE) > CACHE_SIZE:
        _CACHE.popitem(last=False)
    return entry


def compile_seconds(dynamics: LatentDynamics) -> float:
    """Seconds the compilation of ``dynamics`` took (compiling it now if needed)."""
    return _compiled(dynamics)["compile_s"]


@dataclass(frozen=True)
class GeneratedFunctions:
    """One model's generated code, compiled.

    integrator(x_true, v_true, drive, lens, resets, limit, dt, substeps): RK4 with the
    interface of ``symrom.compiled.kernel.table_integrator``'s integrators (drive: nu (J,
    n_max, l), phase (J, n_max)), compiled with the build; rhs(y (2l,), t, phase index, nu
    (l,)) -> dy/dt (2l,), for SciPy's LSODA; c_rhs(): the address of the same as a C function
    ``void f(double t, double *y, double *dy, double *p)``, p = [phase index, nu (l)], for a
    compiled LSODA (``symrom.rollout.compiled_lsoda``); these two compiled on their first call."""

    integrator: Callable
    rhs: Callable
    c_rhs: Callable[[], int]


def generated(dynamics: LatentDynamics) -> GeneratedFunctions:
    """The generated code of ``dynamics``, compiled now unless a build is at hand."""
    entry = _compiled(dynamics)
    fn = entry["rollout"]

    def integrate(x_true, v_true, drive, lens, resets, limit, dt, substeps):
        X, V = np.empty((2, *x_true.shape))  # one block: fewer page faults (huge pages from 4 MB)
        return X, V, rollout_jumps(fn, x_true, v_true, drive, lens, resets, limit, dt, substeps, X, V)

    return GeneratedFunctions(integrate, entry["rhs"], lambda: _c_rhs(entry))


def _c_rhs(entry: dict) -> int:
    if "c_rhs_address" not in entry:
        import numba
        from numba import types

        ptr = types.CPointer(types.double)
        entry["c_rhs_cfunc"] = numba.cfunc(types.void(types.double, ptr, ptr, ptr))(entry["c_rhs"])
        entry["c_rhs_address"] = entry["c_rhs_cfunc"].address
    return entry["c_rhs_address"]
