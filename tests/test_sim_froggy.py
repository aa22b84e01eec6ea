"""A1 froggy jumps under Cartesian PD: every generated jump has the phases the paper needs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _simdata import N_JUMPS, reference_file

from symrom.data.io import read_dataset
from symrom.robots import get_robot
from symrom.sim.controllers import froggy
from symrom.sim.engines.bullet import BulletWorld as World

pytestmark = pytest.mark.slow
LIMIT = np.asarray(get_robot("a1").torque_limit)


@pytest.fixture(scope="module")
def ds():
    return read_dataset(reference_file("froggy"))  # read_dataset validates the file


def _per_jump(ds):
    for j, (a, b) in enumerate(ds.jump_bounds()):
        yield j, slice(a, b)


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    best, run_start = (0, 0), None
    for i, m in enumerate(np.r_[mask, False]):
        if m and run_start is None:
            run_start = i
        elif not m and run_start is not None:
            if i - run_start > best[1] - best[0]:
                best = (run_start, i)
            run_start = None
    return best


def test_file_layout(ds):
    assert ds.robot == "a1" and ds.motion == "froggy" and ds.source == "sim"
    assert ds.dt == 0.002 and ds.n_jumps == N_JUMPS["froggy"]
    assert ds.phase_names == ["contact", "partial", "flight"]
    for _j, s in _per_jump(ds):
        assert np.allclose(np.diff(ds.t[s]), 0.002)
        assert 900 <= ds.t[s].size <= 1500  # ~1200 samples per jump, as in the paper
    gen = ds.generator
    assert gen["config"]["seed"] == 3 and len(gen["jumps"]) == ds.n_jumps
    assert "retries" in gen and all("retries" in r for r in gen["jumps"])
    json.dumps(gen)


def test_each_jump_has_rear_only_push_then_a_real_flight(ds):
    for j, s in _per_jump(ds):
        c = ds.contact[s]
        a, b = _longest_run(c.sum(axis=1) == 0)
        assert (b - a) * ds.dt >= 0.12, f"jump {j}: flight {(b - a) * ds.dt:.3f} s"
        assert (c[:a].sum(axis=1) > 0).all(), f"jump {j}: feet left the ground before the flight"
        rear_only = (c[:, :2].sum(axis=1) == 0) & (c[:, 2:].sum(axis=1) > 0)
        n = 0
        while rear_only[a - 1 - n]:
            n += 1
        assert n * ds.dt >= 0.04, f"jump {j}: rear-only contact {n * ds.dt:.3f} s"
        assert c[0].tolist() == [1, 1, 1, 1]
        assert (c[b:].sum(axis=1) == 4).any(), f"jump {j}: never back on four feet"
        ph = ds.phase[s]
        assert (ph[a:b] == ds.phase_id("flight")).all()
        assert (ph[a - n:a] == ds.phase_id("partial")).all()


def test_each_jump_rises_travels_and_lands_upright(ds):
    for j, s in _per_jump(ds):
        q = ds.q[s]
        assert q[:, 14].max() - q[0, 14] >= 0.05, f"jump {j}: apex gain"
        assert q[-1, 12] - q[0, 12] >= 0.1, f"jump {j}: forward travel"
        assert np.abs(q[:, 15:17]).max() < 0.8, f"jump {j}: tilt"
        assert q[-1, 14] > 0.15
        assert np.all(np.abs(ds.tau[s]) <= LIMIT + 1e-9)


def test_jumps_differ(ds):
    travel = [ds.q[s][-1, 12] - ds.q[s][0, 12] for _, s in _per_jump(ds)]
    assert np.ptp(travel) > 1e-3


def test_sample_params_is_deterministic_and_varied():
    a = froggy.sample_params(np.random.default_rng(1))
    b = froggy.sample_params(np.random.default_rng(1))
    c = froggy.sample_params(np.random.default_rng(2))
    assert a == b and a != c


def test_initial_pose_is_standing():
    with World("a1") as w:
        ctrl = froggy.FroggyController("a1", froggy.FroggyParams())
        w.reset(ctrl.reset(w))
        s = w.state()
        assert s.contact.tolist() == [1, 1, 1, 1]
        tau = ctrl.torque(s)
        assert tau.shape == (12,) and np.all(np.abs(tau) <= LIMIT + 1e-9)
        assert not ctrl.done(s)


def test_hx_joints_are_held_as_in_the_paper(ds):
    for j, s in _per_jump(ds):
        assert np.ptp(ds.q[s][:, 0:12:3], axis=0).max() < 1e-4, f"jump {j}: hx moved"


def _hx_travel(hold: bool) -> float:
    """Largest hx excursion (rad) over the crouch and push of a default jump."""
    params = froggy.FroggyParams(hold_hx=hold)
    with World("a1") as w:
        ctrl = froggy.FroggyController("a1", params)
        w.reset(ctrl.reset(w))
        hx = []
        for _ in range(950):
            s = w.state()
            hx.append(s.q[0:12:3])
            w.step(ctrl.torque(s))
    return float(np.ptp(np.array(hx), axis=0).max())


def test_hx_moves_when_not_held():
    assert _hx_travel(False) > 100 * _hx_travel(True)


def _rear_feet_up_after_landing(landing: str, seed: int) -> tuple[float, float]:
    """Seconds the rear feet spend off the ground from 0.15 s after touchdown (the landing's
    first compression over), and the trunk's pitch at the end, for one A1 froggy jump."""
    from symrom.sim.controllers.froggy import FroggyController, sample_params
    from symrom.sim.engines.registry import make_world
    from symrom.sim.generation.episode import run_episode

    params = sample_params(np.random.default_rng(seed))
    ctrl = FroggyController("a1", params, landing=landing)
    world = make_world("mujoco", "a1")
    log = []
    try:
        run_episode(world, ctrl, ctrl.reset(world), params.max_time,
                    on_sample=lambda tick, s, applied: log.append((s.t, s.q[16], s.contact[2] or s.contact[3])))
    finally:
        world.close()
    t, pitch, rear_down = (np.array(v, float) for v in zip(*log))
    late = t > ctrl.touchdown[0] + 0.15
    return float(np.sum(late & (rear_down == 0)) * (t[1] - t[0])), float(pitch[-1])


@pytest.mark.parametrize("seed", [0, 1])
def test_plumb_low_legs_bring_the_rear_feet_down_sooner(seed):
    # Body-fixed landing targets put the front feet under the CoM: the trunk pivots over them,
    # rear feet in the air, for half a second or more; the low end's legs plumb end that sooner.
    body, body_pitch = _rear_feet_up_after_landing("body", seed)
    plumb, plumb_pitch = _rear_feet_up_after_landing("low_plumb", seed)
    assert body > 0.45
    assert plumb < min(0.85 * body, 0.5)
    assert abs(plumb_pitch) < 0.15


def test_unknown_landing_is_refused():
    with pytest.raises(ValueError, match="low_plumb"):
        froggy.FroggyController("a1", froggy.FroggyParams(), landing="level")


@pytest.mark.parametrize("pitch", [0.6, 0.95, -0.9])
def test_flight_targets_past_flight_pitch_keep_the_feet_depth(pitch):
    # Past flight_pitch the flight's targets sit in the trunk's frame at the clipped pitch, each
    # foot at the depth below the base its level target has: the controller pulls nowhere when
    # the feet are there, and (past the limit) pulls hard there without the limit. Checked on
    # the pair at the trunk's lower end, the legs that land: the other pair's targets are out
    # of reach at these pitches, limit or not.
    from symrom.names import JOINTS
    from symrom.robots import leg_kinematics
    from symrom.robots.kinematics import rpy_to_matrix
    from symrom.robots.stance import leg_ik
    from symrom.sim.controllers.compiled import FLIGHT, froggy_torque

    cap = 0.75
    ctrl = froggy.FroggyController("a1", froggy.FroggyParams(), flight_pitch=cap)
    stand = ctrl.params.stand_height
    R = rpy_to_matrix(np.array([[0.0, pitch, 0.0]]))[0]
    e = pitch - np.clip(pitch, -cap, cap)
    # in the frame pitched by e from level, the depth d puts each foot stand below the base
    x = ctrl.feet0[:, 0]
    d = (x * np.sin(e) - stand) / np.cos(e)
    P = rpy_to_matrix(np.array([[0.0, e, 0.0]]))[0]
    target_body = (R.T @ P @ np.stack([x, ctrl.feet0[:, 1], d], axis=1).T).T
    np.testing.assert_allclose((R @ target_body.T).T[:, 2], -stand, atol=1e-12)
    q, dq = np.zeros(18), np.zeros(18)
    q[JOINTS] = leg_ik("a1", target_body)
    low = slice(0, 6) if pitch > 0 else slice(6, 12)  # the lower pair's joints
    feet = slice(0, 2) if pitch > 0 else slice(2, 4)
    np.testing.assert_allclose(leg_kinematics("a1").foot_positions(q[JOINTS][None])[0][feet], target_body[feet],
                               atol=1e-6)
    q[14], q[16] = 0.4, pitch

    def tau(limit_pitch):
        feet = ctrl.feet0
        return froggy_torque(FLIGHT, 2.0, ctrl._prm, 1.0, 0.0, 12.0, q, dq, R, np.zeros(3),
                             np.zeros(4, dtype=np.uint8), feet, feet, feet, np.zeros(3), ctrl.limit, 0,
                             limit_pitch, 0, *ctrl._chains)

    assert np.max(np.abs(tau(cap)[low])) < 1e-2
    if e != 0.0:
        assert np.max(np.abs(tau(np.inf)[low])) > 1.0


def _flight_targets(ctrl, pitch: float) -> np.ndarray:
    """The flight's leg targets (4, 3) in the base frame at ``pitch`` rad (roll, yaw and forward
    speed zero), written out from their definition: level below flight_pitch; past it in the frame
    pitched by the excess, each foot ``stand_height`` below the base."""
    from symrom.robots.kinematics import rpy_to_matrix

    cap, stand, x = ctrl.flight_pitch, ctrl.params.stand_height, ctrl.feet0[:, 0]
    e = pitch - np.clip(pitch, -cap, cap)
    d = (x * np.sin(e) - stand) / np.cos(e)
    R, P = (rpy_to_matrix(np.array([[0.0, a, 0.0]]))[0] for a in (pitch, e))
    return (R.T @ P @ np.stack([x, ctrl.feet0[:, 1], d], axis=1).T).T


@pytest.mark.parametrize("pitch", [0.3, 0.95, -0.9])
def test_flight_track_follows_targets_the_trunk_turns_under(pitch):
    # The trunk turns nose down at 2.5 rad/s; each foot sits at its flight target and moves, in
    # the base frame, as that target does (the derivative of its definition, by central
    # differences). Tracking, the PD pulls nowhere; damping the feet to rest, it pulls them back.
    from symrom.names import JOINTS
    from symrom.robots import leg_kinematics
    from symrom.robots.kinematics import rpy_to_matrix
    from symrom.robots.stance import leg_ik
    from symrom.sim.controllers.compiled import FLIGHT, froggy_torque

    rate, h = 2.5, 1e-6
    ctrl = froggy.FroggyController("a1", froggy.FroggyParams(), flight_pitch=0.75, flight_track=True)
    target = _flight_targets(ctrl, pitch)
    v_target = (_flight_targets(ctrl, pitch + h) - _flight_targets(ctrl, pitch - h)) / (2 * h) * rate
    q, dq = np.zeros(18), np.zeros(18)
    q[JOINTS] = leg_ik("a1", target)
    pos, J = leg_kinematics("a1").one(q[JOINTS])
    low = slice(0, 2) if pitch > 0 else slice(2, 4)  # the lower pair: the other's targets are out of reach
    np.testing.assert_allclose(pos[low], target[low], atol=1e-6)
    for k in range(4):
        dq[3 * k:3 * k + 3] = np.linalg.solve(J[k], v_target[k])
    q[14], q[16] = 0.4, pitch
    R = rpy_to_matrix(np.array([[0.0, pitch, 0.0]]))[0]
    omega = np.array([0.0, rate, 0.0])

    def tau(track, contact=np.zeros(4, dtype=np.uint8)):
        feet = ctrl.feet0
        return froggy_torque(FLIGHT, 2.0, ctrl._prm, 1.0, 0.0, 12.0, q, dq, R, omega, contact, feet, feet, feet,
                             np.zeros(3), ctrl.limit, 0, ctrl.flight_pitch, track, *ctrl._chains)

    joints = slice(3 * low.start, 3 * low.stop)
    assert np.max(np.abs(tau(1)[joints])) < 1e-2
    assert np.max(np.abs(tau(0)[joints])) > 0.1
    # with a foot still down the flight does not track: the same torques as without
    down = np.array([0, 0, 1, 0], dtype=np.uint8)
    np.testing.assert_array_equal(tau(1, down), tau(0, down))


def test_flight_pitch_must_be_a_positive_angle():
    for bad in (0.0, -0.5, float("nan")):
        with pytest.raises(ValueError, match="flight_pitch"):
            froggy.FroggyController("a1", froggy.FroggyParams(), flight_pitch=bad)


def _crouched_feet():
    """A1-like feet (4, 3) m and a base centre over the rear pair, as a froggy crouches."""
    feet = np.array([[0.16, -0.13, 0.0], [0.16, 0.13, 0.0], [-0.2, -0.13, 0.0], [-0.2, 0.13, 0.0]])
    return feet, np.array([0.0, 0.0, 0.19])


def test_push_forces_keep_to_the_friction_pyramid():
    # Least norm gives every foot the same horizontal share: the lightly loaded front feet are asked
    # past their pyramid. Within it, the same sum and (here reachable) the same moment.
    feet, centre = _crouched_feet()
    force, moment = np.array([116.0, 0.0, 204.0]), np.array([0.1, -0.1, 0.0])
    free = froggy.wrench_forces(feet, centre, (0, 1, 2, 3), force, moment)
    assert np.max(np.abs(free[:2, 0]) / free[:2, 2]) > 1.0
    f = froggy.wrench_forces(feet, centre, (0, 1, 2, 3), force, moment, mu=0.6)
    np.testing.assert_allclose(f.sum(axis=0), force, atol=1e-6)
    assert np.all(f[:, 2] >= -1e-9)
    assert np.all(np.abs(f[:, :2]) <= 0.6 * f[:, 2:3] + 1e-6)
    np.testing.assert_allclose(np.cross(feet - centre, f).sum(axis=0), moment, atol=1e-3)


def test_push_forces_within_the_pyramid_are_the_least_norm_ones():
    feet, centre = _crouched_feet()
    force, moment = np.array([20.0, 3.0, 204.0]), np.array([0.5, -1.0, 0.2])
    free = froggy.wrench_forces(feet, centre, (0, 1, 2, 3), force, moment)
    assert np.array_equal(froggy.wrench_forces(feet, centre, (0, 1, 2, 3), force, moment, mu=0.6), free)


def test_a_sum_past_the_pyramid_is_shared_at_its_own_ratio():
    # a plan at its friction bound, to round-off: every foot at most at the sum's ratio
    feet, centre = _crouched_feet()
    force = np.array([0.61 * 300.0, 0.0, 300.0])
    free = froggy.wrench_forces(feet, centre, (0, 1, 2, 3), force, np.zeros(3))
    assert np.max(np.abs(free[:, 0]) / free[:, 2]) > 1.0  # least norm asks more of the front feet
    f = froggy.wrench_forces(feet, centre, (0, 1, 2, 3), force, np.zeros(3), mu=0.6)
    np.testing.assert_allclose(f.sum(axis=0), force, atol=1e-6)
    assert np.all(f[:, 2] >= -1e-9)
    assert np.all(np.abs(f[:, 0]) <= 0.61 * f[:, 2] * (1 + 1e-6) + 1e-6)
