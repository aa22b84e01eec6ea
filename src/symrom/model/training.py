"""Multi-phase training, the paper's three steps, with two solvers.

(a) encoder and decoder on the contact phase, minimising the reconstruction
    loss ||q - W_d (W_e q + B_e) - B_d||^2;
(b) encoder frozen, decoder on all phases, same loss;
(c) autoencoder frozen, one sparse Xi per phase minimising
    ||ddxi - Theta Xi||^2 + ||ddq - W_d Theta Xi||^2 (+ sparsity).

``exact`` (default) takes each step's closed-form optimum:
(a) The reconstruction loss depends on (W_e, W_d) only through the rank-l map
    W_d W_e; by Eckart-Young its minimum is the orthogonal projector onto the
    top-l principal subspace of the centred contact-phase configurations. Any
    orthonormal basis of that subspace is optimal; we take the varimax rotation
    of the leading principal directions, the basis whose rows load on as few
    configuration components as possible (so a latent reads as "mostly CoM x"),
    ordered by latent variance, sign fixed so each row's largest entry is
    positive. The loss
    fixes only W_d B_e + B_d, so B_e = 0 is a free choice: xi is then a pure
    linear projection of q, and xi, dxi, ddxi share one map.
(b) With xi fixed the loss is linear least squares in (W_d, B_d).
(c) On a fixed support the loss is a quadratic whose normal equations are
    solved exactly; sequential thresholding (threshold 0.01) gives the support
    (see ``regression``).
``adam`` is the paper's gradient training (``adam.py``, needs torch).

Three options generalise the paper's losses (defaults reproduce them):
``encoder_components`` lets the encoder read only the named configuration
components (step (a) then minimises their reconstruction, the decoder still
maps to all 18), ``decoded_weight`` scales the decoded-acceleration term
||ddq - W_d Theta Xi||^2 of step (c), and ``alpha`` adds a ridge on the
standardised library features to step (c).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from symrom.data.dataset import Dataset
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.hybrid import HybridModel
from symrom.model.library import CandidateLibrary
from symrom.model.regression import STLSQConfig, stlsq
from symrom.names import Q_NAMES

SOLVERS = ("exact", "adam")

Progress = Callable[[str, float], None]  # (stage description, fraction done 0..1)


@dataclass
class AdamConfig:
    """The paper's gradient training (Table 1) with every hyper-parameter a field."""

    learning_rate: float = 1e-3
    batch_size: int = 100
    epochs: int = 501
    threshold_every: int = 100
    l1: float = 1e-4
    refine_epochs: int = 100
    ae_epochs: int | None = None  # epochs for steps (a) and (b); None = ``epochs``


@dataclass
class TrainConfig:
    """latent_dim l, polynomial order p, library options, solver and its settings.

    ``contact_phase`` names the phase that trains the encoder in step (a).
    ``encoder_components``: names of the q components the encoder reads (None =
    all 18, the paper); ``decoded_weight``: weight of the decoded-acceleration
    term of the SINDy loss (1 = the paper); ``alpha``: ridge on the standardised
    features in step (c) (``regression.STLSQConfig``; 0 = none, the paper).
    """

    latent_dim: int = 2
    poly_order: int = 1
    trig: bool = True
    inputs: bool = True
    solver: str = "exact"
    threshold: float = 0.01
    ridge: float = 0.0
    alpha: float = 0.0
    seed: int = 0
    contact_phase: str = "contact"
    encoder_components: tuple[str, ...] | None = None
    decoded_weight: float = 1.0
    adam: AdamConfig = field(default_factory=AdamConfig)

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise ValueError(f"unknown solver {self.solver!r}; choose from {SOLVERS}")
        if not 1 <= self.latent_dim <= 18:
            raise ValueError(f"latent_dim must be within 1..18, got {self.latent_dim}")
        if isinstance(self.adam, dict):
            self.adam = AdamConfig(**self.adam)
        if self.encoder_components is not None:
            comps = tuple(self.encoder_components)
            bad = [c for c in comps if c not in Q_NAMES]
            if bad:
                raise ValueError(f"encoder_components: unknown component(s) {', '.join(bad)}; "
                                 f"choose from {', '.join(Q_NAMES)}")
            if len(set(comps)) != len(comps):
                raise ValueError("encoder_components: a component is named twice")
            if len(comps) < self.latent_dim:
                raise ValueError(f"encoder_components: {len(comps)} component(s) cannot span "
                                 f"latent_dim {self.latent_dim}")
            self.encoder_components = comps
        if not self.alpha >= 0:
            raise ValueError(f"alpha must be >= 0, got {self.alpha}")
        if not self.decoded_weight >= 0:
            raise ValueError(f"decoded_weight must be >= 0, got {self.decoded_weight}")

    def encoder_mask(self) -> np.ndarray:
        """(18,) bool: the configuration components the encoder reads."""
        if self.encoder_components is None:
            return np.ones(len(Q_NAMES), dtype=bool)
        return np.isin(np.array(Q_NAMES), self.encoder_components)


def data_hash(ds: Dataset) -> str:
    """SHA-256 of the arrays a model is trained on."""
    h = hashlib.sha256()
    for a in (ds.jump, ds.q, ds.dq, ds.ddq, ds.u, ds.phase):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(np.asarray(ds.split, dtype=str).tobytes())
    return h.hexdigest()


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


def contact_rows(ds: Dataset, rows: np.ndarray, contact_phase: str) -> np.ndarray:
    pid = ds.phase_names.index(contact_phase) if contact_phase in ds.phase_names else 0
    sel = rows & (ds.phase == pid)
    return sel if sel.sum() > 0 else rows


def train(ds: Dataset, config: TrainConfig = TrainConfig(), rows: np.ndarray | None = None,
          progress: Progress | None = None) -> HybridModel:
    """Train a HybridModel on the ``train`` split of ``ds`` (or on boolean ``rows`` (N,)).

    Returns a model whose arrays are all in physical units (rad, m, s).
    """
    rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
    if not rows.any():
        raise ValueError("no training rows (the dataset has no 'train' jumps)")
    progress = progress or (lambda stage, frac: None)
    lib = CandidateLibrary(config.latent_dim, config.poly_order, config.trig, config.inputs)
    contact = contact_rows(ds, rows, config.contact_phase)
    if config.solver == "exact":
        progress("encoder (contact phase)", 0.0)
        W_e = principal_encoder(ds.q[contact], config.latent_dim, config.encoder_mask())
        B_e = np.zeros(config.latent_dim)
        progress("decoder (all phases)", 0.3)
        W_d, B_d = fit_decoder(ds.q[rows] @ W_e.T, ds.q[rows])
        ae = LinearAutoencoder(W_e, B_e, W_d, B_d)
        sw = np.sqrt(config.decoded_weight)
        Xi, mask = [], []
        for k, _ in enumerate(ds.phase_names):
            progress(f"dynamics ({ds.phase_names[k]})", 0.6 + 0.4 * k / len(ds.phase_names))
            r = rows & (ds.phase == k)
            if not r.any():
                Xi.append(np.zeros((lib.n_features, config.latent_dim)))
                mask.append(np.zeros((lib.n_features, config.latent_dim), dtype=bool))
                continue
            theta = lib.transform(ae.encode(ds.q[r]), ae.encode_derivative(ds.dq[r]),
                                  ae.encode_input(ds.u[r]))
            x, m = stlsq(theta, ae.encode_derivative(ds.ddq[r]), sw * ds.ddq[r], sw * ae.W_d,
                         STLSQConfig(config.threshold, config.ridge, config.alpha))
            Xi.append(x)
            mask.append(m)
        Xi_arr, mask_arr = np.array(Xi), np.array(mask)
    else:
        from symrom.model.adam import train_adam

        ae, Xi_arr, mask_arr = train_adam(ds, rows, contact, lib, config, progress)
    progress("done", 1.0)
    xi = ae.encode(ds.q[rows])
    dxi = ae.encode_derivative(ds.dq[rows])
    scale = np.maximum(np.concatenate([np.abs(xi).max(0), np.abs(dxi).max(0)]), 1e-9)
    info = {"robot": ds.robot, "motion": ds.motion, "source": ds.source, "dt": ds.dt,
            "training": asdict(config), "solver": config.solver, "seed": config.seed,
            "data_sha256": data_hash(ds), "n_train_rows": int(rows.sum()),
            "n_train_jumps": int(np.unique(ds.jump[rows]).size)}
    return HybridModel(ae, lib, list(ds.phase_names), Xi_arr, mask_arr, scale, info)


def reconstruction_error(model: HybridModel, ds: Dataset, rows: np.ndarray) -> float:
    """The reconstruction loss ||q - q_recon||^2 (squared 2-norm over the 18
    components, as the paper's L_recon) averaged over ``rows``: the sweep's E_dec."""
    q = ds.q[rows]
    return float(np.mean(np.sum((model.autoencoder.reconstruct(q) - q) ** 2, axis=1)))
