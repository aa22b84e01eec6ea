"""Newton's law on the measured ground force: the baseline a CoM model has to beat.

    b'' = g + F / m

with b the base position (symrom's stand-in for the CoM), F the summed
ground-reaction force of the feet in contact logged in the data
(``u[:, 12:15]``, N; zero in flight) and m the robot's total mass. Nothing is
fitted: whatever the data's force explains, this model explains. Where it
errs, the gap comes from what the CoM model leaves out: legs that move the
CoM against the base, and ground forces estimated from joint torques
through massless-leg Jacobians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.baselines.com import COMPONENTS, GRAVITY, com_system, robot_mass
from symrom.data.dataset import Dataset
from symrom.rollout.system import RolloutSystem


@dataclass(frozen=True)
class Newton:
    """b'' = g + F/m as a model that can be rolled out (``Rollable``); m in kg."""

    m: float
    components = COMPONENTS

    def __post_init__(self) -> None:
        if not (np.isfinite(self.m) and self.m > 0):
            raise ValueError(f"Newton baseline: mass must be a positive number, got {self.m}")

    @classmethod
    def of(cls, ds: Dataset, m: float | None = None) -> Newton:
        """The baseline for the robot of ``ds`` (its description's mass unless ``m`` is given)."""
        return cls(robot_mass(ds.robot) if m is None else float(m))

    def rollout_system(self, ds: Dataset, jumps: np.ndarray) -> RolloutSystem:
        return com_system(ds, jumps, self.m, lambda d, x, v: GRAVITY + d["u"])
