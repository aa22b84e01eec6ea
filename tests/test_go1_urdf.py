"""The authored Go1 URDF matches Unitree's published parameters."""

from __future__ import annotations

import numpy as np
import pytest

from symrom.robots import get_robot, leg_kinematics, torque_limits

pybullet = pytest.importorskip("pybullet")

SPEC = get_robot("go1")


@pytest.fixture(scope="module")
def body():
    cid = pybullet.connect(pybullet.DIRECT)
    rid = pybullet.loadURDF(str(SPEC.urdf_path), physicsClientId=cid)
    yield cid, rid
    pybullet.disconnect(cid)


def _joints(cid, rid):
    return {pybullet.getJointInfo(rid, i, physicsClientId=cid)[1].decode(): i
            for i in range(pybullet.getNumJoints(rid, physicsClientId=cid))}


def _links(cid, rid):
    return {pybullet.getJointInfo(rid, i, physicsClientId=cid)[12].decode(): i
            for i in range(pybullet.getNumJoints(rid, physicsClientId=cid))}


def test_masses(body):
    cid, rid = body
    n = pybullet.getNumJoints(rid, physicsClientId=cid)
    total = sum(pybullet.getDynamicsInfo(rid, i, physicsClientId=cid)[0] for i in range(-1, n))
    assert 12.8 <= total <= 13.1 + 1e-9
    assert pybullet.getDynamicsInfo(rid, -1, physicsClientId=cid)[0] == pytest.approx(5.204)
    links = _links(cid, rid)
    for leg in ("FR", "FL", "RR", "RL"):
        for name, m in (("hip", 0.591), ("thigh", 0.92), ("calf", 0.136), ("foot", 0.06)):
            info = pybullet.getDynamicsInfo(rid, links[f"{leg}_{name}"], physicsClientId=cid)
            assert info[0] == pytest.approx(m)


def test_link_lengths_from_kinematics():
    kin = leg_kinematics("go1")
    feet = kin.foot_positions(np.zeros(12))[0]  # (4, 3), legs straight down
    sx = np.array([1, 1, -1, -1])
    sy = np.array([-1, 1, -1, 1])
    np.testing.assert_allclose(feet[:, 0], 0.1881 * sx, atol=1e-9)
    np.testing.assert_allclose(feet[:, 1], (0.04675 + 0.08) * sy, atol=1e-9)
    np.testing.assert_allclose(feet[:, 2], -2 * 0.213, atol=1e-9)
    # standing pose like the A1's sign convention: feet under the hips, base at start height
    stand = kin.foot_positions(np.tile([0.0, 0.8, -1.6], 4))[0]
    np.testing.assert_allclose(stand[:, 0], 0.1881 * sx, atol=1e-9)
    assert -stand[0, 2] + 0.02 == pytest.approx(SPEC.start_height, abs=2e-3)


def test_joint_limits(body):
    cid, rid = body
    joints = _joints(cid, rid)
    expect = {"hip": (-0.863, 0.863, 23.7, 30.1), "thigh": (-0.686, 4.501, 23.7, 30.1),
              "calf": (-2.818, -0.888, 35.55, 20.06)}
    for name in SPEC.joint_names:
        info = pybullet.getJointInfo(rid, joints[name], physicsClientId=cid)
        lo, hi, eff, vel = expect[name.split("_")[1]]
        assert info[2] == pybullet.JOINT_REVOLUTE
        assert (info[8], info[9], info[10], info[11]) == pytest.approx((lo, hi, eff, vel))
    np.testing.assert_allclose(torque_limits("go1"), [23.7, 23.7, 35.55] * 4)


def test_feet_are_spheres(body):
    cid, rid = body
    links = _links(cid, rid)
    for foot in SPEC.foot_links:
        shapes = pybullet.getCollisionShapeData(rid, links[foot], physicsClientId=cid)
        assert len(shapes) == 1 and shapes[0][2] == pybullet.GEOM_SPHERE
        assert shapes[0][3][0] == pytest.approx(0.02)
