"""The linear autoencoder over many jumps at once, compiled (numba): a rollout's set-up and read-out.

A rollout of J jumps encodes every row of the data (q, dq, u -> xi, dxi, nu), lays them out
as the (J, n_max, l) arrays the integrators take (each jump's last sample repeated past its
end) and decodes the integrated paths back to q. With NumPy that is either 4 x J small matrix
products entered from Python, or a few products over all rows, which OpenBLAS spreads over its
threads at several times the CPU time on a busy machine. Here each is one compiled pass over
the rows, on the calling thread, written straight into its output.

The sums run in the order of ``LinearAutoencoder``'s products (terms by column, the offset
last) and may differ from BLAS's by rounding (~1e-16 relative).
"""

from __future__ import annotations

import numpy as np

from symrom.model.autoencoder import LinearAutoencoder

# LLVM's fast-math flags without nnan/ninf (as ``symrom.model.codegen``): sums may be
# vectorised; NaN (a diverged path) still decodes to NaN.
FASTMATH = {"contract", "arcp", "nsz", "reassoc"}
_KERNELS: dict[str, object] = {}


def _kernels() -> dict[str, object]:
    if _KERNELS:
        return _KERNELS
    import numba

    njit = numba.njit(cache=True, fastmath=FASTMATH)

    @njit
    def encode(q, dq, u, phase, starts, lens, W_e, B_e, M, x, v, nu, ph):
        J, n_max, l = x.shape
        C = q.shape[1]
        for j in range(J):
            a, n = starts[j], lens[j]
            for k in range(n):
                r = a + k
                ph[j, k] = phase[r]
                for i in range(l):
                    sx, sv, su = 0.0, 0.0, 0.0
                    for c in range(C):
                        sx += q[r, c] * W_e[i, c]
                        sv += dq[r, c] * W_e[i, c]
                        su += u[r, c] * M[i, c]
                    x[j, k, i] = sx + B_e[i]
                    v[j, k, i] = sv
                    nu[j, k, i] = su
            for k in range(n, n_max):  # past the jump's end: its last sample (``pad_edge``)
                ph[j, k] = ph[j, n - 1]
                for i in range(l):
                    x[j, k, i], v[j, k, i], nu[j, k, i] = x[j, n - 1, i], v[j, n - 1, i], nu[j, n - 1, i]

    @njit
    def decode(X, lens, offsets, W_t, B_d, out):
        J, n_max, l = X.shape
        C = out.shape[1]
        for j in range(J):
            for k in range(lens[j]):
                r = offsets[j] + k
                for c in range(C):  # rows of W_d^T: each loop a vector over the components
                    out[r, c] = X[j, k, 0] * W_t[0, c]
                for i in range(1, l):
                    x = X[j, k, i]
                    for c in range(C):
                        out[r, c] += x * W_t[i, c]
                for c in range(C):
                    out[r, c] += B_d[c]

    _KERNELS.update(encode=encode, decode=decode)
    return _KERNELS


def encode_jumps(ae: LinearAutoencoder, q: np.ndarray, dq: np.ndarray, u: np.ndarray, phase: np.ndarray,
                 bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """xi, dxi, nu (J, n_max, l) and phase (J, n_max) int64 of the J row ranges ``bounds``
    (J, 2) ``[start, stop)`` of q, dq, u (N, 18) and phase (N,), each jump's last sample
    repeated past its end (n_max: the longest jump; every range holds a row)."""
    starts = np.ascontiguousarray(bounds[:, 0], dtype=np.int64)
    lens = np.ascontiguousarray(bounds[:, 1] - bounds[:, 0], dtype=np.int64)
    J, l = len(starts), ae.latent_dim
    n_max = int(lens.max()) if J else 0
    x, v, nu = np.empty((3, J, n_max, l))  # one block: fewer page faults (huge pages from 4 MB)
    ph = np.empty((J, n_max), dtype=np.int64)
    f = np.ascontiguousarray
    _kernels()["encode"](f(q, dtype=float), f(dq, dtype=float), f(u, dtype=float), f(phase, dtype=np.int64),
                         starts, lens, f(ae.W_e, dtype=float), f(ae.B_e, dtype=float),
                         f(ae.input_map.T, dtype=float), x, v, nu, ph)
    return x, v, nu, ph


def decode_jumps(ae: LinearAutoencoder, X: np.ndarray, lens: np.ndarray) -> list[np.ndarray]:
    """Per jump j the decoded path q (lens[j], 18) of its first lens[j] samples of X
    (J, n_max, l): views of one (sum lens, 18) array."""
    lens = np.ascontiguousarray(lens, dtype=np.int64)
    offsets = np.zeros(len(lens), dtype=np.int64)
    np.cumsum(lens[:-1], out=offsets[1:])
    out = np.empty((int(lens.sum()), ae.W_d.shape[0]))
    _kernels()["decode"](np.ascontiguousarray(X, dtype=float), lens, offsets,
                         np.ascontiguousarray(ae.W_d.T, dtype=float), np.ascontiguousarray(ae.B_d, dtype=float), out)
    return [out[a:a + n] for a, n in zip(offsets.tolist(), lens.tolist())]
