"""What a dataset's jumps did: how far and how high they went, where they left and met the ground.

A model learned from these jumps knows the motion only there; the planner reads the
envelope (saved with the model, ``provenance.data.envelope``) as the part of its reach the data
hold. Per jump, its main flight (the longest run of ``flight`` rows) and:

- the push start: the lowest base height before the flight (the bottom of the crouch);
- travel: the base's forward travel (world x) from the push start to the first row after the
  flight (the touchdown);
- apex: the largest base height in the flight;
- the base height at lift-off (the flight's first row) and at touchdown;
- push: the time from the push start to lift-off, s;
- the ground wrench the push's feet exerted (the input's forward and vertical force and pitch
  moment, ``push_wrench``), per contact phase, over its rows from the push start to lift-off;
- the release (``release``): the last rows before lift-off whose input pulls the base down
  (vertical force below zero). A pronk's controller ends its push by holding the legs without
  ground force while the feet leave, and the torques that catch the legs up to the trunk read, in
  the input derived from them, as a pull on it (about -60 N on the Go1, 8-10 ms): the trunk keeps
  rising and slows down faster than a free fall before its flight begins. Its length is the median
  over the jumps and its force (forward, vertical) the median of the releasing jumps' means;
  none where most jumps have no such rows (the froggy's flight follows its push at once);
- the lift-offs (``liftoffs``): each jump's configuration and velocity at its flight's first row
  and the base's forward travel from there to the touchdown, from which a planner measures what
  its own flight misses of the travel (``plan.bias``).

A jump without a flight, or whose flight runs to its last row, is left out.
Units: m, s, N, N m.
"""

from __future__ import annotations

import numpy as np

from symrom.data.dataset import Dataset
from symrom.names import BASE_POS, FLIGHT_PHASE, U_NAMES

_X, _Z = BASE_POS.start, BASE_POS.start + 2
WRENCH = ("fx", "fz", "my")  # the push's wrench in the sagittal plane, N, N, N m (``U_NAMES``)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def jump_envelope(ds: Dataset, jumps: np.ndarray | list[int]) -> dict | None:
    """The envelope of ``jumps`` (dataset indices) of ``ds`` (module docstring), JSON-ready:
    ``jumps`` (how many had a landed flight), ``travel_x_m`` and ``apex_z_m`` [min, max],
    ``liftoff_z_m`` and ``touchdown_z_m`` (medians), ``push_s`` [min, max], ``push_wrench``:
    {"components": ``WRENCH``, "phases": {phase: {"min": (3,), "max": (3,)}}} over the push rows
    of each phase, ``release``: {"s": its length, "force_n": (fx, fz), "phase": the contact
    phase it ends} or None, and ``liftoffs``: {"q": (n, 18), "dq": (n, 18), "travel_x_m": (n,)} per
    landed jump in turn; None if no jump has a landed flight or the dataset has no ``flight``
    phase."""
    if FLIGHT_PHASE not in ds.phase_names:
        return None
    fid = ds.phase_names.index(FLIGHT_PHASE)
    bounds = ds.jump_bounds()
    travel, apex, z_lo, z_td, push = [], [], [], [], []
    cols = [U_NAMES.index(c) for c in WRENCH]
    release_rows, release_force, release_phase = [], [], []
    lo_q, lo_dq, flown = [], [], []
    wrench: dict[int, list[np.ndarray]] = {}  # phase -> the push rows' wrench (n, 3)
    for j in np.asarray(jumps, dtype=int):
        a0, a1 = bounds[j]
        q, phase = ds.q[a0:a1], ds.phase[a0:a1]
        runs = _runs(phase == fid)
        if not runs:
            continue
        a, b = max(runs, key=lambda r: r[1] - r[0])
        if b >= len(q) or a == 0:
            continue
        k0 = int(np.argmin(q[:a, _Z]))
        travel.append(q[b, _X] - q[k0, _X])
        apex.append(q[a:b, _Z].max())
        z_lo.append(q[a, _Z])
        z_td.append(q[b, _Z])
        push.append((a - k0) * ds.dt)
        lo_q.append(q[a].tolist())
        lo_dq.append(ds.dq[a0 + a].tolist())
        flown.append(float(q[b, _X] - q[a, _X]))
        for k in np.unique(phase[k0:a]):
            wrench.setdefault(int(k), []).append(ds.u[a0 + k0:a0 + a][phase[k0:a] == k][:, cols])
        r = 0  # the release: the push's last rows that pull the base down, in the phase lift-off ends
        while a - r - 1 > k0 and phase[a - r - 1] == phase[a - 1] and ds.u[a0 + a - r - 1, cols[1]] < 0:
            r += 1
        release_rows.append(r)
        if r:
            release_force.append(ds.u[a0 + a - r:a0 + a, cols[:2]].mean(axis=0))
            release_phase.append(ds.phase_names[int(phase[a - 1])])
    if not travel:
        return None
    pushed = {ds.phase_names[k]: np.concatenate(w) for k, w in sorted(wrench.items())}

    def span(v):
        return [float(np.min(v)), float(np.max(v))]

    release = None
    n_release = int(np.floor(np.median(release_rows)))
    if n_release:
        names, counts = np.unique(release_phase, return_counts=True)
        release = {"s": n_release * ds.dt, "force_n": np.median(release_force, axis=0).tolist(),
                   "phase": str(names[np.argmax(counts)])}

    return {"jumps": len(travel), "travel_x_m": span(travel), "apex_z_m": span(apex),
            "liftoff_z_m": float(np.median(z_lo)), "touchdown_z_m": float(np.median(z_td)), "push_s": span(push),
            "push_wrench": {"components": list(WRENCH),
                            "phases": {k: {"min": w.min(axis=0).tolist(), "max": w.max(axis=0).tolist()}
                                       for k, w in pushed.items()}},
            "release": release, "liftoffs": {"q": lo_q, "dq": lo_dq, "travel_x_m": flown}}


__all__ = ["jump_envelope"]
