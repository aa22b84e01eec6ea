"""The controllers' model of the robot: body mass, CoM and inertia standing, and the joint
torques that hold the legs' own weight, computed from a source-neutral description of its links.

A ``BodySource`` gives the robot's links as rigid bodies in its standing pose
(``RigidLinks``) and the joint torques that hold the legs against gravity (inverse dynamics
at rest, base fixed). ``body_model`` and ``LegGravity`` are computed from a source alone, so
the controllers never name where the numbers come from. Sources are named in
``BODY_SOURCES`` (``"module:class"``, imported when asked for); the one built in, ``urdf``,
reads the robot's URDF with PyBullet's parser and inverse dynamics
(``symrom.sim.controllers.urdf_body.UrdfBody``), so the controllers' model is the same
whatever engine simulates the jump. Another source (e.g. one fed from MuJoCo's compiled
model, for a robot described by an MJCF model) is a class meeting ``BodySource`` and a line
in ``BODY_SOURCES``.

Units: kg, m, kg m^2, N m; joints in symrom's order and signs.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from functools import cache
from typing import Protocol, runtime_checkable

import numpy as np

from symrom.names import GRAVITY
from symrom.robots import get_robot, robot_key

# name -> "module:class" of a BodySource (constructed with the robot's key); imported when asked for
BODY_SOURCES: dict[str, str] = {"urdf": "symrom.sim.controllers.urdf_body:UrdfBody"}
DEFAULT_BODY_SOURCE = "urdf"


@dataclass(frozen=True)
class RigidLinks:
    """A robot's n links as rigid bodies, base link first, in the standing pose.

    mass (n,) kg; com (n, 3) m: each link's centre of mass in the base link frame; inertia
    (n, 3, 3) kg m^2: each link's inertia about its own centre of mass, in the base link
    frame's axes; trunk (n,) bool: the link turns with the trunk while the feet are planted
    (the trunk, hips and rotors up to the hip-flexion joints).
    """

    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray
    trunk: np.ndarray


@runtime_checkable
class BodySource(Protocol):
    """Where the controllers' model of a robot comes from (see the module docstring)."""

    def standing_links(self) -> RigidLinks:
        """The links in the robot's standing pose (``symrom.robots.stance.standing_joints``)."""

    def gravity_torques(self, q_joints: np.ndarray, gravity_base: np.ndarray) -> np.ndarray:
        """Joint torques (12,) N m that hold the legs still at joint angles q_joints (12,) rad
        with the base fixed, gravity_base (3,) m/s^2 being gravity in the base frame (an array or a
        sequence of numbers)."""


class UnknownBodySourceError(ValueError):
    """No body source of that name in ``BODY_SOURCES``."""


@cache
def body_source(robot: str, kind: str = DEFAULT_BODY_SOURCE) -> BodySource:
    """The body source ``kind`` of ``robot`` (a name or a description file), one per robot and
    process (a source may hold an engine's copy of the robot)."""
    if kind not in BODY_SOURCES:
        raise UnknownBodySourceError(f"unknown body source {kind!r}; known: {', '.join(BODY_SOURCES)}")
    key = robot_key(robot)
    if key != robot:
        return body_source(key, kind)
    module, _, attr = BODY_SOURCES[kind].partition(":")
    return getattr(importlib.import_module(module), attr)(key)


@dataclass(frozen=True)
class BodyModel:
    """Rigid-body summary of the robot in its standing pose.

    mass kg; com_base (3,) m, CoM in the base frame; inertia (3, 3) kg m^2
    about the CoM, base frame, of the whole robot; inertia_upper (3, 3) the same
    for the links that turn with the trunk while the feet are planted (trunk,
    hips, rotors up to the hip-flexion joints), the inertia the body shows in
    stance; foot_radius m.
    """

    mass: float
    com_base: np.ndarray
    inertia: np.ndarray
    inertia_upper: np.ndarray
    foot_radius: float

    @classmethod
    def of_links(cls, links: RigidLinks, foot_radius: float) -> BodyModel:
        """The summary of ``links``: total mass, their CoM, and the composite inertias about it
        (each link's own plus its mass's parallel-axis term), of all links and of the trunk's."""
        mass = float(links.mass.sum())
        com = (links.mass[:, None] * links.com).sum(0) / mass
        inertia, inertia_upper = np.zeros((3, 3)), np.zeros((3, 3))
        for m, c, own, up in zip(links.mass, links.com, links.inertia, links.trunk):
            r = c - com
            term = own + m * (r @ r * np.eye(3) - np.outer(r, r))
            inertia += term
            if up:
                inertia_upper += term
        return cls(mass=mass, com_base=com, inertia=inertia, inertia_upper=inertia_upper, foot_radius=foot_radius)


def body_model(robot: str) -> BodyModel:
    """Mass, CoM and composite inertia of ``robot`` standing, from its body source."""
    return _body_model(robot_key(robot))


@cache
def _body_model(robot: str) -> BodyModel:
    return BodyModel.of_links(body_source(robot).standing_links(), get_robot(robot).foot_radius)


class LegGravity:
    """Joint torques (12,) N m that hold the legs' own weight, for a given base orientation.

    A convex MPC treats the legs as massless, but a Go1's thighs and calves carry
    about a third of its mass; without this term the feet push with less than the
    planned force. The body source's inverse dynamics at zero velocity and
    acceleration, with gravity turned into the base frame (the ``urdf`` source: a
    fixed-base PyBullet copy of the robot, one per robot and process).
    """

    def __init__(self, robot: str, source: BodySource | None = None):
        self._source = body_source(robot) if source is None else source

    def torques(self, q_joints: np.ndarray, R: np.ndarray) -> np.ndarray:
        """(12,) N m for joint angles (12,) rad and base orientation R (3, 3) base -> world."""
        r0, r1, r2 = R[2].tolist()  # R^T (0, 0, -g), the products NumPy's -g * R[2] takes
        return self._source.gravity_torques(q_joints, (-GRAVITY * r0, -GRAVITY * r1, -GRAVITY * r2))
