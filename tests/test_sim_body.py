"""The controllers' body model from a source-neutral description of the links: composite
inertias of planted links, gravity handed to a source in the base frame, sources by name."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from symrom.robots import get_robot
from symrom.sim.controllers import body
from symrom.sim.controllers.body import (
    BODY_SOURCES,
    BodyModel,
    BodySource,
    LegGravity,
    RigidLinks,
    UnknownBodySourceError,
    body_model,
    body_source,
)


class PlantedSource:
    """Three links with a known answer; gravity torques that show the gravity they were given."""

    def __init__(self, robot: str):
        self.robot = robot

    def standing_links(self) -> RigidLinks:
        return RigidLinks(mass=np.array([2.0, 1.0, 1.0]),
                          com=np.array([[0.0, 0.0, 0.1], [0.3, 0.0, 0.1], [-0.3, 0.0, 0.1]]),
                          inertia=np.array([np.diag([0.1, 0.2, 0.3]), np.zeros((3, 3)), np.zeros((3, 3))]),
                          trunk=np.array([True, True, False]))

    def gravity_torques(self, q_joints, gravity_base):
        return np.concatenate([np.asarray(gravity_base)] * 4) + 0.0 * np.asarray(q_joints)


def test_the_composite_of_planted_links():
    m = BodyModel.of_links(PlantedSource("go1").standing_links(), foot_radius=0.02)
    assert m.mass == 4.0 and m.foot_radius == 0.02
    np.testing.assert_allclose(m.com_base, [0.0, 0.0, 0.1], atol=1e-15)
    # two 1 kg points 0.3 m either side along x add 2 x 0.09 about y and z; the trunk's has one
    np.testing.assert_allclose(m.inertia, np.diag([0.1, 0.38, 0.48]), atol=1e-15)
    np.testing.assert_allclose(m.inertia_upper, np.diag([0.1, 0.29, 0.39]), atol=1e-15)


def test_leg_gravity_hands_the_source_gravity_in_the_base_frame():
    R = Rotation.from_euler("ZYX", [0.7, 0.3, -0.2]).as_matrix()
    tau = LegGravity("go1", PlantedSource("go1")).torques(np.zeros(12), R)
    np.testing.assert_allclose(tau[:3], R.T @ [0.0, 0.0, -body.GRAVITY], atol=1e-14)


def test_sources_by_name(monkeypatch):
    monkeypatch.setitem(BODY_SOURCES, "planted", "test_sim_body:PlantedSource")
    src = body_source("go1", "planted")
    assert isinstance(src, BodySource) and src.robot == "go1" and body_source("go1", "planted") is src
    with pytest.raises(UnknownBodySourceError, match="unknown body source 'mjcf'; known: urdf, planted"):
        body_source("go1", "mjcf")


def test_the_urdf_source_holds_the_description_mass():
    m = body_model("go1")
    assert m.mass == pytest.approx(get_robot("go1").mass, rel=1e-12)  # every link of the URDF
    assert np.all(np.linalg.eigvalsh(m.inertia - m.inertia_upper) > -1e-12)  # the legs only add
    assert np.all(np.linalg.eigvalsh(m.inertia_upper) > 0)
