"""The flights of a logged jump, read from its contact flags: runs of samples with no foot
down, the rule of a jump with one main flight (``one_main_flight``) and its watcher
(``FlightWatch``), which sees while a jump runs that the rule will certainly fail. Motions
check their own flights with these (``motion.PlainMotion``, froggy's rear-only push), and the
common checks of generation read the longest flight with them.
"""

from __future__ import annotations

import numpy as np

BRIEF_FLIGHT = "a brief flight before the main one"  # the one_main_flight reason FlightWatch foresees


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the runs of True in a boolean (n,) array."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of True (the first of equals); mask must hold a True."""
    return max(runs(mask), key=lambda r: r[1] - r[0])


def one_main_flight(log: dict[str, np.ndarray]) -> list[str]:
    """[``BRIEF_FLIGHT``] if the first run of samples with no foot down in ``log["contact"]``
    (n, 4) is not the longest (the first of equals), else []: a jump with one flight."""
    airborne = log["contact"].sum(axis=1) == 0
    flights = runs(airborne)
    if flights and flights[0][0] != longest_run(airborne)[0]:
        return [BRIEF_FLIGHT]
    return []


class FlightWatch:
    """Watches the logged contact flags of a running jump for a certain failure of
    ``one_main_flight`` (the first run of samples with no foot down must be the longest,
    the first of equals).

    ``update(contact (4,))`` per logged sample; ``failed`` turns true once a later
    airborne run has grown longer than the first one ended at: the whole log will fail
    that check whatever follows; ``reason`` says which check that is.
    """

    reason = BRIEF_FLIGHT

    def __init__(self) -> None:
        self.first: int | None = None  # length of the first airborne run, once it ended
        self.run = 0  # length of the current airborne run
        self.failed = False

    def update(self, contact: np.ndarray) -> bool:
        if not np.count_nonzero(contact):  # (a C call; ``.any()`` goes through NumPy's Python wrapper)
            self.run += 1
            if self.first is not None and self.run > self.first:
                self.failed = True
        else:
            if self.run and self.first is None:
                self.first = self.run
            self.run = 0
        return self.failed
