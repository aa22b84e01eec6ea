"""Planted hybrid systems: known sparse latent dynamics embedded linearly in 18-D.

Each jump runs contact -> flight -> contact (the pronking schedule, 3/8, 2/8,
3/8 of its samples). In phase k the latent state obeys
ddxi = Theta(xi, dxi, nu) Xi_k with a planted sparse Xi_k of the default
library, driven by smooth random inputs nu held constant over each sample.
The configuration is q = E xi + c (+ noise), E (18, l) with orthonormal
columns, and the inputs u = E nu, so that an encoder W_e = E^T sees the planted
xi and nu exactly. Useful to check that a learner recovers what was planted.

Embeddings: ``axis`` (latent i is configuration component i), ``block`` (each
component follows one latent, with its own gain and offset) and ``dense`` (a
random rotation). The linear autoencoder's loss determines the latent plane
but not its basis; with ``dense`` the planted basis is not identifiable and
sin/cos of rotated coordinates leave the library's span, so only ``axis`` and
``block`` admit an exact sparse model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.data.dataset import Dataset, jump_bounds, validate
from symrom.model.library import Library
from symrom.names import GRAVITY, N_JOINTS, N_Q

# Planted equations for l = 2, p = 1, by feature name; every phase damped so
# that long rollouts stay bounded.
PLANTED_2D: dict[str, list[dict[str, float]]] = {
    "contact": [
        {"1": 0.5, "xi1": -6.0, "dxi1": -1.2, "sin(xi2)": 1.5, "nu1": 3.0},
        {"1": -1.0, "xi2": -4.0, "dxi2": -0.8, "cos(xi1)": 2.0, "nu2": 2.5},
    ],
    "flight": [
        {"xi1": -2.0, "dxi1": -0.6, "nu1": 1.5},
        {"1": -3.0, "xi2": -1.0, "dxi2": -0.4, "sin(xi1)": 1.0},
    ],
}


@dataclass
class PlantedSystem:
    """The truth behind a planted dataset: library, Xi per phase (P, p, l), embedding."""

    library: Library
    phase_names: list[str]
    Xi: np.ndarray
    E: np.ndarray  # (18, l) orthonormal columns
    c: np.ndarray  # (18,)


def planted_xi(library: Library, equations: dict[str, list[dict[str, float]]]) -> np.ndarray:
    """(P, p, l) coefficient matrices from ``{phase: [{feature: coef}, ...]}``."""
    names = library.feature_names
    Xi = np.zeros((len(equations), library.n_features, library.latent_dim))
    for k, rows in enumerate(equations.values()):
        for j, eq in enumerate(rows):
            for feat, coef in eq.items():
                Xi[k, names.index(feat), j] = coef
    return Xi


def _inputs(rng: np.random.Generator, t: np.ndarray, l: int, amp: np.ndarray) -> np.ndarray:
    """Smooth random latent inputs (n, l): sums of three sinusoids per channel."""
    nu = np.zeros((t.size, l))
    for i in range(l):
        for _ in range(3):
            a, f, ph = rng.uniform(0.3, 1.0), rng.uniform(0.5, 3.0), rng.uniform(0, 2 * np.pi)
            nu[:, i] += amp[i] * a * np.sin(2 * np.pi * f * t + ph)
    return nu


EMBEDDINGS = ("axis", "block", "dense")


def embedding_matrix(kind: str, l: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """E (18, l) with orthonormal columns and offsets c (18,) of an embedding ``kind``."""
    if kind == "axis":
        E = np.zeros((N_Q, l))
        E[np.arange(l), np.arange(l)] = 1.0
        return E, np.r_[np.zeros(l), rng.uniform(-1, 1, N_Q - l)]
    if kind == "block":
        owner = rng.permutation(np.arange(N_Q) % l)
        E = np.zeros((N_Q, l))
        E[np.arange(N_Q), owner] = rng.uniform(0.5, 1.5, N_Q) * rng.choice([-1, 1], N_Q)
        return E / np.linalg.norm(E, axis=0), rng.uniform(-1, 1, N_Q)
    if kind == "dense":
        return np.linalg.qr(rng.standard_normal((N_Q, l)))[0], rng.uniform(-1, 1, N_Q)
    raise ValueError(f"unknown embedding {kind!r}; choose from {EMBEDDINGS}")


def make_planted_dataset(n_jumps: int = 24, n_samples: int = 400, embedding: str = "block",
                         noise: float = 1e-4, seed: int = 0, dt: float = 0.002,
                         substeps: int = 8, equations: dict[str, list[dict[str, float]]] | None = None,
                         embedding_seed: int | None = None,
                         amplitude: tuple[float, float] = (3.0, 2.0)) -> tuple[Dataset, PlantedSystem]:
    """A planted pronk-like dataset and its truth.

    embedding: ``axis``, ``block`` or ``dense`` (see the module docstring);
    equations: ``{phase: [{feature: coef}] * 2}`` for l = 2, p = 1 (default
    ``PLANTED_2D``); embedding_seed: seed of the embedding alone (default
    ``seed``), so two systems can share one embedding.
    noise: standard deviation of Gaussian noise on q, dq, ddq, relative to each
    component's spread. Splits: 70 % train, 20 % val, 10 % test (at least one).
    """
    rng = np.random.default_rng(seed)
    equations = equations or PLANTED_2D
    lib = Library.standard(2, 1)
    phase_names = list(equations)
    Xi = planted_xi(lib, equations)
    l = lib.latent_dim
    E, c = embedding_matrix(embedding, l, np.random.default_rng(seed if embedding_seed is None
                                                                else embedding_seed))
    n1, n2 = round(n_samples * 3 / 8), round(n_samples * 5 / 8)
    sched = np.r_[np.zeros(n1), np.ones(n2 - n1), np.zeros(n_samples - n2)].astype(np.int8)
    h = dt / substeps
    amp = np.asarray(amplitude, dtype=float)  # the default: wide enough that sin, cos differ from their linearisation

    def acc(x, v, nu, k):  # batch over jumps: (J, l) each, k scalar phase
        return lib.transform(x, v, nu) @ Xi[k]

    t = np.arange(n_samples) * dt
    nu = np.stack([_inputs(rng, t, l, amp) for _ in range(n_jumps)])  # (J, n, l)
    x = rng.uniform(-0.6, 0.6, (n_jumps, l)) * amp
    v = rng.uniform(-0.6, 0.6, (n_jumps, l)) * amp
    X, V, A = (np.empty((n_jumps, n_samples, l)) for _ in range(3))
    for i in range(n_samples):
        k, w = sched[i], nu[:, i]
        X[:, i], V[:, i], A[:, i] = x, v, acc(x, v, w, k)
        for _ in range(substeps):  # RK4, input and phase held over the sample
            k1x, k1v = v, acc(x, v, w, k)
            k2x, k2v = v + h / 2 * k1v, acc(x + h / 2 * k1x, v + h / 2 * k1v, w, k)
            k3x, k3v = v + h / 2 * k2v, acc(x + h / 2 * k2x, v + h / 2 * k2v, w, k)
            k4x, k4v = v + h * k3v, acc(x + h * k3x, v + h * k3v, w, k)
            x = x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    flat = (n_jumps * n_samples, l)
    qs, dqs, ddqs, us = (X.reshape(flat) @ E.T + c, V.reshape(flat) @ E.T,
                         A.reshape(flat) @ E.T, nu.reshape(flat) @ E.T)
    contacts = np.tile(np.repeat((sched == 0)[:, None], 4, axis=1).astype(np.uint8), (n_jumps, 1))
    phases = np.tile(sched, n_jumps)
    jumps = np.repeat(np.arange(n_jumps, dtype=np.int32), n_samples)
    ts = np.tile(t, n_jumps)
    q, dq, ddq, u = qs, dqs, ddqs, us
    for arr in (q, dq, ddq):
        spread = np.ptp(arr, axis=0) + 1e-3
        arr += noise * spread * rng.standard_normal(arr.shape)
    n_test = max(1, round(0.1 * n_jumps))
    n_val = max(1, round(0.2 * n_jumps)) if n_jumps > 2 else 0
    split = np.array(["train"] * (n_jumps - n_val - n_test) + ["val"] * n_val + ["test"] * n_test,
                     dtype=object)
    ds = Dataset(robot="planted", motion="pronk", source="synthetic", phase_names=phase_names,
                 jump=jumps, t=ts, q=q, dq=dq, ddq=ddq,
                 tau=u[:, :N_JOINTS].copy(), contact=contacts, u=u,
                 phase=phases, split=split, dt=dt,
                 generator={"kind": "planted", "n_jumps": n_jumps, "n_samples": n_samples,
                            "embedding": embedding, "noise": noise, "seed": seed,
                            "equations": equations})
    validate(ds)
    return ds, PlantedSystem(lib, phase_names, Xi, E, c)


# Stiff, lightly damped latents: what a logged acceleration's lag turns into negative damping.
LIGHTLY_DAMPED: dict[str, list[dict[str, float]]] = {
    "contact": [{"1": 1.0, "xi1": -60.0, "dxi1": -0.6, "nu1": 20.0},
                {"1": -0.5, "xi2": -40.0, "dxi2": -0.4, "nu2": 15.0}],
    "flight": [{"xi1": -50.0, "dxi1": -0.5}, {"1": -2.0, "xi2": -45.0, "dxi2": -0.5}],
}


def make_lagged_dataset(n_jumps: int, n_samples: int, lag: int = 10, seed: int = 7
                        ) -> tuple[Dataset, PlantedSystem]:
    """A planted dataset of ``LIGHTLY_DAMPED`` latents (axis embedding, little noise) whose
    logged accelerations lag the motion by ``lag`` samples, as a causal filter's do (each jump's
    first ``lag`` rows hold its first value); and its truth."""
    ds, truth = make_planted_dataset(n_jumps, n_samples, embedding="axis", noise=1e-5, seed=seed,
                                     equations=LIGHTLY_DAMPED, amplitude=(1.0, 1.0))
    ddq = ds.ddq.copy()
    for a, b in jump_bounds(ds.jump):
        ddq[a + lag:b] = ds.ddq[a:b - lag]
        ddq[a:a + lag] = ds.ddq[a]
    ds.ddq = ddq
    return ds, truth


def make_slip_dataset(n_jumps: int = 6, n_samples: int = 300, k_s: float = 3000.0, l_0: float = 0.35,
                      m: float = 10.0, seed: int = 0, dt: float = 0.002,
                      substeps: int = 8) -> tuple[Dataset, dict[str, float]]:
    """Spring-mass hops with a known actuation: data whose truth is the aSLIP model.

    A point mass m (kg) on a massless spring leg (k_s N/m, rest length l_0 m)
    starts compressed on a fixed pivot, is pushed by a smooth actuation
    acceleration u(t) (m/s^2) in contact, lifts off when the leg reaches l_0
    while extending, flies ballistically and lands on a new pivot placed l_0
    from the CoM. Phase, pivot and u are decided at each sample's start and held
    over the 2 ms sample (the rollout's zero-order hold); RK4 with ``substeps``
    steps integrates in between. Stored as an 18-D dataset: q, dq, ddq carry the
    CoM in the base x, y, z columns (everything else 0); all four feet sit on
    the pivot and are flagged in contact during stance; the wrench force
    columns hold the actuation force m u (N) in contact and 0 in flight, so that
    ``u[:, 12:15] / m`` is the aSLIP's u; ddq is the exact model acceleration.
    Returns the dataset (robot ``slip``, no URDF) and ``{"k_s", "l_0", "m"}``.
    """
    rng = np.random.default_rng(seed)
    g = np.array([0.0, 0.0, -GRAVITY])
    n = n_samples

    def acc(b, p, u, c):  # (3,) each, c bool
        if not c:
            return g
        leg = b - p
        r = np.linalg.norm(leg)
        return k_s / m * abs(l_0 - r) * leg / r + g + u

    rows = []
    for _ in range(n_jumps):
        tilt = rng.uniform(-0.25, 0.25, 2)  # leg inclination about y and x at the start, rad
        direction = np.array([np.sin(tilt[0]), np.sin(tilt[1]), np.cos(tilt[0]) * np.cos(tilt[1])])
        p = np.r_[rng.uniform(-0.5, 0.5, 2), 0.0]
        b = p + rng.uniform(0.7, 0.8) * l_0 * direction / np.linalg.norm(direction)
        v = np.r_[rng.uniform(-0.5, 0.5, 2), rng.uniform(0.0, 0.4)]
        amp, freq, phase0 = rng.uniform(0.5, 2.0, 3), rng.uniform(1.0, 4.0, 3), rng.uniform(0, 2 * np.pi, 3)
        bias = np.array([0.0, 0.0, 3.0])  # some upward push so every hop lifts off
        contact, high = True, False
        for i in range(n):
            t = i * dt
            leg = b - p
            if contact and np.linalg.norm(leg) >= l_0 and leg @ v > 0:
                contact, high = False, False  # lift-off
            elif not contact:
                # Foot placed ahead of the CoM by about half a stance of travel (Raibert's
                # neutral point) so that landings rebound instead of tipping over.
                d = np.clip(-0.09 * v[:2] / l_0, -0.5, 0.5)
                td_dir = np.r_[d, np.sqrt(1.0 - d @ d)]
                high |= b[2] > l_0 * td_dir[2]  # land only after rising above touch-down height
                if high and b[2] <= l_0 * td_dir[2] and v[2] < 0:
                    contact, p = True, b - l_0 * td_dir  # touch-down on a fresh pivot
            u = (bias + amp * np.sin(2 * np.pi * freq * t + phase0)) if contact else np.zeros(3)
            rows.append((t, b.copy(), v.copy(), acc(b, p, u, contact), p.copy(), u, contact))
            h = dt / substeps
            for _ in range(substeps):
                k1x, k1v = v, acc(b, p, u, contact)
                k2x, k2v = v + h / 2 * k1v, acc(b + h / 2 * k1x, p, u, contact)
                k3x, k3v = v + h / 2 * k2v, acc(b + h / 2 * k2x, p, u, contact)
                k4x, k4v = v + h * k3v, acc(b + h * k3x, p, u, contact)
                b = b + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
                v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    N = len(rows)
    t, B, V, A, P, U, C = (np.array(col) for col in zip(*rows))
    q, dq, ddq, u = (np.zeros((N, N_Q)) for _ in range(4))
    q[:, N_JOINTS:N_JOINTS + 3], dq[:, N_JOINTS:N_JOINTS + 3], ddq[:, N_JOINTS:N_JOINTS + 3] = B, V, A
    u[:, N_JOINTS:N_JOINTS + 3] = m * U  # force, N; zero in flight (U is)
    flight_feet = B - np.array([0.0, 0.0, l_0])
    foot_pos = np.repeat(np.where(C[:, None], P, flight_feet)[:, None], 4, axis=1)
    n_test = max(1, round(0.2 * n_jumps))
    split = np.array(["train"] * (n_jumps - n_test) + ["test"] * n_test, dtype=object)
    ds = Dataset(robot="slip", motion="pronk", source="synthetic", phase_names=["contact", "flight"],
                 jump=np.repeat(np.arange(n_jumps, dtype=np.int32), n), t=t,
                 q=q, dq=dq, ddq=ddq, tau=np.zeros((N, N_JOINTS)),
                 contact=np.repeat(C[:, None], 4, axis=1).astype(np.uint8), u=u,
                 phase=(~C).astype(np.int8), split=split, foot_pos=foot_pos, dt=dt,
                 generator={"kind": "slip", "n_jumps": n_jumps, "n_samples": n_samples, "k_s": k_s,
                            "l_0": l_0, "m": m, "seed": seed, "substeps": substeps})
    validate(ds)
    return ds, {"k_s": k_s, "l_0": l_0, "m": m}
