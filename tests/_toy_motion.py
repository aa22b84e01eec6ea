"""A motion plug-in made for the registry tests: stand still for a few ticks, then done."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.robots.stance import start_pose
from symrom.sim.controllers.motion import PlainMotion


@dataclass(frozen=True)
class StandParams:
    max_time: float = 0.05
    stiffness: float = 200.0  # N m/rad


class StandController:
    def __init__(self, robot: str, params: StandParams):
        self.robot, self.params, self.q0 = robot, params, None

    def reset(self, world):
        self.q0 = start_pose(self.robot)
        return self.q0

    def torque(self, state):
        return self.params.stiffness * (self.q0[:12] - state.q[:12])

    def done(self, state):
        return state.t >= 0.02

    def diagnostics(self):
        return {"ticks": 20}


class StandMotion(PlainMotion):
    def sample_params(self, rng, robot, proxy, dataset_rng=None):
        return StandParams(stiffness=float(rng.uniform(150.0, 250.0)))

    def make_controller(self, robot, params, mpc_solver="osqp"):
        return StandController(robot, params)

    def check(self, log, dt, checks):
        return [] if np.ptp(log["q"][:, 14]) < 0.01 else ["moved"]


MOTION = StandMotion()
