"""What every kept jump must show, checked on its logged samples.

``check_jump`` applies the checks common to all motions (``JumpChecks``); a
motion adds its own through its plug-in's ``check`` (the one-flight jumps,
pronk and froggy, ``one_main_flight``; froggy its rear-only push). Each failed
check is one human-readable reason, recorded with the retry. ``FlightWatch``
sees, while a jump runs, when ``one_main_flight`` is already certain to fail; a
motion hands the runner such a watcher (``watch``) so that it can stop the
attempt there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.names import BASE_POS, BASE_RPY
from symrom.robots import get_robot


@dataclass(frozen=True)
class JumpChecks:
    """What every kept jump must show (from its logged samples).

    max_tilt: |roll|, |pitch| bound, rad; min_final_height: final base height, m;
    min_flight: longest run with no foot down, s; min_apex_gain: max base height
    minus the first, m; min_travel: final minus first base position along the
    start heading, m; torques must be within the robot's limits and the jump
    must end (controller ``done``) before its time limit. A motion's own checks
    (e.g. froggy's rear-only push) are its plug-in's.
    """

    max_tilt: float = 0.8
    min_final_height: float = 0.15
    min_flight: float = 0.12
    min_apex_gain: float = 0.05
    min_travel: float = 0.1


BRIEF_FLIGHT = "a brief flight before the main one"  # the one_main_flight reason FlightWatch foresees


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the runs of True in a boolean (n,) array."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of True (the first of equals); mask must hold a True."""
    return max(runs(mask), key=lambda r: r[1] - r[0])


def check_jump(log: dict[str, np.ndarray], robot: str, dt: float, checks: JumpChecks = JumpChecks(),
               finished: bool = True, torque_bound: np.ndarray | None = None) -> list[str]:
    """Reasons ``log`` (as from ``run_jump``: q (n, 18), tau (n, 12), contact (n, 4)) fails
    the common checks; empty if it passes. dt: s between logged samples; torque_bound (12,)
    N m: what a logged torque may reach (default the robot's limits; a measured torque's
    bias and scale widen it)."""
    q, contact, tau = log["q"], log["contact"], log["tau"]
    bad: list[str] = []
    if q.shape[0] < 2:
        return ["no samples"]
    if not finished:
        bad.append("controller did not finish in time")
    tilt = np.abs(q[:, BASE_RPY][:, :2]).max()
    if tilt >= checks.max_tilt:
        bad.append(f"fell: tilt {tilt:.2f} rad")
    if q[-1, BASE_POS][2] <= checks.min_final_height:
        bad.append(f"fell: final height {q[-1, BASE_POS][2]:.3f} m")
    limit = np.asarray(get_robot(robot).torque_limit if torque_bound is None else torque_bound)
    if np.any(np.abs(tau) > limit + 1e-9):
        bad.append("torque over the limit")
    airborne = contact.sum(axis=1) == 0
    flights = runs(airborne)
    if not flights:
        bad.append("no flight")
    else:
        a, b = longest_run(airborne)
        if (b - a) * dt < checks.min_flight - 1e-9:
            bad.append(f"flight {(b - a) * dt:.3f} s")
    z = q[:, BASE_POS][:, 2]
    if z.max() - z[0] < checks.min_apex_gain:
        bad.append(f"apex gain {z.max() - z[0]:.3f} m")
    yaw0 = q[0, BASE_RPY][2]
    travel = float(np.dot(q[-1, BASE_POS][:2] - q[0, BASE_POS][:2], [np.cos(yaw0), np.sin(yaw0)]))
    if travel < checks.min_travel:
        bad.append(f"travel {travel:.3f} m")
    return bad


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
        if not contact.any():
            self.run += 1
            if self.first is not None and self.run > self.first:
                self.failed = True
        else:
            if self.run and self.first is None:
                self.first = self.run
            self.run = 0
        return self.failed
