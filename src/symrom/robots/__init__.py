"""Robots as descriptions: a robot model (a URDF, or an MJCF alone) plus a small TOML file
(``robots.description``; ``robots.init`` writes one from the model, ``robots.mjcf`` derives the
URDF of an MJCF).

``get_robot`` takes a built-in name (``ROBOTS``: name -> description file) or
the path of any description file, so a quadruped that is not built in works
with no code change. A dataset names its robot by ``RobotDescription.key``:
the built-in name, or the description file's absolute path.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from symrom.robots.description import ActuatorEffects, RobotDescription, RobotDescriptionError, load_description
from symrom.robots.kinematics import LegKinematics
from symrom.robots.masses import MassModel

_HERE = Path(__file__).resolve().parent

# The registry of built-in robots: adding one is its description file (and URDF) plus a line here.
ROBOTS: dict[str, Path] = {
    "a1": _HERE / "a1" / "a1.toml",
    "go1": _HERE / "go1" / "go1.toml",
    "laikago": _HERE / "laikago" / "laikago.toml",
}

__all__ = ["ROBOTS", "ActuatorEffects", "LegKinematics", "MassModel", "RobotDescription", "RobotDescriptionError",
           "get_robot", "leg_kinematics", "mass_model", "robot_key", "torque_limits", "total_mass"]


def robot_key(robot: str | Path) -> str:
    """The key naming ``robot`` in datasets: a built-in name as is, a file path made absolute."""
    name = str(robot)
    if name.lower() in ROBOTS:
        return name.lower()
    if name.endswith(".toml") or Path(name).is_file():
        return str(Path(name).resolve())
    raise RobotDescriptionError(f"unknown robot {name!r}; known: {sorted(ROBOTS)}, or the path "
                                f"of a robot description file (.toml)")


@cache
def _load(key: str) -> RobotDescription:
    return load_description(ROBOTS[key], key=key) if key in ROBOTS else load_description(key)


def get_robot(robot: str | Path) -> RobotDescription:
    """The description of ``robot``: a built-in name (``go1``, ``a1``) or a description file path."""
    return _load(robot_key(robot))


@cache
def _kinematics(key: str) -> LegKinematics:
    d = _load(key)
    return LegKinematics(d.urdf_path, d.base_link, list(d.joint_names), list(d.foot_links), d.joint_signs)


def leg_kinematics(robot: str | Path) -> LegKinematics:
    """Leg kinematics of ``robot`` (symrom's joint signs), parsed once from its URDF."""
    return _kinematics(robot_key(robot))


@cache
def _masses(key: str) -> MassModel:
    d = _load(key)
    return MassModel(d.urdf_path, d.base_link, list(d.joint_names), d.joint_signs)


def mass_model(robot: str | Path) -> MassModel:
    """The mass distribution of ``robot`` (whole-body centre of mass, the legs' holding
    torques), parsed once from its URDF."""
    return _masses(robot_key(robot))


def torque_limits(robot: str | Path) -> np.ndarray:
    """(12,) N m."""
    return np.asarray(get_robot(robot).torque_limit, dtype=float)


def total_mass(robot: str | Path) -> float:
    """Total mass of ``robot``, kg: the sum of every link's mass in its URDF."""
    return get_robot(robot).mass
