"""Phase labels from the four foot-contact flags, by the motion's rule.

The rules live in the motion registry (``symrom.motions``): ``pronk`` labels
``contact``/``flight``, ``froggy`` ``contact``/``partial``/``flight`` (partial:
1-3 feet down before the first flight).
"""

from __future__ import annotations

import numpy as np

from symrom.motions import get_motion


def phase_names_for(motion: str) -> list[str]:
    """Phase names of ``motion`` (a name in ``symrom.motions.MOTIONS``)."""
    return list(get_motion(motion).phase_names)


def label_phases(contact: np.ndarray, jump: np.ndarray, motion: str) -> tuple[np.ndarray, list[str]]:
    """Phase index per row and the phase names.

    contact: (N, 4) flags in {0, 1}, FR FL RR RL; jump: (N,) jump index.
    Returns ``phase`` (N,) int8 and ``phase_names``.
    """
    return get_motion(motion).label(contact, jump)
