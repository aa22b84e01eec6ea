"""The paper's gradient training of the three steps with Adam.

(a) W_e, B_e, W_d, B_d on contact-phase configurations, reconstruction loss;
(b) W_d, B_d on all phases, encoder frozen (``fit_autoencoder_adam``);
(c) per phase, Xi on the SINDy loss ||ddxi - Theta Xi||^2 + ||ddq - W_d Theta
Xi||^2 + l1 ||Xi||_1 with the entries |Xi| < threshold zeroed (and kept zero)
every ``threshold_every`` epochs, then ``refine_epochs`` more epochs on the
surviving terms without L1 (the ``Adam`` regressor). Mini-batches of
``batch_size`` samples, Adam at ``learning_rate`` (Table 1: 1e-3, 100, 501
epochs) with torch.optim.Adam's defaults (betas 0.9 and 0.999, eps 1e-8).
Everything runs in float64 on one thread. One NumPy generator, seeded once, draws the
initialisation and every epoch's order of the rows, for the three steps in turn. The losses
are quadratic (plus the L1 term), so their gradients are written in closed form, and a whole
epoch of mini-batch steps is one compiled call (``symrom.learn.compiled``): a step of the
paper's sizes is a few microseconds of arithmetic, where an array library's per-operation
overhead would be most of its time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar

import numpy as np

from symrom.learn.regressors.base import Coefficients, RegressionProblem, Regressor
from symrom.model.autoencoder import LinearAutoencoder

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

    def __post_init__(self) -> None:
        if not (np.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"adam learning_rate must be a positive number, got {self.learning_rate}")
        if not (np.isfinite(self.l1) and self.l1 >= 0):
            raise ValueError(f"adam l1 must be a non-negative number, got {self.l1}")
        for name, least in (("batch_size", 1), ("epochs", 1), ("threshold_every", 1), ("refine_epochs", 0),
                            ("ae_epochs", 1)):
            value = getattr(self, name)
            if value is not None and (int(value) != value or value < least):
                raise ValueError(f"adam {name} must be a whole number of at least {least}, got {value}")


def check_seed(seed: int) -> int:
    """``seed`` as an int, refused unless it is a non-negative integer (what seeds a generator)."""
    if int(seed) != seed or seed < 0:
        raise ValueError(f"the adam solver's seed must be a non-negative integer, got {seed}")
    return int(seed)


def generator(seed: int) -> np.random.Generator:
    """The generator of one training run (``check_seed``)."""
    return np.random.default_rng(check_seed(seed))


class _Moments:
    """Adam's state for one parameter vector of length k: both moments and the step count."""

    def __init__(self, k: int) -> None:
        self.m, self.v, self.t = np.zeros(k), np.zeros(k), 0


def fit_autoencoder_adam(q_contact: np.ndarray, q_all: np.ndarray, latent_dim: int,
                         encoder_mask: np.ndarray, config: AdamConfig, gen: np.random.Generator,
                         progress: Progress) -> LinearAutoencoder:
    """Steps (a) and (b) by Adam: q_contact (Nc, 18) and q_all (N, 18) configurations,
    encoder_mask (18,) the components the encoder reads; ``gen`` the run's generator."""
    from symrom.learn.compiled import adam_recon_epoch

    l, n = latent_dim, q_all.shape[1]
    ae_epochs = config.ae_epochs if config.ae_epochs is not None else config.epochs
    # W_e, B_e, W_d, B_d are views of one vector: step (a) trains all of it, step (b) the
    # decoder's tail.
    flat = np.zeros(2 * l * n + l + n)
    W_e, B_e, W_d, B_d = (v.reshape(shape) for v, shape in zip(
        np.split(flat, np.cumsum([l * n, l, n * l])), ((l, n), (l,), (n, l), (n,))))
    W_e[:] = (gen.random((l, n)) * 2 - 1) * (1.0 / np.sqrt(n))
    W_d[:] = (gen.random((n, l)) * 2 - 1) / np.sqrt(l)
    emask = np.asarray(encoder_mask, dtype=float)
    for q, start, stage, done, share in ((q_contact, 0, "encoder (contact phase)", 0.0, 0.3),
                                         (q_all, l * n + l, "decoder (all phases)", 0.3, 0.2)):
        q = np.ascontiguousarray(q, dtype=float)
        state = _Moments(flat.size - start)
        for e in range(ae_epochs):
            state.t = adam_recon_epoch(q, gen.permutation(q.shape[0]), int(config.batch_size), flat, start, l,
                                       emask, state.m, state.v, state.t, float(config.learning_rate))
            progress(stage, done + share * (e + 1) / ae_epochs)
    return LinearAutoencoder(W_e * emask, B_e.copy(), W_d.copy(), B_d.copy())


@dataclass
class Adam(Regressor):
    """Step (c) by Adam with an L1 penalty and periodic thresholding (module docstring).

    threshold: |Xi| below it is zeroed; seed: of the generator when none is
    given; generator: a NumPy generator to continue (the autoencoder's, so a
    whole training run draws from one stream); progress: (stage, fraction).
    """

    kind: ClassVar[str] = "adam"
    config: AdamConfig = field(default_factory=AdamConfig)
    threshold: float = 0.01
    seed: int = 0
    generator: Any = field(default=None, repr=False, compare=False)
    progress: Progress | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "config": asdict(self.config), "threshold": self.threshold, "seed": self.seed}

    def _reduce(self, problem: RegressionProblem, allowed: np.ndarray,
                init: Coefficients | None) -> Coefficients:
        from symrom.learn.compiled import adam_sindy_epoch

        ac = self.config
        gen = self.generator if self.generator is not None else generator(self.seed)
        say = self.progress or (lambda stage, frac: None)
        P, p, l = problem.shape
        Xis, masks = np.zeros((P, p, l)), np.zeros((P, p, l), dtype=bool)
        total = ac.epochs + ac.refine_epochs
        for k, (name, ph) in enumerate(zip(problem.phase_names, problem.phases)):
            if ph is None:
                continue
            Wd = np.asarray(ph.W_d, dtype=float)
            # theta | ddxi + ddq W_d, and I + W_d^T W_d: the loss's gradient (adam_sindy_epoch)
            rows = np.hstack([ph.theta, ph.ddxi + ph.ddq @ Wd]).astype(float)
            M = np.eye(l) + Wd.T @ Wd
            Xi = np.zeros((p, l))
            mask = np.repeat(allowed[k][:, None], l, axis=1).astype(float)
            state = _Moments(p * l)

            def epoch(l1: float) -> None:
                state.t = adam_sindy_epoch(rows, M, Xi, mask, gen.permutation(rows.shape[0]), int(ac.batch_size),
                                           float(l1), state.m, state.v, state.t, float(ac.learning_rate))

            def threshold() -> None:
                mask[:] *= np.abs(Xi) >= self.threshold
                Xi[:] *= mask

            for e in range(ac.epochs):
                epoch(ac.l1)
                if (e + 1) % ac.threshold_every == 0:
                    threshold()
                say(f"dynamics ({name})", 0.5 + 0.5 * (k + (e + 1) / total) / P)
            threshold()  # the last before the refinement
            for e in range(ac.refine_epochs):
                epoch(0.0)
                say(f"dynamics ({name}, refinement)", 0.5 + 0.5 * (k + (ac.epochs + e + 1) / total) / P)
            m = mask.astype(bool)
            Xis[k] = Xi * m
            masks[k] = m
        return Coefficients(Xis, masks)
