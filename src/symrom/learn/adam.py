"""The paper's gradient training of the three steps with Adam (needs torch).

(a) W_e, B_e, W_d, B_d on contact-phase configurations, reconstruction loss;
(b) W_d, B_d on all phases, encoder frozen (``fit_autoencoder_adam``);
(c) per phase, Xi on the SINDy loss ||ddxi - Theta Xi||^2 + ||ddq - W_d Theta
Xi||^2 + l1 ||Xi||_1 with the entries |Xi| < threshold zeroed (and kept zero)
every ``threshold_every`` epochs, then ``refine_epochs`` more epochs on the
surviving terms without L1 (the ``Adam`` regressor). Mini-batches of
``batch_size`` samples, Adam at ``learning_rate`` (Table 1: 1e-3, 100, 501
epochs). Everything runs in float64 on the CPU, one thread (the matrices are
tiny; threads only add overhead). One torch generator, seeded once, draws the
initialisation and every mini-batch of the three steps in turn.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
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


def _torch():
    try:
        import torch
    except ImportError:
        raise ImportError("the 'adam' solver needs PyTorch: pip install 'symrom[adam]' "
                          "(torch==2.13.0)") from None
    return torch


@contextmanager
def single_thread(torch) -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def generator(seed: int):
    """The torch generator of one training run."""
    return _torch().Generator().manual_seed(int(seed))


def _epochs(n_rows: int, batch: int, epochs: int, gen, torch, step: Callable[[object], None],
            on_epoch: Callable[[int], None] | None = None) -> None:
    for e in range(epochs):
        perm = torch.randperm(n_rows, generator=gen)
        for a in range(0, n_rows, batch):
            step(perm[a:a + batch])
        if on_epoch:
            on_epoch(e)


def fit_autoencoder_adam(q_contact: np.ndarray, q_all: np.ndarray, latent_dim: int,
                         encoder_mask: np.ndarray, config: AdamConfig, gen,
                         progress: Progress) -> LinearAutoencoder:
    """Steps (a) and (b) by Adam: q_contact (Nc, 18) and q_all (N, 18) configurations,
    encoder_mask (18,) the components the encoder reads; ``gen`` the run's generator."""
    torch = _torch()
    l, n = latent_dim, q_all.shape[1]
    f64 = dict(dtype=torch.float64)
    ae_epochs = config.ae_epochs if config.ae_epochs is not None else config.epochs
    with single_thread(torch):
        qc = torch.as_tensor(q_contact, **f64)
        bound = 1.0 / np.sqrt(n)
        W_e = ((torch.rand((l, n), generator=gen, **f64) * 2 - 1) * bound).requires_grad_()
        B_e = torch.zeros(l, **f64, requires_grad=True)
        W_d = ((torch.rand((n, l), generator=gen, **f64) * 2 - 1) / np.sqrt(l)).requires_grad_()
        B_d = torch.zeros(n, **f64, requires_grad=True)
        opt = torch.optim.Adam([W_e, B_e, W_d, B_d], lr=config.learning_rate)
        emask = torch.as_tensor(encoder_mask, **f64)

        def recon_step(q):
            def step(idx):
                qb = q[idx]
                loss = ((qb - ((qb @ (W_e * emask).T + B_e) @ W_d.T + B_d)) ** 2).sum(1).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
            return step

        _epochs(qc.shape[0], config.batch_size, ae_epochs, gen, torch, recon_step(qc),
                lambda e: progress("encoder (contact phase)", 0.3 * (e + 1) / ae_epochs))
        W_e.requires_grad_(False)
        B_e.requires_grad_(False)
        qa = torch.as_tensor(q_all, **f64)
        opt = torch.optim.Adam([W_d, B_d], lr=config.learning_rate)
        _epochs(qa.shape[0], config.batch_size, ae_epochs, gen, torch, recon_step(qa),
                lambda e: progress("decoder (all phases)", 0.3 + 0.2 * (e + 1) / ae_epochs))
        return LinearAutoencoder((W_e * emask).detach().numpy().copy(), B_e.detach().numpy().copy(),
                                 W_d.detach().numpy().copy(), B_d.detach().numpy().copy())


@dataclass
class Adam(Regressor):
    """Step (c) by Adam with an L1 penalty and periodic thresholding (module docstring).

    threshold: |Xi| below it is zeroed; seed: of the generator when none is
    given; generator: a torch generator to continue (the autoencoder's, so a
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
        torch = _torch()
        ac = self.config
        gen = self.generator if self.generator is not None else generator(self.seed)
        say = self.progress or (lambda stage, frac: None)
        P, p, l = problem.shape
        f64 = dict(dtype=torch.float64)
        Xis, masks = np.zeros((P, p, l)), np.zeros((P, p, l), dtype=bool)
        with single_thread(torch):
            for k, (name, ph) in enumerate(zip(problem.phase_names, problem.phases)):
                if ph is None:
                    continue
                theta = torch.as_tensor(ph.theta, **f64)
                ddxi = torch.as_tensor(ph.ddxi, **f64)
                ddq = torch.as_tensor(ph.ddq, **f64)
                Wd = torch.as_tensor(ph.W_d, **f64)
                Xi = torch.zeros((p, l), **f64, requires_grad=True)
                mask = torch.as_tensor(np.repeat(allowed[k][:, None], l, axis=1), **f64)
                opt = torch.optim.Adam([Xi], lr=ac.learning_rate)
                l1 = {"w": ac.l1}

                def sindy_step(idx):
                    z = theta[idx] @ (Xi * mask)
                    loss = (((ddxi[idx] - z) ** 2).sum(1).mean()
                            + ((ddq[idx] - z @ Wd.T) ** 2).sum(1).mean()
                            + l1["w"] * (Xi * mask).abs().sum())
                    opt.zero_grad()
                    loss.backward()
                    opt.step()

                total = ac.epochs + ac.refine_epochs

                def threshold(e, k=k, name=name):
                    if (e + 1) % ac.threshold_every == 0:
                        with torch.no_grad():
                            mask.mul_((Xi.abs() >= self.threshold).to(mask.dtype))
                            Xi.mul_(mask)
                    say(f"dynamics ({name})", 0.5 + 0.5 * (k + (e + 1) / total) / P)

                _epochs(theta.shape[0], ac.batch_size, ac.epochs, gen, torch, sindy_step, threshold)
                with torch.no_grad():  # final thresholding before refinement
                    mask.mul_((Xi.abs() >= self.threshold).to(mask.dtype))
                    Xi.mul_(mask)
                l1["w"] = 0.0
                _epochs(theta.shape[0], ac.batch_size, ac.refine_epochs, gen, torch, sindy_step,
                        lambda e, k=k, name=name: say(f"dynamics ({name}, refinement)",
                                                      0.5 + 0.5 * (k + (ac.epochs + e + 1) / total) / P))
                m = mask.numpy().astype(bool)
                Xis[k] = Xi.detach().numpy() * m
                masks[k] = m
        return Coefficients(Xis, masks)
