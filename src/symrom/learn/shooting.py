"""Batch rollouts of the latent dynamics with exact parameter sensitivities.

The rollout-aware refinement (``symrom.learn.regressors.refine``) fits the
coefficients of a hybrid latent model to trajectories. It needs the rollout
of many windows at once and the derivative of every simulated state with
respect to every active coefficient. Both come from one pass of classical
Runge-Kutta (RK4) applied to the state s = [xi, dxi] together with its
sensitivity S = ds/dtheta, which obeys the variational equation

    dS/dt = A(s) S + B(s),   A = d f / d s,   B = d f / d theta,

with f(s) = [dxi, Theta(xi, dxi, nu) Xi_phase]. An explicit Runge-Kutta
method applied to this augmented system gives exactly the derivative of its
own discrete map, so the Jacobian handed to the least-squares solver is exact
for the very rollouts it scores. The library supplies dTheta/ds
(``Library.jacobian``); theta is the vector of active coefficients
Xi[mask] in C order (phase, term, latent). Inputs and phases are held over
each sample, as in ``symrom.rollout``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.compiled import rollout_windows
from symrom.model.library import Library


@dataclass
class Trajectory:
    """One training jump, encoded: xi, dxi, nu (n, l) and model phase indices (n,)."""

    xi: np.ndarray
    dxi: np.ndarray
    nu: np.ndarray
    phase: np.ndarray


@dataclass
class Windows:
    """W windows of at most L samples cut from trajectories.

    xi, dxi (W, L, l): the true latent state (sample 0 is the start); nu (W, L, l)
    and phase (W, L) int: the drive held over each sample; valid (W, L) bool:
    samples that exist (a window cut at the end of its jump is shorter).
    """

    xi: np.ndarray
    dxi: np.ndarray
    nu: np.ndarray
    phase: np.ndarray
    valid: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return self.valid.shape


def cut_windows(trajs: list[Trajectory], length: int | None) -> Windows:
    """Non-overlapping windows of ``length`` samples (None: each whole trajectory)."""
    pieces = []
    for t in trajs:
        n = t.xi.shape[0]
        step = n if length is None else max(int(length), 2)
        for a in range(0, n - 1, step):
            b = min(a + step, n)
            if b - a >= 2:
                pieces.append((t, a, b))
    L = max(b - a for _, a, b in pieces)
    W, l = len(pieces), trajs[0].xi.shape[1]
    out = Windows(np.zeros((W, L, l)), np.zeros((W, L, l)), np.zeros((W, L, l)),
                  np.zeros((W, L), dtype=int), np.zeros((W, L), dtype=bool))
    for w, (t, a, b) in enumerate(pieces):
        n = b - a
        for name in ("xi", "dxi", "nu"):
            arr = getattr(t, name)[a:b]
            getattr(out, name)[w, :n] = arr
            getattr(out, name)[w, n:] = arr[-1]  # pad by holding the last sample
        out.phase[w, :n], out.phase[w, n:] = t.phase[a:b], t.phase[b - 1]
        out.valid[w, :n] = True
    return out


@dataclass
class Parameters:
    """The active coefficients of Xi (P, p, l) as a vector: index arrays (n,) of
    phase, term and latent of each entry, in C order of Xi[mask]."""

    phase: np.ndarray
    term: np.ndarray
    latent: np.ndarray

    @classmethod
    def of(cls, mask: np.ndarray) -> Parameters:
        k, p, j = np.nonzero(mask)
        return cls(k, p, j)

    @property
    def size(self) -> int:
        return int(self.phase.size)

    def vector(self, Xi: np.ndarray) -> np.ndarray:
        return Xi[self.phase, self.term, self.latent].copy()

    def matrix(self, theta: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
        Xi = np.zeros(shape)
        Xi[self.phase, self.term, self.latent] = theta
        return Xi


BACKENDS = ("auto", "table", "numpy")


def simulate(library: Library, Xi: np.ndarray, params: Parameters, win: Windows, dt: float,
             limit: np.ndarray, substeps: int = 1, sensitivities: bool = True, stride: int = 1,
             backend: str = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """Roll every window out from its true start.

    Xi (P, p, l), every coefficient: the parameters' entries and any held fixed (nonzero
    entries outside ``params``, whose sensitivities are not computed); limit (2l,) bound on
    |[xi, dxi]|. Returns X, V (W, L, l), the
    sensitivities S (W, ceil(L / stride), 2l, n) of [xi, dxi] to the parameters
    at every ``stride``-th sample (None unless ``sensitivities``), and alive
    (W, L) bool: False from the first sample at which a window left the bound
    (its state is then held, its S zeroed). backend: ``table`` (numba,
    ``symrom.compiled.rollout_windows``), ``numpy`` (the reference), or ``auto``
    (the table kernel when the library has a term table).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose from {BACKENDS}")
    if backend != "numpy":
        out = rollout_windows(library.terms, Xi, params.phase, params.term, params.latent, win.xi, win.dxi,
                              win.nu, win.phase, dt, limit, substeps, sensitivities, stride)
        if out is None and backend == "table":
            raise ValueError("this library has terms the compiled kernel cannot evaluate")
        if out is not None:
            return out.X, out.V, out.S, out.alive
    W, L = win.shape
    l = library.latent_dim
    n = params.size
    h = dt / substeps
    X, V = np.zeros((W, L, l)), np.zeros((W, L, l))
    S_all = np.zeros((W, -(-L // stride), 2 * l, n)) if sensitivities else None
    alive = np.ones((W, L), dtype=bool)
    x, v = win.xi[:, 0].copy(), win.dxi[:, 0].copy()
    S = np.zeros((W, 2 * l, n))
    ok = np.ones(W, dtype=bool)
    cols = np.arange(n)

    def field(x, v, S, nu, Xi_w, on):
        theta = library.transform(x, v, nu)  # (W, p)
        acc = (theta[:, None, :] @ Xi_w)[:, 0]
        if S is None:
            return v, acc, None
        Jt = library.jacobian(x, v, nu)  # (W, p, 2l)
        A = np.swapaxes(Xi_w, 1, 2) @ Jt  # d acc / d s: (W, l, 2l)
        dS = np.empty_like(S)
        dS[:, :l] = S[:, l:]
        dS[:, l:] = A @ S
        dS[:, l + params.latent, cols] += theta[:, params.term] * on  # d acc / d theta
        return v, acc, dS

    for k in range(L):
        X[:, k], V[:, k] = x, v
        if sensitivities and k % stride == 0:
            S_all[:, k // stride] = S
        alive[:, k] = ok
        if k == L - 1:
            break
        nu, ph = win.nu[:, k], win.phase[:, k]
        Xi_w = Xi[ph]  # (W, p, l)
        on = (ph[:, None] == params.phase[None, :]).astype(float)  # (W, n)
        Sk = S if sensitivities else None
        for _ in range(substeps):
            with np.errstate(over="ignore", invalid="ignore"):
                k1 = field(x, v, Sk, nu, Xi_w, on)
                k2 = field(x + h / 2 * k1[0], v + h / 2 * k1[1],
                           None if Sk is None else Sk + h / 2 * k1[2], nu, Xi_w, on)
                k3 = field(x + h / 2 * k2[0], v + h / 2 * k2[1],
                           None if Sk is None else Sk + h / 2 * k2[2], nu, Xi_w, on)
                k4 = field(x + h * k3[0], v + h * k3[1],
                           None if Sk is None else Sk + h * k3[2], nu, Xi_w, on)
                x_new = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
                v_new = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
                S_new = None if Sk is None else Sk + h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
            good = ok & np.isfinite(x_new).all(1) & np.isfinite(v_new).all(1) & \
                np.all(np.abs(np.c_[x_new, v_new]) <= limit, axis=1)
            if S_new is not None:
                good &= np.isfinite(S_new).reshape(W, -1).all(1)
                S_new[~good] = 0.0
                Sk = S_new
            x = np.where(good[:, None], x_new, x)
            v = np.where(good[:, None], v_new, v)
            ok = good
        if sensitivities:
            S = Sk
    return X, V, S_all, alive
