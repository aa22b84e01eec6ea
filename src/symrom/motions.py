"""The motion registry: what every layer may know about a kind of jump.

An entry gives a motion's phase names and phase rule (used by ``data`` to
label samples), its default train/val/test splits, the variants it offers,
and where its simulation plug-in lives (``"module:attribute"``, imported only
by ``symrom.sim`` when a jump is simulated). This module sits on the ground
floor (it imports nothing of symrom but ``names``), so ``data`` reads phase
rules without importing the simulator.

Adding a motion: one new file ``sim/controllers/<motion>.py`` exporting a ``Motion``
(``symrom.sim.controllers.motion``) and one entry in ``MOTIONS`` (a plug-in may live in
any importable module; its entry names it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from symrom.names import FLIGHT_PHASE, N_LEGS, PARTIAL_PHASE, STANCE_PHASE

PhaseRule = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _jump_starts(jump: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) rows of each jump in a (N,) array of contiguous jump indices."""
    cuts = np.flatnonzero(np.diff(jump)) + 1
    edges = np.r_[0, cuts, jump.shape[0]]
    return list(zip(edges[:-1], edges[1:]))


def contact_flight(contact: np.ndarray, jump: np.ndarray) -> np.ndarray:
    """Phases ``contact`` (0) / ``flight`` (1): flight when no foot is down; the brief
    1-3-foot moments at take-off and touch-down belong to contact. contact (N, 4)."""
    return (np.asarray(contact, dtype=int).sum(axis=1) == 0).astype(np.int8)


def partial_before_flight(contact: np.ndarray, jump: np.ndarray) -> np.ndarray:
    """Phases ``contact`` (0) / ``partial`` (1) / ``flight`` (2): partial with 1-3 feet
    down before the jump's first flight row (e.g. the rear legs still pushing); 1-3
    feet after it (a staggered touch-down) count as contact. contact (N, 4), jump (N,)."""
    n_down = np.asarray(contact, dtype=int).sum(axis=1)
    phase = np.zeros(n_down.shape[0], dtype=np.int8)
    phase[n_down == 0] = 2
    for a, b in _jump_starts(np.asarray(jump)):
        fl = np.flatnonzero(n_down[a:b] == 0)
        seg = slice(a, a + (fl[0] if fl.size else b - a))
        phase[seg][(n_down[seg] > 0) & (n_down[seg] < N_LEGS)] = 1
    return phase


@dataclass(frozen=True)
class MotionEntry:
    """One motion of the registry.

    phase_names: index -> name of the phases ``phase_rule(contact (N, 4), jump (N,))
    -> (N,) int8`` assigns; sequence: the phases one jump passes through, in order (each
    transition taken once; a free prediction never goes back); splits: the paper's (train, val, test) jump counts per
    variant (``""`` for the plain one), scaled for other jump counts; variants:
    the options beyond ``noise`` the plug-in offers (e.g. ``proxy``,
    ``randomized``); plugin:
    ``"module:attribute"`` of its ``symrom.sim.controllers.motion.Motion``.
    """

    name: str
    phase_names: tuple[str, ...]
    phase_rule: PhaseRule
    splits: dict[str, tuple[int, int, int]]
    plugin: str
    variants: tuple[str, ...] = field(default=())
    sequence: tuple[str, ...] = field(default=())

    def label(self, contact: np.ndarray, jump: np.ndarray) -> tuple[np.ndarray, list[str]]:
        """Phase index per row (N,) int8 and the phase names."""
        return self.phase_rule(contact, jump), list(self.phase_names)


MOTIONS: dict[str, MotionEntry] = {
    "froggy": MotionEntry("froggy", (STANCE_PHASE, PARTIAL_PHASE, FLIGHT_PHASE), partial_before_flight,
                          splits={"": (100, 40, 10)}, plugin="symrom.sim.controllers.froggy:MOTION",
                          variants=("proxy", "randomized"),
                          sequence=(STANCE_PHASE, PARTIAL_PHASE, FLIGHT_PHASE, STANCE_PHASE)),
    "pronk": MotionEntry("pronk", (STANCE_PHASE, FLIGHT_PHASE), contact_flight,
                         splits={"": (120, 30, 6), "proxy": (12, 2, 1)}, plugin="symrom.sim.controllers.pronk:MOTION",
                         variants=("proxy", "randomized"), sequence=(STANCE_PHASE, FLIGHT_PHASE, STANCE_PHASE)),
}


class UnknownMotionError(ValueError):
    """A motion name is not in the registry."""


def phase_sequence(name: str | None) -> tuple[str, ...]:
    """The phase sequence of one jump of motion ``name`` (``MotionEntry.sequence``); () for a
    motion the registry does not hold (its jumps may pass through their phases in any order)."""
    entry = MOTIONS.get(name) if name is not None else None
    return entry.sequence if entry is not None else ()


def get_motion(name: str) -> MotionEntry:
    """The registry entry of motion ``name``."""
    try:
        return MOTIONS[name]
    except KeyError:
        raise UnknownMotionError(f"unknown motion {name!r}; known: {sorted(MOTIONS)}") from None
