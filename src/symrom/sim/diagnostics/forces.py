"""How far the torque-derived ground force is from the engine's own contact force.

A dataset's input ``u`` carries the CoM wrench from the joint torques: per foot in
contact ``F_k = -(J_k^T)^-1 tau_k`` (``symrom.data.preprocess``), which ignores the
legs' own weight and inertia and the held joints' torques. A simulated file also
logs the engine's ground force on each foot (``contact_force``, a diagnostic). This
module compares the two, summed over the feet as ``u`` sums them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from symrom.data.dataset import Dataset
from symrom.names import GRAVITY
from symrom.robots import get_robot

AXES = ("x", "y", "z")


class NoContactForceError(ValueError):
    """The dataset holds no ``contact_force`` (imported logs, or made before it was logged)."""


@dataclass(frozen=True)
class AxisError:
    """Torque-derived minus engine summed ground force along one world axis, over all samples.

    rms, peak: RMS and largest absolute difference, N; corr: Pearson correlation (nan if
    either is constant); peak_torque, peak_engine: the largest absolute value of each, N.
    """

    rms: float
    peak: float
    corr: float
    peak_torque: float
    peak_engine: float


@dataclass(frozen=True)
class ForceReport:
    """The comparison of one dataset: robot, engine (from its generator), samples, the robot's
    weight (N, from its description's mass), and per axis."""

    robot: str
    engine: str
    samples: int
    weight: float
    axes: dict[str, AxisError]

    def to_dict(self) -> dict:
        d = asdict(self)
        d["axes"] = {k: asdict(v) for k, v in self.axes.items()}
        return d


def force_error(ds: Dataset) -> ForceReport:
    """Compare ``u``'s summed ground force (N, 3) with the summed ``contact_force`` of ``ds``."""
    if ds.contact_force is None:
        raise NoContactForceError(f"dataset of {ds.robot} {ds.motion} has no key 'contact_force' "
                                  f"(imported, or generated before true contact forces were logged)")
    torque = ds.u[:, 12:15]
    engine = ds.contact_force.sum(axis=1)
    axes = {}
    for i, name in enumerate(AXES):
        a, b = torque[:, i], engine[:, i]
        diff = a - b
        corr = float(np.corrcoef(a, b)[0, 1]) if a.std() > 0 and b.std() > 0 else float("nan")
        axes[name] = AxisError(rms=float(np.sqrt(np.mean(diff ** 2))), peak=float(np.abs(diff).max()),
                               corr=corr, peak_torque=float(np.abs(a).max()), peak_engine=float(np.abs(b).max()))
    weight = get_robot(ds.robot).mass * GRAVITY
    return ForceReport(robot=ds.robot, engine=str(ds.generator.get("engine", "pybullet")),
                       samples=ds.n_samples, weight=weight, axes=axes)
