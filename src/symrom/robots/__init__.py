"""Robot descriptions: one ``RobotSpec`` per robot, geometry read from its URDF.

The URDF is the one source of geometry and limits; the spec only names which
URDF joints and links play the roles symrom uses (joint order FR FL RR RL x
hx hy kn, four foot links) and the few facts a URDF does not carry.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from symrom.robots.kinematics import LegKinematics

_HERE = Path(__file__).resolve().parent
_LEG_PREFIX = ("FR", "FL", "RR", "RL")


def _pybullet_data(rel: str) -> Path:
    import pybullet_data

    return Path(pybullet_data.getDataPath()) / rel


@dataclass(frozen=True)
class RobotSpec:
    """What symrom needs to know of a robot beyond its URDF.

    torque_limit: per joint (12,) N m, the actuators' real limit (may be tighter
    than the URDF's ``effort``); start_height: nominal standing base height, m.
    """

    name: str
    urdf_rel: str
    in_pybullet_data: bool
    base_link: str
    joint_names: tuple[str, ...]
    foot_links: tuple[str, ...]
    torque_limit: tuple[float, ...]
    start_height: float

    @property
    def urdf_path(self) -> Path:
        return _pybullet_data(self.urdf_rel) if self.in_pybullet_data else _HERE / self.urdf_rel


def _names(hx: str, hy: str, kn: str) -> tuple[str, ...]:
    return tuple(f"{leg}_{j}" for leg in _LEG_PREFIX for j in (hx, hy, kn))


ROBOTS: dict[str, RobotSpec] = {
    "a1": RobotSpec(
        name="a1", urdf_rel="a1/a1.urdf", in_pybullet_data=True, base_link="trunk",
        joint_names=_names("hip_joint", "upper_joint", "lower_joint"),
        foot_links=tuple(f"{leg}_toe" for leg in _LEG_PREFIX),
        torque_limit=(33.5,) * 12, start_height=0.30),
    "go1": RobotSpec(
        name="go1", urdf_rel="go1/go1.urdf", in_pybullet_data=False, base_link="trunk",
        joint_names=_names("hip_joint", "thigh_joint", "calf_joint"),
        foot_links=tuple(f"{leg}_foot" for leg in _LEG_PREFIX),
        torque_limit=(23.7, 23.7, 35.55) * 4, start_height=0.3165),
}


def get_robot(name: str) -> RobotSpec:
    """The spec of robot ``name`` (``go1`` or ``a1``)."""
    try:
        return ROBOTS[name.lower()]
    except KeyError:
        raise ValueError(f"unknown robot {name!r}; known: {sorted(ROBOTS)}") from None


@cache
def leg_kinematics(name: str) -> LegKinematics:
    """Leg kinematics of robot ``name``, parsed once from its URDF."""
    spec = get_robot(name)
    return LegKinematics(spec.urdf_path, spec.base_link, list(spec.joint_names), list(spec.foot_links))


def torque_limits(name: str) -> np.ndarray:
    """(12,) N m."""
    return np.asarray(get_robot(name).torque_limit, dtype=float)


@cache
def total_mass(name: str) -> float:
    """Total mass of robot ``name``, kg: the sum of every link's ``<inertial><mass>`` in its URDF."""
    import xml.etree.ElementTree as ET

    root = ET.parse(get_robot(name).urdf_path).getroot()
    masses = [float(m.get("value")) for m in root.findall("link/inertial/mass") if m.get("value") is not None]
    if not masses:
        raise ValueError(f"the URDF of robot {name!r} declares no link masses")
    return float(sum(masses))
