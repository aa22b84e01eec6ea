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
initialisation and every mini-batch of the three steps in turn. The losses are
quadratic (plus the L1 term), so their gradients are written in closed form
(``recon_grads``, ``sindy_grad``; checked against autograd in the tests) and
handed to Adam's update (``AdamStep``, torch's own to the bit): a mini-batch step is then a
few small products instead of an autograd graph, which was most of the training's time.
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


class AdamStep:
    """``torch.optim.Adam(params=[param], lr=lr)``'s update of one CPU tensor (its defaults: betas
    0.9 and 0.999, eps 1e-8, no weight decay, no AMSGrad) in the torch operations and Python
    scalars of its single-tensor path (the one torch takes for CPU tensors), so the same numbers
    to the bit (``tests/test_planted.py`` holds it to torch's). Written out because constructing
    torch's optimizer imports ``torch._dynamo``, 2-3 s of every process that trains with Adam.
    ``step(grad)`` updates ``param`` in place."""

    BETA1, BETA2, EPS = 0.9, 0.999, 1e-8

    def __init__(self, param, lr: float, torch) -> None:
        self.param, self.lr = param, lr
        self.exp_avg = torch.zeros_like(param, memory_format=torch.preserve_format)
        self.exp_avg_sq = torch.zeros_like(param, memory_format=torch.preserve_format)
        # torch counts the steps in a scalar tensor of its scalar type (float32 unless the
        # default type is float64), so do we: the count it reads back is that tensor's
        scalar = torch.float64 if torch.get_default_dtype() == torch.float64 else torch.float32
        self.step_t = torch.tensor(0.0, dtype=scalar)

    def step(self, grad) -> None:
        beta1, beta2 = self.BETA1, self.BETA2
        self.step_t += 1
        self.exp_avg.lerp_(grad, 1 - beta1)
        self.exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
        step = self.step_t.item()
        bias_correction1 = 1 - beta1**step
        bias_correction2 = 1 - beta2**step
        step_size = self.lr / bias_correction1
        bias_correction2_sqrt = bias_correction2**0.5
        denom = (self.exp_avg_sq.sqrt() / bias_correction2_sqrt).add_(self.EPS)
        self.param.addcdiv_(self.exp_avg, denom, value=-step_size)


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


def recon_grads(q, W_e, B_e, W_d, B_d, emask) -> tuple:
    """The gradients of the reconstruction loss mean_b ||q_b - ((q_b (W_e*emask)^T + B_e) W_d^T +
    B_d)||^2 of a mini-batch q (B, n) with respect to (W_e, B_e, W_d, B_d), shapes (l, n), (l,),
    (n, l), (n,); W_e's is zero where ``emask`` (n,) is."""
    h = q @ (W_e * emask).T + B_e
    d = (h @ W_d.T + B_d - q) * (2.0 / q.shape[0])  # d loss / d prediction
    dh = d @ W_d
    return (dh.T @ q) * emask, dh.sum(0), d.T @ h, d.sum(0)


def sindy_grad(theta, ddxi, ddq, W_d, Xi, mask, l1: float):
    """The gradient with respect to Xi (p, l) of step (c)'s mini-batch loss
    mean_b ||ddxi_b - z_b||^2 + mean_b ||ddq_b - z_b W_d^T||^2 + l1 ||Xi*mask||_1, with
    z = theta (Xi*mask): theta (B, p), ddxi (B, l), ddq (B, n), W_d (n, l), mask (p, l)."""
    Xm = Xi * mask
    z = theta @ Xm
    d = ((z - ddxi) + (z @ W_d.T - ddq) @ W_d) * (2.0 / theta.shape[0])
    g = theta.T @ d
    if l1:
        g = g + l1 * Xm.sign()
    return g * mask


def fit_autoencoder_adam(q_contact: np.ndarray, q_all: np.ndarray, latent_dim: int,
                         encoder_mask: np.ndarray, config: AdamConfig, gen,
                         progress: Progress) -> LinearAutoencoder:
    """Steps (a) and (b) by Adam: q_contact (Nc, 18) and q_all (N, 18) configurations,
    encoder_mask (18,) the components the encoder reads; ``gen`` the run's generator."""
    torch = _torch()
    l, n = latent_dim, q_all.shape[1]
    f64 = dict(dtype=torch.float64)
    ae_epochs = config.ae_epochs if config.ae_epochs is not None else config.epochs
    with single_thread(torch), torch.no_grad():
        qc = torch.as_tensor(q_contact, **f64)
        # W_e, B_e, W_d, B_d are views of one vector, so one Adam step updates them all (the
        # update is element-wise: the same numbers as one step per tensor, at a fraction of
        # the optimizer's per-tensor cost); step (b) trains the decoder's tail of it.
        flat = torch.zeros(2 * l * n + l + n, **f64)
        W_e, B_e, W_d, B_d = (v.view(shape) for v, shape in zip(
            flat.split([l * n, l, n * l, n]), ((l, n), (l,), (n, l), (n,))))
        W_e.copy_((torch.rand((l, n), generator=gen, **f64) * 2 - 1) * (1.0 / np.sqrt(n)))
        W_d.copy_((torch.rand((n, l), generator=gen, **f64) * 2 - 1) / np.sqrt(l))
        emask = torch.as_tensor(encoder_mask, **f64)

        def recon_step(q, start):
            opt = AdamStep(flat[start:], config.learning_rate, torch)

            def step(idx):
                grads = recon_grads(q[idx], W_e, B_e, W_d, B_d, emask)
                opt.step(torch.cat([g.reshape(-1) for g in grads])[start:])
            return step

        _epochs(qc.shape[0], config.batch_size, ae_epochs, gen, torch, recon_step(qc, 0),
                lambda e: progress("encoder (contact phase)", 0.3 * (e + 1) / ae_epochs))
        qa = torch.as_tensor(q_all, **f64)
        _epochs(qa.shape[0], config.batch_size, ae_epochs, gen, torch, recon_step(qa, l * n + l),
                lambda e: progress("decoder (all phases)", 0.3 + 0.2 * (e + 1) / ae_epochs))
        return LinearAutoencoder((W_e * emask).numpy().copy(), B_e.numpy().copy(),
                                 W_d.numpy().copy(), B_d.numpy().copy())


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
        with single_thread(torch), torch.no_grad():
            for k, (name, ph) in enumerate(zip(problem.phase_names, problem.phases)):
                if ph is None:
                    continue
                theta = torch.as_tensor(ph.theta, **f64)
                ddxi = torch.as_tensor(ph.ddxi, **f64)
                ddq = torch.as_tensor(ph.ddq, **f64)
                Wd = torch.as_tensor(ph.W_d, **f64)
                Xi = torch.zeros((p, l), **f64)
                mask = torch.as_tensor(np.repeat(allowed[k][:, None], l, axis=1), **f64)
                opt = AdamStep(Xi, ac.learning_rate, torch)
                l1 = {"w": ac.l1}

                def sindy_step(idx):
                    opt.step(sindy_grad(theta[idx], ddxi[idx], ddq[idx], Wd, Xi, mask, l1["w"]))

                total = ac.epochs + ac.refine_epochs

                def threshold(e, k=k, name=name):
                    if (e + 1) % ac.threshold_every == 0:
                        mask.mul_((Xi.abs() >= self.threshold).to(mask.dtype))
                        Xi.mul_(mask)
                    say(f"dynamics ({name})", 0.5 + 0.5 * (k + (e + 1) / total) / P)

                _epochs(theta.shape[0], ac.batch_size, ac.epochs, gen, torch, sindy_step, threshold)
                # final thresholding before refinement
                mask.mul_((Xi.abs() >= self.threshold).to(mask.dtype))
                Xi.mul_(mask)
                l1["w"] = 0.0
                _epochs(theta.shape[0], ac.batch_size, ac.refine_epochs, gen, torch, sindy_step,
                        lambda e, k=k, name=name: say(f"dynamics ({name}, refinement)",
                                                      0.5 + 0.5 * (k + (ac.epochs + e + 1) / total) / P))
                m = mask.numpy().astype(bool)
                Xis[k] = Xi.numpy() * m
                masks[k] = m
        return Coefficients(Xis, masks)
