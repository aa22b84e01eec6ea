"""Compiled (numba) kernels of learning: the guards' timing losses over many candidate levels,
and the epochs of the gradient training (``symrom.learn.adam``).

Fitting a guard (``symrom.learn.guards``) scores thousands of (feature, level) pairs on the
logged stays: for each, the first sample of each window at which the running maximum of the
feature reaches the level. Sorted levels and a running maximum make that one pass per window
(a merge), where NumPy needs a search per window and feature. Compiled on first use and
cached on disk; this module imports numba, so it is imported only where it runs.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def timing_losses(P, starts, ends, switch, kind, levels, n_levels, out):
    """Summed timing errors (samples) of the guards ``P[f] >= levels[f, k]``.

    P (F, N): the candidate features at every row; per window w (W,): its first row
    ``starts[w]``, its end row ``ends[w]`` (exclusive), the switch's offset ``switch[w]``
    from its start and its ``kind`` (0: the stay ends in the guard's target, 1: in another
    phase, 2: the jump ends in it); levels (F, K) ascending in their first ``n_levels[f]``
    entries. Adds to ``out`` (F, K) int64 per (feature, level): |fire - switch| (kind 0;
    never firing: max(L - switch, 1)), max(switch - fire, 0) (kind 1), L - fire (kind 2;
    never firing: 0), with L the window's length and fire the first sample whose running
    maximum reaches the level (a NaN counts as reaching every level)."""
    F = P.shape[0]
    for f in range(F):
        K = n_levels[f]
        for w in range(starts.shape[0]):
            a = starts[w]
            L = ends[w] - a
            e = switch[w]
            kd = kind[w]
            r = -np.inf
            k = 0
            for j in range(L):
                v = P[f, a + j]
                if v != v:
                    r = np.inf
                elif v > r:
                    r = v
                while k < K and levels[f, k] <= r:
                    if kd == 0:
                        out[f, k] += abs(j - e)
                    elif kd == 1:
                        out[f, k] += max(e - j, 0)
                    else:
                        out[f, k] += L - j
                    k += 1
                if k == K:
                    break
            if kd == 0:
                never = max(L - e, 1)
                while k < K:
                    out[f, k] += never
                    k += 1


# ---------------------------------------------------------------- Adam's epochs (symrom.learn.adam)
# torch.optim.Adam's defaults, the paper's optimiser
ADAM_BETA1, ADAM_BETA2, ADAM_EPS = 0.9, 0.999, 1e-8


@numba.njit(cache=True)
def _adam_update(p, g, m, v, t, lr):
    """One Adam step t (1, 2, ...) of the parameters p (k,) with gradient g (k,) and moments
    m, v (k,), all updated in place: torch.optim.Adam's update without weight decay or AMSGrad."""
    bc1 = 1.0 - ADAM_BETA1 ** t
    bc2_sqrt = (1.0 - ADAM_BETA2 ** t) ** 0.5
    step_size = lr / bc1
    for i in range(p.shape[0]):
        gi = g[i]
        m[i] += (1.0 - ADAM_BETA1) * (gi - m[i])
        v[i] = v[i] * ADAM_BETA2 + (1.0 - ADAM_BETA2) * gi * gi
        p[i] += -step_size * (m[i] / (np.sqrt(v[i]) / bc2_sqrt + ADAM_EPS))


@numba.njit(cache=True)
def _gather(src, perm, a, B, out):
    """Rows perm[a:a + B] of src (N, w) into out[:B] (batch, w): a batch's rows first, in loads
    that do not wait for each other (they lie scattered through memory, and fetching them is
    most of a step)."""
    for b in range(B):
        r = perm[a + b]
        for c in range(src.shape[1]):
            out[b, c] = src[r, c]


@numba.njit(cache=True)
def adam_recon_epoch(q, perm, batch, flat, start, l, emask, m, v, t, lr):
    """One epoch of Adam on the reconstruction loss mean_b ||q_b - ((q_b (W_e*emask)^T + B_e)
    W_d^T + B_d)||^2 over the mini-batches ``perm[a:a + batch]`` of the rows of q (N, n).

    flat (2 l n + l + n,) holds W_e (l, n), B_e (l,), W_d (n, l), B_d (n,) in that order, row
    major; Adam trains its tail ``flat[start:]`` (0: all four; l n + l: the decoder's), with
    moments m, v of that tail's length, from step t. W_e's gradient is zero where emask (n,) is.
    Returns the step count reached."""
    n = q.shape[1]
    ne, nb, nd = l * n, l * n + l, l * n + l + n * l
    encoder = start < nb  # whether the encoder trains: its gradients are needed
    g = np.zeros(flat.shape[0])
    Q = np.empty((batch, n))
    We = np.empty((l, n))
    h = np.empty(l)
    d = np.empty(n)
    for a in range(0, perm.shape[0], batch):
        B = min(batch, perm.shape[0] - a)
        scale = 2.0 / B
        _gather(q, perm, a, B, Q)
        for k in range(l):
            for j in range(n):
                We[k, j] = flat[k * n + j] * emask[j]
        g[:] = 0.0
        for b in range(B):
            for k in range(l):
                s = flat[ne + k]
                for j in range(n):
                    s += Q[b, j] * We[k, j]
                h[k] = s
            for j in range(n):
                s = flat[nd + j]
                for k in range(l):
                    s += h[k] * flat[nb + j * l + k]
                e = (s - Q[b, j]) * scale
                d[j] = e
                g[nd + j] += e
                for k in range(l):
                    g[nb + j * l + k] += e * h[k]
            if encoder:
                for k in range(l):
                    s = 0.0
                    for j in range(n):
                        s += d[j] * flat[nb + j * l + k]
                    g[ne + k] += s
                    for j in range(n):
                        g[k * n + j] += s * Q[b, j]
        if encoder:
            for k in range(l):
                for j in range(n):
                    g[k * n + j] *= emask[j]
        t += 1
        _adam_update(flat[start:], g[start:], m, v, float(t), lr)
    return t


@numba.njit(cache=True)
def adam_sindy_epoch(rows, M, Xi, mask, perm, batch, l1, m, v, t, lr):
    """One epoch of Adam on step (c)'s loss mean_b ||ddxi_b - z_b||^2 + mean_b ||ddq_b - z_b
    W_d^T||^2 + l1 ||Xi*mask||_1, z = theta (Xi*mask), over the mini-batches ``perm[a:a + batch]``.

    Its gradient in z is 2 (z M - y) with M = I + W_d^T W_d (l, l) and y = ddxi + ddq W_d, which
    stay fixed through step (c): rows (N, p + l) holds theta | y side by side, one contiguous
    block per sample. Xi, mask (p, l) (mask 0 or 1; Xi's gradient is zero where it is 0) and the moments
    m, v (p l,) are updated in place from step t. Returns the step count reached."""
    p, l = Xi.shape
    flat = Xi.reshape(p * l)
    Xm = np.empty((p, l))
    R = np.empty((batch, p + l))
    d = np.empty((batch, l))
    g = np.empty((p, l))
    z = np.empty(l)
    for a in range(0, perm.shape[0], batch):
        B = min(batch, perm.shape[0] - a)
        scale = 2.0 / B
        _gather(rows, perm, a, B, R)
        for i in range(p):
            for k in range(l):
                Xm[i, k] = Xi[i, k] * mask[i, k]
        for b in range(B):
            for k in range(l):
                s = 0.0
                for i in range(p):
                    s += R[b, i] * Xm[i, k]
                z[k] = s
            for k in range(l):
                s = -R[b, p + k]
                for c in range(l):
                    s += z[c] * M[c, k]
                d[b, k] = s * scale
        g[:] = 0.0
        for b in range(B):
            for i in range(p):
                x = R[b, i]
                for k in range(l):
                    g[i, k] += x * d[b, k]
        for i in range(p):
            for k in range(l):
                s = g[i, k]
                if l1 != 0.0:
                    s += l1 * np.sign(Xm[i, k])
                g[i, k] = s * mask[i, k]
        t += 1
        _adam_update(flat, g.reshape(p * l), m, v, float(t), lr)
    return t
