"""Compiled (numba) kernels of learning: the guards' timing losses over many candidate levels.

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
