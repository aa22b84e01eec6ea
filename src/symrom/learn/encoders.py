"""Steps (a) and (b) of the training: the linear autoencoder, as plug-ins.

An encoder plug-in fits a ``LinearAutoencoder`` from the contact-phase
configurations (step (a): encoder and decoder on the reconstruction loss) and
all training configurations (step (b): decoder refit with the encoder frozen).

``PCAEncoder`` takes each step's closed-form optimum:
(a) The reconstruction loss depends on (W_e, W_d) only through the rank-l map
    W_d W_e; by Eckart-Young its minimum is the orthogonal projector onto the
    top-l principal subspace of the centred contact-phase configurations. Any
    orthonormal basis of that subspace is optimal; we take the varimax rotation
    of the leading principal directions, the basis whose rows load on as few
    configuration components as possible (so a latent reads as "mostly CoM x"),
    ordered by latent variance, sign fixed so each row's largest entry is
    positive. The loss fixes only W_d B_e + B_d, so B_e = 0 is a free choice:
    xi is then a pure linear projection of q, and xi, dxi, ddxi share one map.
(b) With xi fixed the loss is linear least squares in (W_d, B_d).
Options: ``components`` restricts the encoder to the named configuration
components (their reconstruction is then minimised, the decoder still maps to
all 18); ``base_latents`` makes it block-diagonal, that many latents from the
principal directions of the base pose and the others from those of the joints,
so some latents are the body's motion and the rest leg synergies;
``scaling="spread"`` divides each component by its standard deviation
over the contact rows first (at least 5 % of the largest of its unit, so that a
joint held still is not blown up from its jitter), so radians and metres weigh
alike.

``AdamAutoencoder`` is the paper's gradient training of both steps.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar

import numpy as np

from symrom.learn.adam import AdamConfig, Progress, fit_autoencoder_adam, generator
from symrom.model.autoencoder import LinearAutoencoder
from symrom.names import BASE_NAMES, JOINT_NAMES, N_Q, Q_NAMES, Q_UNITS

SCALINGS = ("none", "spread")
SPREAD_FLOOR = 0.05  # a component's spread counts as at least this share of the largest of its unit


def unit_floored(std: np.ndarray, floor: float = SPREAD_FLOOR) -> np.ndarray:
    """(18,) spreads ``std`` of the configuration components, each raised to at least
    ``floor`` times the largest among the components of the same unit (rad or m)."""
    std = np.asarray(std, dtype=float)
    units = np.array([Q_UNITS[n] for n in Q_NAMES])
    out = std.copy()
    for u in set(units):
        same = units == u
        out[same] = np.maximum(std[same], floor * std[same].max())
    return np.maximum(out, 1e-12)


def varimax(W: np.ndarray, max_iter: int = 500, tol: float = 1e-13) -> np.ndarray:
    """Orthogonal rotation of the rows of W (l, n) maximising the varimax criterion.

    Kaiser's (1958) iteration, written here because SciPy and NumPy have none:
    each step is the polar factor of the criterion's gradient. The best rotation
    seen is kept, since on perfectly symmetric loadings the iteration can cycle.
    """
    L = W.T  # (n, l) loadings

    def criterion(B):
        return float(np.sum(np.var(B ** 2, axis=0)))

    R = best = np.eye(L.shape[1])
    best_val = criterion(L)
    for _ in range(max_iter):
        B = L @ R
        U, _, Vt = np.linalg.svd(L.T @ (B ** 3 - B @ np.diag(np.mean(B ** 2, axis=0))))
        R_new = U @ Vt
        val = criterion(L @ R_new)
        if val > best_val:
            best, best_val = R_new, val
        if np.abs(R_new - R).max() < tol ** 0.5 * 1e-1:  # rotation settled
            break
        R = R_new
    return (L @ best).T


def principal_encoder(q: np.ndarray, latent_dim: int, components: np.ndarray | None = None) -> np.ndarray:
    """Step (a), exact: W_e (l, 18), an orthonormal basis of the top-l principal
    subspace of q (N, 18), varimax-rotated, ordered by variance, signs fixed.

    With ``components`` (18,) bool the encoder reads only those columns (zero
    weight elsewhere): the optimum of their reconstruction loss.
    """
    if components is not None and not np.all(components):
        W = np.zeros((latent_dim, q.shape[1]))
        W[:, components] = principal_encoder(q[:, components], latent_dim)
        return W
    qc = q - q.mean(axis=0)
    _, _, Vt = np.linalg.svd(qc, full_matrices=False)
    W = Vt[:latent_dim].copy()
    if W.shape[0] < latent_dim:  # fewer samples than dimensions: pad with orthonormal rows
        Q, _ = np.linalg.qr(np.vstack([W, np.eye(q.shape[1])]).T)
        W = Q.T[:latent_dim]
    if latent_dim > 1:
        W = varimax(W)
        W = W[np.argsort(-np.var(qc @ W.T, axis=0), kind="stable")]
    sign = np.sign(W[np.arange(latent_dim), np.argmax(np.abs(W), axis=1)])
    return W * sign[:, None]


def fit_decoder(xi: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Step (b), exact: least-squares W_d (18, l), B_d (18,) with q ~ W_d xi + B_d."""
    X = np.hstack([xi, np.ones((xi.shape[0], 1))])
    coef, *_ = np.linalg.lstsq(X, q, rcond=None)
    return coef[:-1].T.copy(), coef[-1].copy()


def component_mask(components: tuple[str, ...] | None) -> np.ndarray:
    """(18,) bool of the named configuration components (all for None)."""
    if components is None:
        return np.ones(N_Q, dtype=bool)
    return np.isin(np.array(Q_NAMES), components)


def _named(components, allowed, key: str, unknown: str) -> tuple[str, ...]:
    """``components`` as a tuple; ValueError under ``key`` naming those not in ``allowed``
    (``unknown``: the message, ``{}`` where they go) or one named twice."""
    comps = tuple(components)
    bad = [str(c) for c in comps if c not in allowed]
    if bad:
        raise ValueError(f"{key}: {unknown.format(', '.join(bad))}; choose from {', '.join(allowed)}")
    if len(set(comps)) != len(comps):
        raise ValueError(f"{key}: a component is named twice")
    return comps


def check_components(components: tuple[str, ...] | None, latent_dim: int) -> tuple[str, ...] | None:
    """The components as a tuple; ValueError naming unknown, repeated or too few."""
    if components is None:
        return None
    comps = _named(components, Q_NAMES, "encoder_components", "unknown component(s) {}")
    if len(comps) < latent_dim:
        raise ValueError(f"encoder_components: {len(comps)} component(s) cannot span "
                         f"latent_dim {latent_dim}")
    return comps


# Base components along which the dynamics may be held invariant: on flat, uniform ground the
# same push moves the robot alike wherever it starts, in x and in y.
TRANSLATIONS = ("x", "y")


def check_invariant(components) -> tuple[str, ...]:
    """``components`` as a tuple of ``TRANSLATIONS``; ValueError naming an unknown or repeated one."""
    comps = tuple(components or ())
    return _named(comps, TRANSLATIONS, f"invariant={','.join(map(str, comps))!r}", "{} is no horizontal translation")


PIVOT_SHARE = 0.1  # a component gets a latent of its own only where it is at least this share of one's largest loading


def translation_basis(ae: LinearAutoencoder, components: tuple[str, ...],
                      q: np.ndarray | None = None) -> LinearAutoencoder:
    """The same latent space in a basis where moving the robot along ``components`` (base x,
    y) moves one latent each and leaves the others still.

    Gauss-Jordan on the encoder's columns of those components, pivoting on the latent that
    loads each most: the pivot latent keeps its row, every other row loses its multiple of it
    (at most 1, by the pivoting), so its loading on the component is exactly zero. The
    decoder follows (W_d T^-1), so the reconstruction is unchanged. A component no latent
    holds as a main part (its largest loading below ``PIVOT_SHARE`` of that latent's largest:
    y in jumps that hardly move sideways) would cost a latent for little; the encoder stops
    reading it instead, and the decoder is fitted again to the configurations ``q`` (N, 18)
    (step (b); ValueError without them). The latents left are positions the dynamics may read
    without reading where the robot stands (``reading_latents``)."""
    W, B = ae.W_e.copy(), ae.B_e.copy()
    l = W.shape[0]
    T = np.eye(l)
    pivots: list[int] = []
    dropped = []
    for name in components:
        c = Q_NAMES.index(name)
        free = [k for k in range(l) if k not in pivots]
        if not free:
            raise ValueError(f"invariant: latent_dim {l} leaves no latent to carry {name} (one per component)")
        k = max(free, key=lambda j: abs(W[j, c]))
        if abs(W[k, c]) < PIVOT_SHARE * np.abs(W[k]).max():
            W[:, c] = 0.0
            dropped.append(name)
            continue
        E = np.eye(l)
        E[:, k] = -W[:, c] / W[k, c]
        E[k, k] = 1.0
        W, B, T = E @ W, E @ B, E @ T
        W[np.arange(l) != k, c] = 0.0
        pivots.append(k)
    if not dropped:
        return LinearAutoencoder(W, B, ae.W_d @ np.linalg.inv(T), ae.B_d.copy())
    if q is None:
        raise ValueError(f"invariant: no latent holds {', '.join(dropped)} as a main part; refitting the decoder "
                         "without it needs the configurations (q)")
    W_d, B_d = fit_decoder(q @ W.T + B, q)
    return LinearAutoencoder(W, B, W_d, B_d)


def reading_latents(ae: LinearAutoencoder, components: tuple[str, ...]) -> np.ndarray:
    """(l,) bool: the latents whose position moves with any of ``components`` (a nonzero
    encoder loading)."""
    cols = [Q_NAMES.index(c) for c in components]
    return np.any(ae.W_e[:, cols] != 0.0, axis=1) if cols else np.zeros(ae.latent_dim, dtype=bool)


@dataclass(frozen=True)
class PCAEncoder:
    """The exact steps (a) and (b) (module docstring). components: names the encoder
    reads (None = all 18, the paper); scaling: ``none`` (the paper) or ``spread``;
    base_latents: None (one PCA, the paper) or the number of latents taken from the
    base pose, the rest from the joints."""

    kind: ClassVar[str] = "pca"
    components: tuple[str, ...] | None = None
    scaling: str = "none"
    base_latents: int | None = None

    def __post_init__(self) -> None:
        if self.scaling not in SCALINGS:
            raise ValueError(f"encoder scaling must be one of {SCALINGS}, got {self.scaling!r}")
        if self.components is not None:
            object.__setattr__(self, "components", tuple(self.components))
        if self.base_latents is not None and self.base_latents < 1:
            raise ValueError(f"base_latents must be >= 1, got {self.base_latents}")

    def fit(self, q_contact: np.ndarray, q_all: np.ndarray, latent_dim: int) -> LinearAutoencoder:
        """q_contact (Nc, 18), q_all (N, 18) configurations -> the autoencoder."""
        check_components(self.components, latent_dim)
        mask = component_mask(self.components)
        scale = unit_floored(q_contact.std(axis=0)) if self.scaling == "spread" else np.ones(q_contact.shape[1])
        qs = q_contact / scale
        if self.base_latents is None:
            W = principal_encoder(qs, latent_dim, mask)
        else:
            if not self.base_latents < latent_dim:
                raise ValueError(f"base_latents {self.base_latents} leaves no latent for the joints "
                                 f"(latent_dim {latent_dim})")
            base = mask & component_mask(BASE_NAMES)
            joints = mask & component_mask(JOINT_NAMES)
            k = latent_dim - self.base_latents
            if base.sum() < self.base_latents or joints.sum() < k:
                raise ValueError(f"encoder: {int(base.sum())} base and {int(joints.sum())} joint components "
                                 f"cannot span {self.base_latents} + {k} latents")
            W = np.vstack([principal_encoder(qs, self.base_latents, base), principal_encoder(qs, k, joints)])
        W_e = W / scale
        W_d, B_d = fit_decoder(q_all @ W_e.T, q_all)
        return LinearAutoencoder(W_e, np.zeros(latent_dim), W_d, B_d)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "components": None if self.components is None else list(self.components),
                "scaling": self.scaling, "base_latents": self.base_latents}


@dataclass
class AdamAutoencoder:
    """Steps (a) and (b) by Adam (``symrom.learn.adam``). ``generator_`` holds the
    run's generator after ``fit``, for the Adam regressor to continue."""

    kind: ClassVar[str] = "adam_autoencoder"
    config: AdamConfig = field(default_factory=AdamConfig)
    components: tuple[str, ...] | None = None
    seed: int = 0
    progress: Progress | None = field(default=None, repr=False, compare=False)
    generator_: Any = field(default=None, init=False, repr=False, compare=False)

    def fit(self, q_contact: np.ndarray, q_all: np.ndarray, latent_dim: int) -> LinearAutoencoder:
        check_components(self.components, latent_dim)
        self.generator_ = generator(self.seed)
        return fit_autoencoder_adam(q_contact, q_all, latent_dim, component_mask(self.components),
                                    self.config, self.generator_, self.progress or (lambda s, f: None))

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "config": asdict(self.config), "seed": self.seed,
                "components": None if self.components is None else list(self.components)}
