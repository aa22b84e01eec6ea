"""Phase labels from the four foot-contact flags, with per-motion rules.

- ``pronk``: ``contact`` whenever any foot is down (the brief 1-3-foot moments
  at take-off and touch-down belong to contact), ``flight`` when none is.
- ``froggy``: ``contact`` with all four feet down, ``partial`` with 1-3 feet
  down before the first flight (the rear legs still pushing), ``flight`` with
  none; 1-3 feet after the first flight (staggered touch-down) count as contact.
"""

from __future__ import annotations

import numpy as np

from symrom.data.dataset import jump_bounds

PHASE_RULES: dict[str, list[str]] = {
    "pronk": ["contact", "flight"],
    "froggy": ["contact", "partial", "flight"],
}


def phase_names_for(motion: str) -> list[str]:
    """Phase names of ``motion``; unknown motions use the pronk rule."""
    return list(PHASE_RULES.get(motion, PHASE_RULES["pronk"]))


def label_phases(contact: np.ndarray, jump: np.ndarray, motion: str) -> tuple[np.ndarray, list[str]]:
    """Phase index per row and the phase names.

    contact: (N, 4) flags in {0, 1}, FR FL RR RL; jump: (N,) jump index.
    Returns ``phase`` (N,) int8 and ``phase_names``.
    """
    names = phase_names_for(motion)
    n_down = np.asarray(contact, dtype=int).sum(axis=1)
    phase = np.zeros(n_down.shape[0], dtype=np.int8)
    flight = names.index("flight")
    phase[n_down == 0] = flight
    if "partial" in names:
        partial = names.index("partial")
        # Rows before the first flight row of their own jump.
        for a, b in jump_bounds(jump):
            fl = np.flatnonzero(n_down[a:b] == 0)
            first_flight = a + (fl[0] if fl.size else b - a)
            seg = slice(a, first_flight)
            phase[seg][(n_down[seg] > 0) & (n_down[seg] < 4)] = partial
    return phase, names
