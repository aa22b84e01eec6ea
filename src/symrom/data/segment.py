"""Continuous recordings cut into jumps by the motion's phase rule.

A robot logging continuously writes several jumps as one: no jump column, time
never restarting. A jump of the motions symrom models is the stance before a
flight, the flight and the landing after it, so a recording holding several
flights is cut between them: the motion's phase rule labels the rows
(``motions``), the flights are its runs of ``flight`` rows at least
``min_flight`` s long (shorter runs are a foot bouncing, not a jump), and the
cut between two flights is the middle row of the ground run between them (the
landing of the one and the stance before the next share it). A jump with one
flight or none is left whole. Each new jump's time restarts at 0.
"""

from __future__ import annotations

import numpy as np

from symrom.motions import get_motion

SEGMENT = ("auto", "off")
MIN_FLIGHT = 0.03  # s: a flight of a pronk is 0.1-0.3 s; a foot bouncing on landing is a few ms


def flights(contact: np.ndarray, t: np.ndarray, motion: str, min_flight: float = MIN_FLIGHT) -> np.ndarray:
    """(k, 2) ``[start, stop)`` rows of the flights of one jump: contact (n, 4), t (n,) s."""
    entry = get_motion(motion)
    phase, names = entry.label(np.asarray(contact), np.zeros(len(t), np.int32))
    air = np.r_[0, (phase == names.index("flight")).astype(int), 0]
    starts, stops = np.flatnonzero(np.diff(air) == 1), np.flatnonzero(np.diff(air) == -1)
    end = np.minimum(stops, len(t) - 1)
    long = (t[end] - t[starts]) >= min_flight
    return np.stack([starts[long], stops[long]], axis=1) if long.any() else np.zeros((0, 2), int)


def segment_log(lg, motion: str, min_flight: float = MIN_FLIGHT) -> list[dict]:
    """Cut every jump of ``lg`` (an ``importers.RawLog``) holding more than one flight (in
    place: ``jump`` renumbered, ``t`` restarted per new jump). Returns one record per jump
    cut: the file, the logged jump, and per segment its rows of the logged jump, its time
    span (s, logged) and its flight (s)."""
    out = []
    new_jump = np.empty_like(lg.jump)
    new_t = lg.t.copy()
    next_id = 0
    for j, (a, b) in enumerate(lg.bounds()):
        t = lg.t[a:b]
        fl = flights(lg.contact[a:b], t, motion, min_flight).astype(int)
        cuts = [0] + [int((fl[i, 1] + fl[i + 1, 0]) // 2) for i in range(len(fl) - 1)] + [int(b - a)]
        for k, (c0, c1) in enumerate(zip(cuts[:-1], cuts[1:])):
            new_jump[a + c0:a + c1] = next_id + k
            new_t[a + c0:a + c1] = t[c0:c1] - t[c0]
        if len(fl) > 1:
            out.append({"file": lg.path.name, "jump": j, "segments": [
                {"rows": [c0, c1], "t": [float(t[c0]), float(t[c1 - 1])],
                 "flight": [float(t[fl[k, 0]]), float(t[min(fl[k, 1], b - a - 1)])]}
                for k, (c0, c1) in enumerate(zip(cuts[:-1], cuts[1:]))]})
        next_id += len(cuts) - 1
    lg.jump, lg.t = new_jump, new_t
    return out
