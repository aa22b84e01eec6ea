"""What every kept jump must show, checked on its logged samples.

``check_jump`` applies the checks common to all motions (``JumpChecks``); a
motion adds its own through its plug-in's ``check`` (the one-flight jumps,
pronk and froggy, ``controllers.flight.one_main_flight``; froggy its rear-only
push). Each failed check is one human-readable reason, recorded with the retry.
A motion's watcher (``Motion.watch``, e.g. ``controllers.flight.FlightWatch``)
lets the episode loop stop an attempt once it has certainly failed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.names import BASE_POS, BASE_RPY
from symrom.robots import get_robot
from symrom.sim.controllers.flight import longest_run, runs


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
