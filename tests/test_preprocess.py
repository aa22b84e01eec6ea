"""Preprocessing: the CoM wrench on a hand-built stance, differentiation, phase labels."""

from __future__ import annotations

import numpy as np
import pytest

from symrom.data.preprocess import assemble, com_wrench, differentiate, foot_positions_world, ground_reaction_forces
from symrom.robots import get_robot, leg_kinematics

ROBOTS = ["a1", pytest.param("go1", marks=pytest.mark.skipif(
    not get_robot("go1").urdf_path.is_file(), reason="go1 URDF not present"))]

# A crouched stance, each leg a little different, and a tilted, turned base.
JOINTS = np.array([0.05, 0.75, -1.45, -0.08, 0.85, -1.60, 0.10, 0.95, -1.70, -0.02, 0.70, -1.40])
BASE = np.array([0.3, -0.2, 0.28, 0.07, -0.15, 0.6])  # x y z (m), roll pitch yaw (rad)
# World-frame foot forces, N (mostly up, with friction components).
FORCES = np.array([[5.0, -3.0, 40.0], [-2.0, 4.0, 35.0], [1.0, 2.5, 55.0], [3.0, -1.0, 60.0]])


def _rot(rpy):
    """Base -> world rotation built by hand: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _fd_jacobian(robot, joints, leg, h=1e-6):
    """(3, 3) base-frame foot Jacobian of ``leg`` by central finite differences."""
    kin = leg_kinematics(robot)
    J = np.empty((3, 3))
    for i in range(3):
        dp, dm = joints.copy(), joints.copy()
        dp[3 * leg + i] += h
        dm[3 * leg + i] -= h
        J[:, i] = (kin.foot_positions(dp[None])[0, leg] - kin.foot_positions(dm[None])[0, leg]) / (2 * h)
    return J


def _stance(robot):
    """q (1, 18), tau (1, 12) holding FORCES, and the hand-computed feet (4, 3), world."""
    R = _rot(BASE[3:])
    tau = np.concatenate([-_fd_jacobian(robot, JOINTS, k).T @ (R.T @ FORCES[k]) for k in range(4)])
    feet_base = leg_kinematics(robot).foot_positions(JOINTS[None])[0]
    feet = BASE[:3] + feet_base @ R.T
    return np.r_[JOINTS, BASE][None], tau[None], feet


@pytest.mark.parametrize("robot", ROBOTS)
def test_wrench_of_a_hand_computed_stance(robot):
    q, tau, feet = _stance(robot)
    assert np.all(feet[:, 2] < BASE[2] - 0.15)  # the feet really are below the trunk
    W = com_wrench(robot, q, tau, np.ones((1, 4), np.uint8))[0]
    force = FORCES.sum(axis=0)
    moment = sum(np.cross(feet[k] - BASE[:3], FORCES[k]) for k in range(4))
    np.testing.assert_allclose(W[:3], force, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(W[3:], moment, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(ground_reaction_forces(robot, q, tau, np.ones((1, 4)))[0], FORCES,
                               rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(foot_positions_world(robot, q)[0], feet, atol=1e-12)


@pytest.mark.parametrize("robot", ROBOTS)
def test_feet_in_the_air_carry_no_force(robot):
    q, tau, feet = _stance(robot)
    contact = np.array([[1, 0, 1, 0]], np.uint8)
    W = com_wrench(robot, q, tau, contact)[0]
    down = [0, 2]
    np.testing.assert_allclose(W[:3], FORCES[down].sum(0), rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(W[3:], sum(np.cross(feet[k] - BASE[:3], FORCES[k]) for k in down),
                               rtol=1e-6, atol=1e-5)
    assert np.all(com_wrench(robot, q, tau, np.zeros((1, 4), np.uint8)) == 0)


def test_logged_foot_positions_are_used():
    q, tau, feet = _stance("a1")
    moved = feet + np.array([0.0, 0.0, -0.1])
    W = com_wrench("a1", q, tau, np.ones((1, 4), np.uint8), foot_pos=moved[None])[0]
    expect = sum(np.cross(moved[k] - BASE[:3], FORCES[k]) for k in range(4))
    np.testing.assert_allclose(W[3:], expect, rtol=1e-6, atol=1e-5)


# ----------------------------------------------------------------- differentiation

def _signal(dt=0.002, n=200):
    """Two jumps of a smooth signal (N, 2) with a jump in value between them, and its derivative."""
    t = np.arange(n) * dt
    x1 = np.stack([np.sin(7 * t), t ** 2], axis=1)
    d1 = np.stack([7 * np.cos(7 * t), 2 * t], axis=1)
    x2 = np.stack([50 + np.cos(5 * t), -3 * t ** 3], axis=1)
    d2 = np.stack([-5 * np.sin(5 * t), -9 * t ** 2], axis=1)
    jump = np.repeat([0, 1], n)
    return np.concatenate([x1, x2]), np.concatenate([d1, d2]), jump, dt


@pytest.mark.parametrize("method, tol", [("savgol", 1e-4), ("central", 2e-3)])
def test_differentiation_recovers_a_known_derivative(method, tol):
    x, dx, jump, dt = _signal()
    est = differentiate(x, dt, jump, method)
    assert est.shape == x.shape
    inner = np.r_[5:195, 205:395]
    np.testing.assert_allclose(est[inner], dx[inner], atol=tol)
    # Edges, including the rows next to the 50-unit step between the jumps, stay accurate.
    np.testing.assert_allclose(est, dx, atol=0.1)


def test_central_is_second_order():
    x, dx, jump, dt = _signal()
    err1 = np.abs(differentiate(x, dt, jump, "central") - dx)[5:195].max()
    x2, dx2, jump2, _ = _signal(dt / 2, 400)
    err2 = np.abs(differentiate(x2, dt / 2, jump2, "central") - dx2)[10:390].max()
    assert 3.0 < err1 / err2 < 5.0


def test_differentiation_rejects_unknown_method():
    x, _, jump, dt = _signal()
    with pytest.raises(ValueError, match="spline"):
        differentiate(x, dt, jump, "spline")


# ----------------------------------------------------------------- phases

# Per-row foot flags (FR FL RR RL) of one jump: stance, staggered take-off,
# flight, staggered touch-down, stance.
PATTERN = np.array([[1, 1, 1, 1]] * 3 + [[1, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]]
                   + [[0, 0, 0, 0]] * 3 + [[1, 0, 0, 0], [1, 1, 0, 1]] + [[1, 1, 1, 1]] * 2,
                   dtype=np.uint8)
PRONK = [0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0]
FROGGY = [0, 0, 0, 1, 1, 1, 2, 2, 2, 0, 0, 0, 0]


def _assemble(motion, contact, robot="a1"):
    n = contact.shape[0] // PATTERN.shape[0]
    rows = PATTERN.shape[0]
    rng = np.random.default_rng(0)
    q = np.r_[JOINTS, BASE] + 0.01 * rng.standard_normal((n * rows, 18))
    t = np.tile(np.arange(rows) * 0.002, n)
    return assemble(robot=robot, motion=motion, source="synthetic", jump=np.repeat(np.arange(n), rows),
                    t=t, q=q, dq=np.cumsum(q, 0), tau=rng.standard_normal((n * rows, 12)),
                    contact=contact)


@pytest.mark.parametrize("motion, names, expect", [
    ("pronk", ["contact", "flight"], PRONK),
    ("froggy", ["contact", "partial", "flight"], FROGGY),
])
def test_assemble_labels_phases(motion, names, expect):
    contact = np.tile(PATTERN, (2, 1))
    ds = _assemble(motion, contact)
    assert ds.phase_names == names
    np.testing.assert_array_equal(ds.phase, np.tile(expect, 2))
    np.testing.assert_array_equal(ds.u[:, :12], ds.tau)
    np.testing.assert_allclose(ds.u[:, 12:], com_wrench("a1", ds.q, ds.tau, contact))
    np.testing.assert_allclose(ds.ddq, differentiate(ds.dq, 0.002, ds.jump, "savgol"))
    assert list(ds.split) == ["train", "train"]


def test_froggy_partial_is_per_jump():
    """A jump with no flight at all is partial wherever 1-3 feet are down."""
    no_flight = PATTERN.copy()
    no_flight[6:9] = [1, 0, 0, 0]
    ds = _assemble("froggy", np.concatenate([no_flight, PATTERN]))
    first = ds.phase[:PATTERN.shape[0]]
    np.testing.assert_array_equal(first, [0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0])
    np.testing.assert_array_equal(ds.phase[PATTERN.shape[0]:], FROGGY)


def test_savgol_derivative_is_scipys_to_the_last_bit_without_importing_scipy_signal():
    """``savgol_derivative`` gives ``scipy.signal.savgol_filter(..., deriv=1, mode="interp")``
    bit for bit (the datasets stay byte for byte) on rows of any trailing shape, windows and
    orders, and a fresh process that builds a dataset's derivatives imports neither
    ``scipy.signal`` nor ``scipy.ndimage``; a cubic's derivative comes out exact, ends included."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from scipy.signal import savgol_filter

    import symrom
    from symrom.data.preprocess import savgol_derivative

    rng = np.random.default_rng(7)
    for n, window, order, tail, dt in ((9, 9, 3, (18,), 0.002), (40, 5, 1, (), 0.01), (200, 9, 3, (4, 3), 0.002),
                                        (31, 13, 4, (2,), 1 / 300), (12, 11, 2, (5,), 0.001), (20, 8, 3, (3,), 0.002)):
        x = rng.normal(size=(n, *tail)) * 10.0 ** rng.uniform(-3, 3)
        np.testing.assert_array_equal(savgol_derivative(x, window, order, dt),
                                      savgol_filter(x, window, order, deriv=1, delta=dt, axis=0, mode="interp"))
    t = np.arange(50) * 0.002
    np.testing.assert_allclose(savgol_derivative((t ** 3 - t)[:, None], 9, 3, 0.002)[:, 0], 3 * t ** 2 - 1,
                               rtol=0, atol=1e-9)
    code = ("import sys, numpy as np; from symrom.data.preprocess import differentiate; "
            "differentiate(np.ones((30, 18)), 0.002, np.zeros(30, int)); "
            "print('scipy.signal' in sys.modules, 'scipy.ndimage' in sys.modules)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(symrom.__file__).parents[1]),
                                                         os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert out.returncode == 0 and out.stdout.split() == ["False", "False"], out.stderr


@pytest.mark.parametrize("kind", ["symmetric", "antisymmetric", "general"])
def test_correlation_inside_is_ndimages_to_the_last_bit(kind):
    """The rows ``_correlate_inside`` fills are ``scipy.ndimage.correlate1d``'s bit for bit, for
    weights SciPy pairs about the centre (symmetric, antisymmetric) and weights it does not (any,
    even-sized with a convolution's origin), and exactly the rows whose window lies inside."""
    from scipy.ndimage import correlate1d

    from symrom.data.preprocess import _correlate_inside

    rng = np.random.default_rng(3)
    for k in (1, 2, 3, 4, 5, 8, 9, 13):
        if kind != "general" and k % 2 == 0:
            continue
        for n in (k, k + 1, 37):
            w = rng.normal(size=k) * 50.0
            if kind == "symmetric":
                w = w + w[::-1]
            elif kind == "antisymmetric":
                w = w - w[::-1]
            x = rng.normal(size=(n, 2, 3)) * 10.0 ** rng.uniform(-3, 3)
            origin = -1 if k % 2 == 0 else 0
            out = np.full_like(x, np.nan)
            _correlate_inside(x, w, origin, out)
            inside = ~np.isnan(out[:, 0, 0])
            assert inside.sum() == n - k + 1
            ref = correlate1d(x, w, axis=0, mode="constant", origin=origin)
            np.testing.assert_array_equal(out[inside], ref[inside])
