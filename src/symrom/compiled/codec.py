"""The linear autoencoder over many jumps at once, compiled (numba): a rollout's set-up and read-out.

A rollout of J jumps encodes every row of the data (q, dq, u -> xi, dxi, nu), lays them out
as the (J, n_max, l) arrays the integrators take (each jump's last sample repeated past its
end) and decodes the integrated paths back to q. With NumPy that is either 4 x J small matrix
products entered from Python, or a few products over all rows, which OpenBLAS spreads over its
threads at several times the CPU time on a busy machine. Here each is one compiled pass over
the rows, on the calling thread, written straight into its output. The true states xi, dxi
are encoded only at the samples asked for (``encode_states(rows=...)``: an integrator reads
them at the start and the resets only); ``JumpViews`` hands out per-jump lists computed in
full on their first read.

The sums run in the order of ``LinearAutoencoder``'s products (terms by column, the offset
last) and may differ from BLAS's by rounding (~1e-16 relative).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from symrom.compiled.batch import over_jumps

# LLVM's fast-math flags without nnan/ninf (as ``symrom.compiled.codegen``): sums may be
# vectorised; NaN (a diverged path) still decodes to NaN.
FASTMATH = {"contract", "arcp", "nsz", "reassoc"}
_KERNELS: dict[str, object] = {}


class LinearMaps(Protocol):
    """What the codec reads of a linear autoencoder (``symrom.model.autoencoder``): W_e
    (l, C), B_e (l,), W_d (C, l), B_d (C,) and the input map (C, l), nu rows = u rows @ it."""

    W_e: np.ndarray
    B_e: np.ndarray
    W_d: np.ndarray
    B_d: np.ndarray

    @property
    def latent_dim(self) -> int: ...

    @property
    def input_map(self) -> np.ndarray: ...


def _kernels() -> dict[str, object]:
    if _KERNELS:
        return _KERNELS
    import numba

    njit = numba.njit(cache=True, fastmath=FASTMATH, nogil=True)  # nogil: jumps run in threads (``batch``)

    @njit
    def encode_states(q, dq, starts, lens, rows, W_e, B_e, x, v):
        J, n_max, l = x.shape
        C = q.shape[1]
        for j in range(J):
            for k in range(n_max):
                if not rows[k]:
                    continue
                r = starts[j] + min(k, lens[j] - 1)  # past the jump's end: its last sample
                for i in range(l):
                    sx, sv = 0.0, 0.0
                    for c in range(C):
                        sx += q[r, c] * W_e[i, c]
                        sv += dq[r, c] * W_e[i, c]
                    x[j, k, i] = sx + B_e[i]
                    v[j, k, i] = sv

    @njit
    def encode_inputs(u, phase, starts, lens, M, nu, ph):
        J, n_max, l = nu.shape
        C = u.shape[1]
        for j in range(J):
            a, n = starts[j], lens[j]
            for k in range(n):
                r = a + k
                ph[j, k] = phase[r]
                for i in range(l):
                    su = 0.0
                    for c in range(C):
                        su += u[r, c] * M[i, c]
                    nu[j, k, i] = su
            for k in range(n, n_max):  # past the jump's end: its last sample (``pad_edge``)
                ph[j, k] = ph[j, n - 1]
                for i in range(l):
                    nu[j, k, i] = nu[j, n - 1, i]

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

    _KERNELS.update(encode_states=encode_states, encode_inputs=encode_inputs, decode=decode)
    return _KERNELS


def _read_only(*arrays: np.ndarray, dtype=float) -> list[np.ndarray]:
    """C-contiguous read-only views (copies only where the layout or dtype asks): the kernels
    are compiled for read-only inputs alone, so that arrays handed over read-only (Ray's object
    store) and writable ones take the same build, instead of a second one per process; the same
    numbers either way."""
    out = []
    for a in arrays:
        v = np.ascontiguousarray(a, dtype=dtype).view()
        v.flags.writeable = False
        out.append(v)
    return out


def _starts_lens(bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (np.ascontiguousarray(bounds[:, 0], dtype=np.int64),
            np.ascontiguousarray(bounds[:, 1] - bounds[:, 0], dtype=np.int64))


def encode_states(ae: LinearMaps, q: np.ndarray, dq: np.ndarray, bounds: np.ndarray,
                  rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """xi, dxi (J, n_max, l) of the J row ranges ``bounds`` (J, 2) ``[start, stop)`` of q, dq
    (N, 18), each jump's last sample repeated past its end (n_max: the longest jump; every
    range holds a row). rows (n_max,) bool: encode only these samples (what the others hold
    is unspecified; their memory is not even touched); None: all."""
    starts, lens = _starts_lens(bounds)
    J, l = len(starts), ae.latent_dim
    n_max = int(lens.max()) if J else 0
    rows = np.ones(n_max, dtype=np.bool_) if rows is None else np.ascontiguousarray(rows, dtype=np.bool_)
    if rows.shape != (n_max,):
        raise ValueError(f"rows: shape {rows.shape}, expected ({n_max},) (the longest jump)")
    x, v = np.empty((2, J, n_max, l))  # one block: fewer page faults (huge pages from 4 MB)
    k = _kernels()["encode_states"]
    q, dq, W_e, B_e = _read_only(q, dq, ae.W_e, ae.B_e)
    over_jumps(lambda r: k(q, dq, starts[r], lens[r], rows, W_e, B_e, x[r], v[r]), np.full(J, n_max))
    return x, v


def encode_inputs(ae: LinearMaps, u: np.ndarray, phase: np.ndarray,
                  bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """nu (J, n_max, l) and phase (J, n_max) int64 of the row ranges ``bounds`` of u (N, 18)
    and phase (N,), as ``encode_states``."""
    starts, lens = _starts_lens(bounds)
    J, l = len(starts), ae.latent_dim
    n_max = int(lens.max()) if J else 0
    nu, ph = np.empty((J, n_max, l)), np.empty((J, n_max), dtype=np.int64)
    k = _kernels()["encode_inputs"]
    (u, M), (phase,) = _read_only(u, ae.input_map.T), _read_only(phase, dtype=np.int64)
    over_jumps(lambda r: k(u, phase, starts[r], lens[r], M, nu[r], ph[r]), np.full(J, n_max))
    return nu, ph


class JumpViews(Sequence):
    """Per jump j the view [j, :lens[j]] of a padded array (J, n_max, ...) that ``make()``
    computes on the first access (once): per-jump lists that cost nothing unless read."""

    def __init__(self, make: Callable[[], np.ndarray], lens: np.ndarray) -> None:
        self._make, self._lens, self._array = make, np.asarray(lens), None

    def __len__(self) -> int:
        return len(self._lens)

    def __getitem__(self, j):
        if isinstance(j, slice):
            return [self[i] for i in range(len(self))[j]]
        if self._array is None:
            self._array = self._make()
        return self._array[j, :self._lens[j]]


def decode_jumps(ae: LinearMaps, X: np.ndarray, lens: np.ndarray) -> list[np.ndarray]:
    """Per jump j the decoded path q (lens[j], 18) of its first lens[j] samples of X
    (J, n_max, l): views of one (sum lens, 18) array."""
    lens = np.ascontiguousarray(lens, dtype=np.int64)
    offsets = np.zeros(len(lens), dtype=np.int64)
    np.cumsum(lens[:-1], out=offsets[1:])
    out = np.empty((int(lens.sum()), ae.W_d.shape[0]))
    (X, W_t, B_d), k = _read_only(X, ae.W_d.T, ae.B_d), _kernels()["decode"]
    over_jumps(lambda r: k(X[r], lens[r], offsets[r], W_t, B_d, out), lens)
    return [out[a:a + n] for a, n in zip(offsets.tolist(), lens.tolist())]
