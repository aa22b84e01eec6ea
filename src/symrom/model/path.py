"""Free prediction: roll a model out from a chosen (q0, dq0) with one's own inputs.

``predict_path`` needs no dataset. The inputs are the wrench ``u`` (18: joint
torques, then the CoM wrench; ``symrom.data.preprocess.input_from_torques``
computes it from torques the way the datasets do), either an (n, 18) array or
a callable ``inputs(t, state) -> u (18,)`` of the time (s) and the
``PathState`` at each sample. The phases are either a given schedule (n,) or
predicted by the model's learned guards (``symrom.model.guards``).

The integrator is the rollouts' (``symrom.rollout.integrate``): classical RK4
with ``substeps`` per sample, the input and the phase held over each sample,
on the backend ``options`` chooses, so that with the logged schedule and inputs
the path equals ``rollout`` on that jump. With guards and an input array, the
path is integrated in the current phase until a guard fires, then again from
that sample in the new phase (the part before the switch is kept: the steps
are the same). A callable is asked for each sample's input in turn, so that
path is stepped sample by sample on NumPy.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from symrom.model.guards import advance, first_stage, first_switch, sequence_targets, switch
from symrom.names import N_Q


class NoGuardsError(ValueError):
    """Predicted phases were asked of a model without guards."""


@dataclass(frozen=True)
class PathState:
    """What an input callable sees at sample k: t (s), q, dq (18,) decoded from the
    latent state xi, dxi (l,), and the phase name the step from k starts in (before
    the guards' decision at k)."""

    k: int
    t: float
    q: np.ndarray
    dq: np.ndarray
    xi: np.ndarray
    dxi: np.ndarray
    phase: str


@dataclass
class PathPrediction:
    """A predicted path of n samples every dt s: t (n,) s; q, dq (n, 18) decoded; xi,
    dxi (n, l); u (n, 18) the inputs used; phase (n,) model phase indices into
    ``phase_names``; switches: [{"k", "t", "source", "target"}] where the phase
    changes; diverged_at: first sample out of the bound (NaN from it on), -1 if none."""

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    xi: np.ndarray
    dxi: np.ndarray
    u: np.ndarray
    phase: np.ndarray
    phase_names: list[str]
    switches: list[dict] = field(default_factory=list)
    diverged_at: int = -1

    @property
    def diverged(self) -> bool:
        return self.diverged_at >= 0

    @property
    def phase_labels(self) -> list[str]:
        """The phase name of each sample."""
        return [self.phase_names[int(k)] for k in self.phase]


def _switches(phase: np.ndarray, names: list[str], dt: float) -> list[dict]:
    cut = np.flatnonzero(np.diff(phase)) + 1
    return [{"k": int(k), "t": round(float(k * dt), 9), "source": names[int(phase[k - 1])],
             "target": names[int(phase[k])]} for k in cut]


def schedule_indices(model, phases, n: int) -> np.ndarray:
    """Model phase indices (n,) of a schedule of names or indices; ValueError naming the
    first sample whose phase the model has no trained equations for."""
    arr = np.asarray(phases)
    if arr.shape != (n,):
        raise ValueError(f"phases: shape {arr.shape}, expected ({n},) (one per sample of the inputs)")
    trained = model.trained_phases()
    if arr.dtype.kind in "USO":
        idx = np.full(n, -1)
        for i, name in enumerate(model.phase_names):
            idx[arr == name] = i
    else:
        idx = arr.astype(int)
    bad = (idx < 0) | (idx >= len(model.phase_names))
    bad |= ~np.isin(idx, [model.phase_names.index(p) for p in trained])
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"phases[{k}]: {arr[k].item()!r} is not a trained phase of the model ({', '.join(trained)})")
    return idx


def predict_path(model, q0: np.ndarray, dq0: np.ndarray, inputs: np.ndarray | Callable, dt: float,
                 phases=None, n: int | None = None, phase0: str | None = None, options=None,
                 dwell0: float = 0.0, stage0: int | None = None) -> PathPrediction:
    """Predict the path of ``model`` (a ``HybridModel``) from q0, dq0 (18,) (rad, m, /s).

    inputs: u (n, 18) (N m, N, N m), held over each sample, or a callable
    ``inputs(t, PathState) -> u (18,)`` (then ``n`` samples are predicted);
    dt: sample period, s; phases: a schedule (n,) of phase names or model phase
    indices, or None to let the guards decide, starting in ``phase0`` (default: the
    model's first phase) entered ``dwell0`` s before sample 0 (a clock guard, ``Guard.clock``, counts
    from that entry: pass it when starting inside a phase), at ``stage0`` of the model's phase
    sequence (default: phase0's first place in it; -1: no sequence, any guard of a phase may
    fire); options: ``RolloutOptions`` (method
    ``rk4``; its substeps, bound and backend; not its reset: there is no truth to reset
    to). Returns a ``PathPrediction``; a
    diverging path ends in NaN with its ``diverged_at``. ``NoGuardsError`` when the
    guards are asked of a model without them.
    """
    from symrom.rollout.integrate import RolloutOptions, integrate_system

    options = RolloutOptions(method="rk4") if options is None else replace(options, reset=None)
    if options.method != "rk4":
        raise ValueError(f"predict_path integrates with rk4 (the rollouts' fixed-step method), "
                         f"got method {options.method!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    q0, dq0 = np.asarray(q0, dtype=float), np.asarray(dq0, dtype=float)
    for name, a in (("q0", q0), ("dq0", dq0)):
        if a.shape != (N_Q,) or not np.isfinite(a).all():
            raise ValueError(f"{name}: expected {N_Q} finite numbers, got shape {a.shape}")
    names, l, ae = list(model.phase_names), model.latent_dim, model.autoencoder
    if phases is None:
        if model.guards is None:
            raise NoGuardsError("this model has no contact guards (a model file of format 3 or older, or "
                                "fitted without them): pass a phase schedule, or train it again with "
                                "this symrom to learn them")
        start = names[0] if phase0 is None else phase0
        if start not in model.trained_phases():
            raise ValueError(f"phase0: {start!r} is not a trained phase of the model "
                             f"({', '.join(model.trained_phases())})")
        p0 = names.index(start)
        seq = model.phase_sequence()
        stage = first_stage(seq, p0) if stage0 is None else int(stage0)
        if stage != -1 and not (0 <= stage < len(seq) and seq[stage] == p0):
            raise ValueError(f"stage0={stage0}: the model's phase sequence "
                             f"{[names[i] for i in seq]} has no {start!r} at that place")
    k_enter0 = -int(round(dwell0 / dt))  # the sample at which phase0 was entered
    x0, v0 = ae.encode(q0[None])[0], ae.encode_derivative(dq0[None])[0]
    limit = options.bound * model.yardstick
    if callable(inputs):
        if n is None or int(n) < 1:
            raise ValueError("n: the number of samples to predict is needed with an input callable")
        sched = None if phases is None else schedule_indices(model, phases, int(n))
        return _step_callable(model, x0, v0, inputs, dt, int(n), sched, None if phases is not None else p0,
                              options, limit, k_enter0, None if phases is not None else (seq, stage))
    u = np.asarray(inputs, dtype=float)
    if u.ndim != 2 or u.shape[1] != N_Q or u.shape[0] < 1:
        raise ValueError(f"inputs: shape {u.shape}, expected (n, {N_Q}) with n >= 1")
    if not np.isfinite(u).all():
        r = int(np.flatnonzero(~np.isfinite(u).all(axis=1))[0])
        raise ValueError(f"inputs: non-finite value at row {r}")
    n = u.shape[0]
    nu = ae.encode_input(u)
    scale = model.yardstick[None]

    def run(x, v, ph):
        sysm = model.latent_system([np.broadcast_to(x, (len(ph), l)).copy()],
                                   [np.broadcast_to(v, (len(ph), l)).copy()], [nu[-len(ph):]], [ph], scale)
        X, V, div = integrate_system(sysm, options, dt)
        return X[0], V[0], int(div[0])

    if phases is not None:
        ph = schedule_indices(model, phases, n)
        X, V, div = run(x0, v0, ph)
    else:
        ph = np.full(n, p0, dtype=np.int64)
        X, V = np.full((n, l), np.nan), np.full((n, l), np.nan)
        k0, k_enter, search, x, v, div = 0, k_enter0, 0, x0, v0, -1
        while True:
            Xs, Vs, d = run(x, v, ph[k0:])
            X[k0:], V[k0:] = Xs, Vs
            if d >= 0:
                div = k0 + d
            stop = n if d < 0 else k0 + d
            Z = np.c_[X[:stop], V[:stop], nu[:stop]]
            hit = first_switch(model.guards, names, int(ph[k0]), k_enter, dt, Z, search,
                               sequence_targets(seq, stage))
            if hit is None:
                break
            k, target = hit
            stage = advance(seq, stage, target)
            ph[k:] = target
            k0 = k_enter = k
            search = k + 1  # one switch per sample, as stepping sample by sample decides
            x, v, div = X[k].copy(), V[k].copy(), -1
    return _prediction(model, X, V, u, ph, dt, div)


def _prediction(model, X, V, u, ph, dt, div) -> PathPrediction:
    ae = model.autoencoder
    n = X.shape[0]
    return PathPrediction(np.arange(n) * dt, ae.decode(X), ae.decode_derivative(V), X, V, u, ph,
                          list(model.phase_names), _switches(ph, list(model.phase_names), dt), div)


def _step_callable(model, x, v, inputs: Callable, dt: float, n: int, sched: np.ndarray | None,
                   p0: int | None, options, limit: np.ndarray, k_enter0: int = 0,
                   staged: tuple[tuple[int, ...], int] | None = None) -> PathPrediction:
    """Sample-by-sample RK4 (``substeps`` per sample) asking ``inputs`` for each sample's u;
    staged: (the phase sequence, the stage at sample 0) when the guards decide."""
    ae, l, names = model.autoencoder, model.latent_dim, list(model.phase_names)
    X, V, U = np.full((n, l), np.nan), np.full((n, l), np.nan), np.full((n, N_Q), np.nan)
    ph = np.zeros(n, dtype=np.int64) if sched is None else sched.copy()
    phase, k_enter, div = (p0 if sched is None else int(sched[0])), k_enter0, -1
    seq, stage = staged if staged is not None else ((), -1)
    h = dt / options.substeps

    def acc(xs, vs, nu, p):
        return model.latent_acceleration(xs[None], vs[None], nu[None], np.array([p]))[0]

    for k in range(n):
        if not (np.isfinite(np.r_[x, v]).all() and np.all(np.abs(np.r_[x, v]) <= limit)):
            div = k
            break
        X[k], V[k] = x, v
        state = PathState(k, k * dt, ae.decode(x[None])[0], ae.decode_derivative(v[None])[0], x.copy(), v.copy(),
                          names[phase])
        u = np.asarray(inputs(k * dt, state), dtype=float)
        if u.shape != (N_Q,) or not np.isfinite(u).all():
            raise ValueError(f"inputs(t={k * dt:g}) at sample {k}: expected {N_Q} finite numbers, got "
                             f"{u.shape if u.shape != (N_Q,) else 'a non-finite value'}")
        U[k] = u
        nu = ae.encode_input(u[None])[0]
        if sched is None:
            new = switch(model.guards, names, phase, k - k_enter, dt, np.r_[x, v, nu],
                         sequence_targets(seq, stage))
            if new != phase:
                phase, k_enter, stage = new, k, advance(seq, stage, new)
            ph[k] = phase
        else:
            phase = int(sched[k])
        if k == n - 1:
            break
        for _ in range(options.substeps):
            k1x, k1v = v, acc(x, v, nu, phase)
            k2x, k2v = v + h / 2 * k1v, acc(x + h / 2 * k1x, v + h / 2 * k1v, nu, phase)
            k3x, k3v = v + h / 2 * k2v, acc(x + h / 2 * k2x, v + h / 2 * k2v, nu, phase)
            k4x, k4v = v + h * k3v, acc(x + h * k3x, v + h * k3v, nu, phase)
            with np.errstate(over="ignore", invalid="ignore"):
                x = x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
                v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    if div >= 0:
        ph[div:] = phase
    return _prediction(model, X, V, U, ph, dt, div)
