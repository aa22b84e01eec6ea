"""Rollouts of any model along logged jumps: one path for every ``Rollable``.

The model sets itself up on the jumps (``Rollable.rollout_system``): its true
state in its own coordinates, the logged drive (inputs, phase, ...) held
constant over each sample (zero-order hold) and its acceleration function.
The state is integrated from the first sample and mapped back to the
configuration components the model predicts; for the learned model that is
the encoded state, integrated with the phase's Xi from the logged phase
sequence and decoded to q_pred = W_d xi + B_d. With ``reset`` (s) the state is
set back to the true one every ``reset`` seconds (the paper's 0.1 s).

Two integrators:
- ``lsoda``: SciPy's LSODA (``odeint``) over each sample interval, the paper's
  choice; a step budget per interval keeps a stiff or exploding model from
  hanging. With ``lsoda_solver="numbalsoda"`` the same loop runs compiled, with
  numbalsoda's LSODA and the model's generated right-hand side
  (``symrom.rollout.compiled_lsoda``, the ``lsoda`` extra).
- ``rk4``: fixed-step classical Runge-Kutta advancing all jumps at once as
  arrays; the fast path for batch evaluation and for MPC-style use.

A rollout whose state turns non-finite or leaves ``bound`` times the model's
yardstick (for the learned model, the largest |xi|, |dxi| seen in training) is
stopped and flagged as diverged, with the time at which it left.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from symrom.data.dataset import Dataset
from symrom.rollout import compiled_lsoda
from symrom.rollout.system import Rollable, RolloutSystem

METHODS = ("lsoda", "rk4")
# auto: rk4 by the model's generated code when a build of it is at hand (compiled in this
# process or in the disk cache, ``symrom.compiled.has_build``) or when the rollout's work pays
# for compiling it (``GENERATED_PAYS_STEPS``, or ``GENERATED_PAYS_NUMPY_STEPS`` for a model
# whose terms have no table), else by the compiled term-table kernel (no compilation per
# model); lsoda with the NumPy right-hand side; generated: the model's own compiled code for
# both (compiled once per model, then the fastest); table: the term-table kernel; numpy: the
# reference.
BACKENDS = ("auto", "table", "generated", "numpy")
# RK4 steps from which compiling the generated code pays under ``auto``: its compile time
# over what it saves per step against the term table (both measured in docs/benchmarks.md,
# "Rollouts").
GENERATED_PAYS_STEPS = 4_000_000
# Without a term table (a custom block) ``auto``'s alternative is NumPy, hundreds of times slower
# per step: the generated code is compiled once the model's NumPy RK4 steps in this process (a
# batch of jumps counts each step once), this call's included, reach the compile's worth in
# time, so that it never takes much more than twice the better choice's time; both measured in
# docs/benchmarks.md, "Rollouts".
GENERATED_PAYS_NUMPY_STEPS = 1_000
_NUMPY_STEPS: dict[str, int] = {}  # per model (``RolloutSystem.key``): NumPy RK4 steps run in this process
# scipy: odeint entered from Python per sample interval; numbalsoda: the loop and the
# solver compiled (needs the model's generated code).
LSODA_SOLVERS = ("scipy", "numbalsoda")


@dataclass
class RolloutOptions:
    """method: ``lsoda`` or ``rk4``; reset: s between resets (None = full horizon);
    substeps: RK4 steps per sample; max_steps: LSODA step budget per sample;
    rtol, atol: LSODA's relative and absolute tolerances (the defaults are odeint's);
    bound: divergence bound as a multiple of the model's yardstick; backend: ``auto``,
    ``table``, ``generated`` or ``numpy`` (see ``BACKENDS``; a model without compiled
    code runs on NumPy with ``auto``); lsoda_solver: ``scipy`` or ``numbalsoda`` (see
    ``LSODA_SOLVERS``; numbalsoda runs the model's generated code, with backend
    ``auto`` or ``generated``)."""

    method: str = "lsoda"
    reset: float | None = None
    substeps: int = 2
    max_steps: int = 2000
    bound: float = 50.0
    backend: str = "auto"
    rtol: float = 1.49012e-8
    atol: float = 1.49012e-8
    lsoda_solver: str = "scipy"

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"unknown integrator {self.method!r}; choose from {METHODS}")
        if self.backend not in BACKENDS:
            raise ValueError(f"unknown rollout backend {self.backend!r}; choose from {BACKENDS}")
        if self.lsoda_solver not in LSODA_SOLVERS:
            raise ValueError(f"unknown LSODA solver {self.lsoda_solver!r}; choose from {LSODA_SOLVERS}")
        if self.lsoda_solver == "numbalsoda" and self.backend not in ("auto", "generated"):
            raise ValueError(f"lsoda_solver 'numbalsoda' runs the model's generated code; "
                             f"backend {self.backend!r} cannot go with it (use 'auto' or 'generated')")
        if self.lsoda_solver == "numbalsoda" and not compiled_lsoda.available():
            raise ValueError(compiled_lsoda.INSTALL_HINT)
        if self.reset is not None and not self.reset > 0:
            raise ValueError(f"reset must be a positive duration in s, got {self.reset}")


@dataclass
class Rollout:
    """Per jump (list of J): predictions q_pred (n_j, C) of ``components``, the model's
    state path xi and dxi (n_j, d); diverged (J,) bool and, for diverged jumps, the
    first bad sample (else -1); dt the sample period, s."""

    jumps: np.ndarray
    q_pred: list[np.ndarray]
    xi: list[np.ndarray]
    dxi: list[np.ndarray]
    diverged: np.ndarray
    diverged_at: np.ndarray
    components: tuple[str, ...] = ()
    dt: float = 0.0

    def divergence_times(self) -> list[dict]:
        """[{"jump": j, "t": s}] for each diverged jump: when it left its bound."""
        return [{"jump": int(j), "t": round(float(k) * self.dt, 6)}
                for j, k, d in zip(self.jumps, self.diverged_at, self.diverged) if d]


def reset_mask(n: int, reset: float | None, dt: float) -> np.ndarray:
    """(n,) bool: samples at which the state is set to the truth (sample 0 always)."""
    m = np.zeros(n, dtype=bool)
    m[0] = True
    if reset is not None:
        every = max(1, int(round(reset / dt)))
        m[::every] = True
    return m


def pad_edge(arrays: list[np.ndarray]) -> np.ndarray:
    """Stack per-jump arrays (n_j, ...) into (J, n_max, ...), repeating each last sample."""
    n_max = max(a.shape[0] for a in arrays)
    first = np.asarray(arrays[0])
    out = np.empty((len(arrays), n_max) + first.shape[1:], dtype=np.result_type(*arrays))
    for j, a in enumerate(arrays):
        n = a.shape[0]
        out[j, :n] = a
        out[j, n:] = a[n - 1]
    return out


# Acceleration of a second-order system with the inputs of sample k held:
# acc(k, x (J, d), v (J, d)) -> (J, d).
Accel = Callable[[int, np.ndarray, np.ndarray], np.ndarray]


def integrate_lsoda(rhs: Callable, args: Callable[[int], tuple], x_true: np.ndarray, v_true: np.ndarray,
                    resets: np.ndarray, limit: np.ndarray, dt: float,
                    max_steps: int, rtol: float = 1.49012e-8,
                    atol: float = 1.49012e-8) -> tuple[np.ndarray, np.ndarray, int]:
    """One jump of y' = rhs(y, t, *args(k)) with LSODA over each sample interval k.

    y = [x, v]; x_true, v_true (n, d) give the start and reset states; resets (n,)
    bool; limit (2d,) bound on |[x, v]|; rtol, atol: LSODA's tolerances. Returns X, V (n, d), NaN from the first bad
    sample on, and that sample's index (-1 if none).
    """
    from scipy.integrate import odeint  # here: scipy.integrate is slow to import, and rk4 never needs it

    n, d = x_true.shape
    X, V = np.full((n, d), np.nan), np.full((n, d), np.nan)
    y = np.r_[x_true[0], v_true[0]]
    for k in range(n):
        if resets[k]:
            y = np.r_[x_true[k], v_true[k]]
        if not (np.isfinite(y).all() and np.all(np.abs(y) <= limit)):
            return X, V, k
        X[k], V[k] = y[:d], y[d:]
        if k == n - 1:
            break

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # odeint warns on an exhausted budget; we check its message
            sol, info = odeint(rhs, y, [0.0, dt], args=args(k), mxstep=max_steps, full_output=True,
                               rtol=rtol, atol=atol)
        if info["message"] != "Integration successful.":
            return X, V, k + 1
        y = sol[1]
    return X, V, -1


def integrate_rk4(acc: Accel, x_true: np.ndarray, v_true: np.ndarray, lens: np.ndarray,
                  resets: np.ndarray, limit: np.ndarray, dt: float,
                  substeps: int) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """J jumps of x'' = acc at once with fixed-step classical Runge-Kutta.

    x_true, v_true (J, n_max, d) padded start/reset states; lens (J,) true lengths;
    resets (n_max,) bool; limit (J, 2d) or (2d,). Returns per jump X, V (n_j, d),
    NaN from the first bad sample on, and the first bad sample per jump (-1 if none).
    """
    J, n_max, d = x_true.shape
    X, V = np.full((J, n_max, d), np.nan), np.full((J, n_max, d), np.nan)
    alive, div_at = np.ones(J, dtype=bool), np.full(J, -1)
    x, v = x_true[:, 0].copy(), v_true[:, 0].copy()
    h = dt / substeps
    for k in range(n_max):
        if resets[k]:
            x, v = x_true[:, k].copy(), v_true[:, k].copy()
        ok = np.isfinite(np.c_[x, v]).all(1) & np.all(np.abs(np.c_[x, v]) <= limit, axis=1)
        div_at[alive & ~ok & (k < lens)] = k
        alive &= ok | (k >= lens)
        x[~alive], v[~alive] = 0.0, 0.0  # frozen; keeps the arithmetic finite
        X[alive, k], V[alive, k] = x[alive], v[alive]
        if k == n_max - 1:
            break
        for _ in range(substeps):
            k1x, k1v = v, acc(k, x, v)
            k2x, k2v = v + h / 2 * k1v, acc(k, x + h / 2 * k1x, v + h / 2 * k1v)
            k3x, k3v = v + h / 2 * k2v, acc(k, x + h / 2 * k2x, v + h / 2 * k2v)
            k4x, k4v = v + h * k3v, acc(k, x + h * k3x, v + h * k3v)
            with np.errstate(over="ignore", invalid="ignore"):
                x = x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
                v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return [X[j, :lens[j]] for j in range(J)], [V[j, :lens[j]] for j in range(J)], div_at


def integrate_system(sysm: RolloutSystem, options: RolloutOptions, dt: float,
                     progress: Callable[[int, int], None] | None = None
                     ) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Integrate a model's ``RolloutSystem`` (its J jumps) with ``options``.

    Returns per jump the state paths X, V (n_j, d), NaN from the first bad sample
    on, and that sample per jump (J,) (-1 if none); dt is the sample period, s.
    This is ``rollout`` without the model's set-up and the map back to its
    components (what the benchmarks time).
    """
    return _integrate(sysm, options, dt, progress)[:3]


def _integrate(sysm: RolloutSystem, options: RolloutOptions, dt: float,
               progress: Callable[[int, int], None] | None = None
               ) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray, np.ndarray | None]:
    """``integrate_system``, and with a compiled ``rk4`` the padded path X (J, n_max, d)
    the per-jump paths are views of (else None)."""
    limit = options.bound * sysm.scale  # (J, 2d)
    n_jumps = len(sysm.x)
    numbalsoda = options.method == "lsoda" and options.lsoda_solver == "numbalsoda"
    want = options.backend == "generated" or numbalsoda
    generated = sysm.generated() if want and sysm.generated else None
    if want and generated is None:
        raise ValueError("this model has no generated code; use backend 'auto' or 'numpy' "
                         "(and LSODA solver 'scipy')")
    if options.method == "lsoda":
        Xs, Vs, div = [], [], []
        c_rhs = generated.c_rhs() if numbalsoda else None
        for i, (x, v) in enumerate(zip(sysm.x, sysm.v)):
            drive = {name: d[i] for name, d in sysm.drive.items()}  # (n, ...)
            resets = reset_mask(x.shape[0], options.reset, dt)
            if c_rhs is not None:
                X, V, d = compiled_lsoda.integrate(c_rhs, x, v, generated.c_params(drive), resets, limit[i],
                                                   dt, options.max_steps, options.rtol, options.atol)
            else:
                if generated is not None:
                    rhs, args = generated.rhs, (lambda k, dr=drive: generated.rhs_args(dr, k))
                else:
                    d = x.shape[1]

                    def rhs(state, _t, k, dr=drive, d=d):
                        a = sysm.acceleration({n: v[k][None] for n, v in dr.items()}, state[None, :d],
                                              state[None, d:])
                        return np.concatenate([state[d:], a[0]])

                    def args(k):
                        return (k,)
                X, V, d = integrate_lsoda(rhs, args, x, v, resets, limit[i],
                                          dt, options.max_steps, options.rtol, options.atol)
            Xs.append(X)
            Vs.append(V)
            div.append(d)
            if progress:
                progress(i + 1, n_jumps)
        return Xs, Vs, np.array(div, dtype=int), None
    out = _integrate_fixed_step(sysm, options, dt, generated)
    if progress:
        progress(n_jumps, n_jumps)
    return out


def _integrate_fixed_step(sysm: RolloutSystem, options: RolloutOptions, dt: float, generated
                          ) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray, np.ndarray | None]:
    """``rk4`` for ``_integrate``."""
    lens = sysm.padded.lens if sysm.padded is not None else np.array([x.shape[0] for x in sysm.x])
    resets = reset_mask(int(lens.max()), options.reset, dt)
    if sysm.padded is not None:  # stacked by the model already, the states where they are read
        (x_pad, v_pad), drive = sysm.padded.states(resets), sysm.padded.drive
    else:
        x_pad, v_pad, drive = pad_edge(sysm.x), pad_edge(sysm.v), {n: pad_edge(d) for n, d in sysm.drive.items()}
    limit = options.bound * sysm.scale  # (J, 2d)
    if options.backend == "table" and sysm.compiled is None:
        raise ValueError("this model has no compiled integrator; use backend 'numpy'")
    batch_steps = max(int(lens.max()) - 1, 0) * options.substeps  # NumPy's work: per step of the batch
    if options.backend == "auto" and sysm.generated is not None and generated is None:
        steps = int((lens - 1).clip(min=0).sum()) * options.substeps
        numpy_paid = sysm.compiled is None and _NUMPY_STEPS.get(sysm.key, 0) + batch_steps >= GENERATED_PAYS_NUMPY_STEPS
        if (sysm.has_build is not None and sysm.has_build()) or steps >= GENERATED_PAYS_STEPS or numpy_paid:
            generated = sysm.generated()
    fast = generated.integrator if generated is not None else sysm.compiled if options.backend != "numpy" else None
    if fast is None:
        Xs, Vs, div_at = integrate_rk4(lambda k, xs, vs: sysm.acceleration(
            {n: a[:, k] for n, a in drive.items()}, xs, vs), x_pad, v_pad, lens, resets, limit, dt,
            options.substeps)
        if options.backend == "auto" and sysm.key is not None:
            _NUMPY_STEPS[sysm.key] = _NUMPY_STEPS.get(sysm.key, 0) + batch_steps
        return Xs, Vs, div_at, None
    X, V, div_at = fast(x_pad, v_pad, drive, lens, resets, limit, dt, options.substeps)
    return [X[j, :n] for j, n in enumerate(lens)], [V[j, :n] for j, n in enumerate(lens)], div_at, X


def rollout(model: Rollable, ds: Dataset, jumps: np.ndarray | list[int] | None = None,
            options: RolloutOptions = RolloutOptions(),
            progress: Callable[[int, int], None] | None = None) -> Rollout:
    """Roll ``model`` out along the logged ``jumps`` of ``ds`` (default: all).

    Returns its predictions in the units of q (rad, m); ValueError with one
    clear message when the data do not fit the model.
    """
    jumps = np.arange(ds.n_jumps) if jumps is None else np.asarray(jumps, dtype=int)
    comps = tuple(model.components)
    if jumps.size == 0:
        return Rollout(jumps, [], [], [], np.zeros(0, bool), np.zeros(0, int), comps, ds.dt)
    sysm = model.rollout_system(ds, jumps)
    Xs, Vs, div_at, padded = _integrate(sysm, options, ds.dt, progress)
    if padded is not None and sysm.observe_padded is not None:  # one call for all jumps
        q_pred = sysm.observe_padded(padded, np.array([x.shape[0] for x in Xs]))
    else:
        q_pred = [sysm.observe(i, X) for i, X in enumerate(Xs)]
    return Rollout(jumps, q_pred, Xs, Vs, div_at >= 0, div_at, comps, ds.dt)
