"""``symrom robot show``: a robot description as symrom reads it, as one typed summary.

Everything comes from the loaded description and the kinematics symrom computes from it (the
URDF, or the URDF derived from the MJCF): the legs with their joints, signs, feet, segment
lengths, joint ranges and torque limits, the masses, the stance the leg IK finds, and the
actuator effects. Lengths m, angles rad, masses kg, torques N m.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symrom.names import LEGS, N_LEGS
from symrom.robots import get_robot, leg_kinematics
from symrom.robots.description import ActuatorEffects
from symrom.robots.stance import standing_joints


@dataclass(frozen=True)
class LegSummary:
    """One leg: ``leg`` (FR, FL, RR, RL), its ``joints`` (hx hy kn names), ``signs`` (3,),
    ``foot`` (how the description names it), ``hip`` (3,) m (the hip flexion axis, base frame,
    zero angles), ``thigh`` and ``calf`` m (hip flexion to knee to foot), ``mass`` kg (its
    links), ``lower``/``upper`` (3,) rad (joint ranges in symrom's signs, infinite where none),
    ``torque`` (3,) N m, ``knee_range`` (2,) rad, ``stance`` (3,) rad (the joints standing)."""

    leg: str
    joints: tuple[str, ...]
    signs: tuple[int, ...]
    foot: str
    hip: tuple[float, ...]
    thigh: float
    calf: float
    mass: float
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    torque: tuple[float, ...]
    knee_range: tuple[float, float]
    stance: tuple[float, ...]


@dataclass(frozen=True)
class RobotSummary:
    """A robot as symrom reads it: ``name``, ``key`` (its name in datasets), ``source`` (the
    description file), ``format``, ``model`` (the URDF or MJCF it names) and ``urdf`` (the URDF
    symrom reads; ``urdf_derived`` when made from the MJCF), ``base_link``, ``mass`` kg (total)
    and ``base_mass`` kg (all but the legs), ``foot_radius`` m, ``start_height`` m,
    ``leg_length`` m (mean thigh plus calf), ``legs`` (4 ``LegSummary``, FR FL RR RL) and the
    ``actuators`` (joint damping, armature, friction loss)."""

    name: str
    key: str
    source: Path
    format: int
    model: Path
    urdf: Path
    urdf_derived: bool
    base_link: str
    mass: float
    base_mass: float
    foot_radius: float
    start_height: float
    leg_length: float
    legs: tuple[LegSummary, ...]
    actuators: ActuatorEffects


def _leg_masses(urdf: Path, hx_joints: list[str]) -> list[float]:
    """kg per leg: the links below each leg's hip abduction joint in the URDF."""
    root = ET.parse(urdf).getroot()
    mass = {link.get("name"): sum(float(m.get("value")) for m in link.findall("inertial/mass"))
            for link in root.findall("link")}
    children: dict[str, list[str]] = {}
    child_of = {}
    for j in root.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j.find("child").get("link"))
        child_of[j.get("name")] = j.find("child").get("link")
    out = []
    for name in hx_joints:
        stack, total = [child_of[name]], 0.0
        while stack:
            link = stack.pop()
            total += mass.get(link, 0.0)
            stack += children.get(link, [])
        out.append(total)
    return out


def _foot_text(desc, k: int) -> str:
    feet = desc.feet
    if feet is None or feet.kind == "link":
        return f"link {desc.foot_links[k]!r}"
    text = f"{feet.kind} {feet.names[k]!r}"
    if feet.points is not None:
        text += " at (" + ", ".join(f"{x:.4g}" for x in feet.points[k]) + ") m"
    return text


def robot_summary(robot: str | Path) -> RobotSummary:
    """The summary of ``robot`` (a built-in name or a description file)."""
    desc = get_robot(robot)
    kin = leg_kinematics(robot)
    seg = kin.segment_lengths()
    hips = kin.hip_positions()
    lim = desc.joint_limits
    stance = standing_joints(robot)
    masses = _leg_masses(desc.urdf_path, list(desc.joint_names[0::3]))
    legs = []
    for k in range(N_LEGS):
        s = slice(3 * k, 3 * k + 3)
        legs.append(LegSummary(
            leg=LEGS[k].upper(), joints=desc.joint_names[s], signs=tuple(int(x) for x in desc.joint_signs[s]),
            foot=_foot_text(desc, k), hip=tuple(float(x) for x in hips[k]), thigh=float(seg[k, 0]),
            calf=float(seg[k, 1]), mass=masses[k], lower=tuple(float(x) for x in lim.lower[s]),
            upper=tuple(float(x) for x in lim.upper[s]), torque=desc.torque_limit[s],
            knee_range=desc.knee_ranges[k], stance=tuple(float(x) for x in stance[s])))
    return RobotSummary(
        name=desc.name, key=desc.key, source=desc.source, format=desc.format,
        model=desc.mjcf_path if desc.urdf_derived else desc.urdf_path, urdf=desc.urdf_path,
        urdf_derived=desc.urdf_derived, base_link=desc.base_link, mass=desc.mass,
        base_mass=desc.mass - float(np.sum(masses)), foot_radius=desc.foot_radius, start_height=desc.start_height,
        leg_length=float(seg.sum(axis=1).mean()), legs=tuple(legs), actuators=desc.actuators)


__all__ = ["LegSummary", "RobotSummary", "robot_summary"]
