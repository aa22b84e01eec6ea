"""The paper's gradient training of the three steps with Adam (needs torch).

(a) W_e, B_e, W_d, B_d on contact-phase configurations, reconstruction loss;
(b) W_d, B_d on all phases, encoder frozen; (c) per phase, Xi on the SINDy loss
||ddxi - Theta Xi||^2 + ||ddq - W_d Theta Xi||^2 + l1 ||Xi||_1 with the
entries |Xi| < threshold zeroed (and kept zero) every ``threshold_every``
epochs, then ``refine_epochs`` more epochs on the surviving terms without L1.
Mini-batches of ``batch_size`` samples, Adam at ``learning_rate`` (Table 1:
1e-3, 100, 501 epochs). Everything runs in float64 on the CPU, one thread
(the matrices are tiny; threads only add overhead).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from symrom.data.dataset import Dataset
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.library import CandidateLibrary


def _torch():
    try:
        import torch
    except ImportError:
        raise ImportError("the 'adam' solver needs PyTorch: pip install 'symrom[adam]' "
                          "(torch==2.13.0)") from None
    return torch


def _epochs(n_rows: int, batch: int, epochs: int, gen, torch, step: Callable[[object], None],
            on_epoch: Callable[[int], None] | None = None) -> None:
    for e in range(epochs):
        perm = torch.randperm(n_rows, generator=gen)
        for a in range(0, n_rows, batch):
            step(perm[a:a + batch])
        if on_epoch:
            on_epoch(e)


def train_adam(ds: Dataset, rows: np.ndarray, contact_rows: np.ndarray, lib: CandidateLibrary,
               config, progress: Callable[[str, float], None]
               ) -> tuple[LinearAutoencoder, np.ndarray, np.ndarray]:
    """Steps (a)-(c) by Adam; returns the autoencoder, Xi (P, p, l) and masks (P, p, l)."""
    torch = _torch()
    ac = config.adam
    l, n = config.latent_dim, ds.q.shape[1]
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        gen = torch.Generator().manual_seed(int(config.seed))
        f64 = dict(dtype=torch.float64)
        ae_epochs = ac.ae_epochs if ac.ae_epochs is not None else ac.epochs

        # (a) encoder + decoder on the contact phase.
        qc = torch.as_tensor(ds.q[contact_rows], **f64)
        bound = 1.0 / np.sqrt(n)
        W_e = ((torch.rand((l, n), generator=gen, **f64) * 2 - 1) * bound).requires_grad_()
        B_e = torch.zeros(l, **f64, requires_grad=True)
        W_d = ((torch.rand((n, l), generator=gen, **f64) * 2 - 1) / np.sqrt(l)).requires_grad_()
        B_d = torch.zeros(n, **f64, requires_grad=True)
        opt = torch.optim.Adam([W_e, B_e, W_d, B_d], lr=ac.learning_rate)
        emask = torch.as_tensor(config.encoder_mask(), **f64)  # components the encoder reads

        def recon_step(q):
            def step(idx):
                qb = q[idx]
                loss = ((qb - ((qb @ (W_e * emask).T + B_e) @ W_d.T + B_d)) ** 2).sum(1).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
            return step

        _epochs(qc.shape[0], ac.batch_size, ae_epochs, gen, torch, recon_step(qc),
                lambda e: progress("encoder (contact phase)", 0.3 * (e + 1) / ae_epochs))

        # (b) decoder on all phases, encoder frozen.
        W_e.requires_grad_(False)
        B_e.requires_grad_(False)
        qa = torch.as_tensor(ds.q[rows], **f64)
        opt = torch.optim.Adam([W_d, B_d], lr=ac.learning_rate)
        _epochs(qa.shape[0], ac.batch_size, ae_epochs, gen, torch, recon_step(qa),
                lambda e: progress("decoder (all phases)", 0.3 + 0.2 * (e + 1) / ae_epochs))
        ae = LinearAutoencoder((W_e * emask).detach().numpy().copy(), B_e.detach().numpy().copy(),
                               W_d.detach().numpy().copy(), B_d.detach().numpy().copy())

        # (c) one Xi per phase, autoencoder frozen.
        Wd = torch.as_tensor(ae.W_d, **f64)
        Xis, masks = [], []
        P = len(ds.phase_names)
        for k, name in enumerate(ds.phase_names):
            r = rows & (ds.phase == k)
            p = lib.n_features
            if not r.any():
                Xis.append(np.zeros((p, l)))
                masks.append(np.zeros((p, l), dtype=bool))
                continue
            theta = torch.as_tensor(lib.transform(ae.encode(ds.q[r]), ae.encode_derivative(ds.dq[r]),
                                                  ae.encode_input(ds.u[r])), **f64)
            ddxi = torch.as_tensor(ae.encode_derivative(ds.ddq[r]), **f64)
            ddq = torch.as_tensor(ds.ddq[r], **f64)
            Xi = torch.zeros((p, l), **f64, requires_grad=True)
            mask = torch.ones((p, l), **f64)
            opt = torch.optim.Adam([Xi], lr=ac.learning_rate)
            l1 = {"w": ac.l1}

            def sindy_step(idx):
                z = theta[idx] @ (Xi * mask)
                loss = (((ddxi[idx] - z) ** 2).sum(1).mean()
                        + config.decoded_weight * ((ddq[idx] - z @ Wd.T) ** 2).sum(1).mean()
                        + l1["w"] * (Xi * mask).abs().sum())
                opt.zero_grad()
                loss.backward()
                opt.step()

            def threshold(e):
                if (e + 1) % ac.threshold_every == 0:
                    with torch.no_grad():
                        mask.mul_((Xi.abs() >= config.threshold).to(mask.dtype))
                        Xi.mul_(mask)
                frac = (k + (e + 1) / (ac.epochs + ac.refine_epochs)) / P
                progress(f"dynamics ({name})", 0.5 + 0.5 * frac)

            _epochs(theta.shape[0], ac.batch_size, ac.epochs, gen, torch, sindy_step, threshold)
            with torch.no_grad():  # final thresholding before refinement
                mask.mul_((Xi.abs() >= config.threshold).to(mask.dtype))
                Xi.mul_(mask)
            l1["w"] = 0.0
            _epochs(theta.shape[0], ac.batch_size, ac.refine_epochs, gen, torch, sindy_step,
                    lambda e: progress(f"dynamics ({name}, refinement)",
                                       0.5 + 0.5 * (k + (ac.epochs + e + 1) / (ac.epochs + ac.refine_epochs)) / P))
            m = mask.numpy().astype(bool)
            Xis.append((Xi.detach().numpy() * m).copy())
            masks.append(m)
        return ae, np.array(Xis), np.array(masks)
    finally:
        torch.set_num_threads(threads)
