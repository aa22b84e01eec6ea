"""The motions on robots that state their actuators: the feed-forward of the effects a description
states (damping, friction loss, armature), checked term by term against the ideal robot's
torques; pronk and froggy jumps in MuJoCo on the four Menagerie-style test models and on the
mesh-free copies of Menagerie's eight quadrupeds as `robot init` writes them (their own joint
damping, friction loss, armature, contacts and limits); froggy's longer push on legs weak for
their size; a dataset's wrench from the torques that reach the joints; the proxy's effects on
top of the description's, uncompensated."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from _menagerie import COPIES, init_copies

from symrom.names import JOINTS
from symrom.robots import get_robot, leg_kinematics
from symrom.robots.description import FRICTION_SPEED, ActuatorEffects
from symrom.robots.init import init_robot
from symrom.robots.stance import start_pose
from symrom.sim.controllers.actuators import Compensation, stance_acceleration

MODELS = Path(__file__).parent / "robots"
NAMES = ("go1", "go2", "a1", "anymal_c")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """robot init on each test model, once: name -> description path; and its ideal twin (the
    same file without its [actuators]) as name + '_ideal'."""
    folder = tmp_path_factory.mktemp("robots")
    out = {}
    for name in NAMES:
        r = init_robot(MODELS / f"{name}.xml", folder / f"{name}.toml")
        out[name] = str(r.path)
        ideal = folder / f"{name}_ideal.toml"
        ideal.write_text(re.sub(r"\n\[actuators\].*", "\n", r.text, flags=re.S))
        out[name + "_ideal"] = str(ideal)
    return out


# ------------------------------------------------------------------ the losses
def test_the_losses_are_damping_friction_and_armature():
    e = ActuatorEffects(damping=(1.0, 2.0, 3.0), armature=(0.01, 0.02, 0.03), friction_loss=(0.2, 0.3, 0.4))
    dq = np.tile([5.0, -0.5 * FRICTION_SPEED, -2.0], 4)
    ddq = np.tile([100.0, 0.0, -50.0], 4)
    want = np.tile([1.0 * 5 + 0.2 + 0.01 * 100, 2.0 * -0.05 - 0.15, 3.0 * -2 - 0.4 - 0.03 * 50], 4)
    assert np.allclose(e.losses(dq, ddq), want, rtol=0, atol=1e-12)
    assert np.allclose(e.losses(dq), want - np.tile([1.0, 0.0, -1.5], 4), atol=1e-12)  # no armature without ddq
    assert np.array_equal(e.losses(-dq, -ddq), -e.losses(dq, ddq))  # odd in the motion
    both = e + ActuatorEffects(damping=(0.5,) * 3)
    assert both.damping == (1.5, 2.5, 3.5) * 4 and both.armature == e.armature and both.friction_loss == e.friction_loss
    assert ActuatorEffects().ideal and not Compensation("go1").active  # the built-in robots state none


def test_legs_are_scaled_into_what_the_losses_leave(written):
    comp = Compensation(written["go1"])
    limit = np.asarray(get_robot(written["go1"]).torque_limit)
    rng = np.random.default_rng(0)
    fitted = 0
    for _ in range(200):
        tau, dq = rng.normal(0, 15, 12), rng.normal(0, 10, 12)
        out = comp.scaled_legs(tau, dq, limit)
        loss = np.clip(comp.losses(dq), -limit, limit)
        assert np.all(np.abs(out) <= limit + 1e-9)
        for k in range(4):
            s = slice(3 * k, 3 * k + 3)
            got = out[s] - loss[s]  # what the joints get
            ratio = got @ tau[s] / (tau[s] @ tau[s])
            assert np.allclose(got, ratio * tau[s], atol=1e-9) and -1e-12 <= ratio <= 1 + 1e-12  # its direction
            if ratio < 1 - 1e-9:  # scaled: some joint of the leg is at its limit
                assert np.isclose(np.abs(out[s]), limit[s]).any()
            else:
                fitted += 1
                assert np.allclose(out[s], tau[s] + loss[s], atol=1e-12)  # the losses made up (up to the limits)
    assert 100 < fitted < 800  # both cases were met


def test_planned_joint_accelerations_keep_the_feet_at_their_speed(written):
    """stance_acceleration against the joint path that keeps a foot at a constant speed (the
    leg IK integrated, its speeds differentiated)."""
    robot = written["go1"]
    kin = leg_kinematics(robot)
    q0 = start_pose(robot, 0.22)[JOINTS]
    v = np.tile([-0.3, 0.0, -1.2], (4, 1))  # m/s, the feet leaving the base down and back

    def speeds(q):
        _, J = kin.one(q)
        return np.concatenate([np.linalg.solve(J[k], v[k]) for k in range(4)])

    def walk(q, h, n=20):  # RK4 along dq = J^-1 v for time h
        for _ in range(n):
            k1 = speeds(q)
            k2 = speeds(q + h / n / 2 * k1)
            k3 = speeds(q + h / n / 2 * k2)
            k4 = speeds(q + h / n * k3)
            q = q + h / n / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return q

    h = 2e-4
    numeric = (speeds(walk(q0, h)) - speeds(walk(q0, -h))) / (2 * h)
    planned = stance_acceleration(kin, q0, v, range(4))
    assert np.abs(numeric).max() > 1.0  # the joints do speed up at a constant foot speed
    assert np.allclose(planned, numeric, rtol=1e-4, atol=1e-4)
    only_rear = stance_acceleration(kin, q0, v, (2, 3))
    assert np.array_equal(only_rear[:6], np.zeros(6)) and np.allclose(only_rear[6:], planned[6:], atol=1e-12)


# ------------------------------------------------------------------ the controllers
def _state(robot: str, dq_joints: np.ndarray, t: float = 0.0):
    """The robot standing (MuJoCo), its joints turning at dq_joints (12,) rad/s."""
    from symrom.sim.engines.registry import make_world
    from symrom.sim.engines.world import RobotState

    w = make_world("mujoco", robot)
    try:
        w.reset(start_pose(robot))
        s = w.state()
    finally:
        w.close()
    dq = s.dq.copy()
    dq[JOINTS] = dq_joints
    return RobotState(t=t, q=s.q, dq=dq, omega=s.omega, R=s.R, contact=s.contact, foot_pos=s.foot_pos,
                      foot_vel=s.foot_vel)


@pytest.mark.parametrize("name", ["go1", "anymal_c"])
def test_the_pronk_adds_the_stated_losses_to_the_ideal_robots_torques(written, name):
    from symrom.sim.controllers.pronk import PronkController, PronkParams

    robot, ideal = written[name], written[name + "_ideal"]
    dqj = np.random.default_rng(1).normal(0, 0.8, 12)
    s = _state(robot, dqj)
    with_, without = PronkController(robot, PronkParams()), PronkController(ideal, PronkParams())
    assert with_.compensation.active and not without.compensation.active
    tau, tau0 = with_.torque(s), without.torque(s)
    assert np.abs(tau0).max() < 0.8 * np.asarray(without.torque_limit).min()  # nothing clipped
    assert np.allclose(tau - tau0, get_robot(robot).actuators.losses(dqj), rtol=0, atol=1e-9)


@pytest.mark.parametrize("phase_time", [0.1, "push_all"])
def test_froggy_adds_the_losses_and_the_pushs_armature(written, phase_time):
    from symrom.sim.controllers.froggy import FroggyController, FroggyParams, scaled

    robot, ideal = written["go1"], written["go1_ideal"]
    params = scaled(FroggyParams(), robot)
    t = params.t_settle + params.t_crouch + params.t_hold + 0.01 if phase_time == "push_all" else phase_time
    dqj = np.random.default_rng(2).normal(0, 0.5, 12)
    s = _state(robot, dqj, t)
    a, b = FroggyController(robot, params), FroggyController(ideal, params)
    a.mass = b.mass = get_robot(robot).mass
    tau, tau0 = a.torque(s), b.torque(s)
    assert a.phase == b.phase == ("push_all" if phase_time == "push_all" else "settle")
    ddq = None
    if a.phase == "push_all":  # the stance legs' planned accelerations take armature torque
        v = -params.push_speed * np.array([np.sin(params.angle), 0.0, np.cos(params.angle)])
        ddq = stance_acceleration(a.kin, s.q[JOINTS], np.tile(v, (4, 1)), range(4))
        assert np.abs(ddq).max() > 1.0
    losses = get_robot(robot).actuators.losses(dqj, ddq)
    assert np.all(np.abs(tau0) < a.limit) and np.all(np.abs(tau0 + losses) < a.limit)  # nothing scaled
    assert np.allclose(tau - tau0, losses, rtol=0, atol=1e-9)
    assert np.allclose(tau, a.torque_numpy(s), rtol=0, atol=1e-9)  # the NumPy reference too


def test_the_proxy_adds_hidden_effects_the_controllers_do_not_compensate(written):
    from symrom.sim.engines.registry import make_world
    from symrom.sim.proxy import ProxyConfig, apply_to_world

    robot = written["go1"]
    w = make_world("mujoco", robot)
    try:
        cfg = ProxyConfig(damping=(0.3, 0.3, 0.3), armature=(0.005, 0.005, 0.005), friction_loss=(0.1, 0.1, 0.1))
        apply_to_world(w, cfg)
        stated = get_robot(robot).actuators
        assert w.effects == stated + cfg.effects
        assert np.allclose(w.model.dof_damping[w._vadr], np.asarray(stated.damping) + 0.3)
    finally:
        w.close()
    assert Compensation(robot).effects == stated  # the controllers know the description's only


# ------------------------------------------------------------------ jumps
def _attempts(robot: str, motion: str, jumps: int, seed: int, max_attempts: int) -> list[int]:
    """Attempts each jump took to pass the checks (MuJoCo), in this process."""
    from symrom.sim.generation.config import GenerateConfig
    from symrom.sim.generation.runner import run_checked_jump

    cfg = GenerateConfig(robot, motion, jumps, seed=seed, engine="mujoco", max_attempts=max_attempts)
    return [run_checked_jump(cfg, j)[1]["attempt"] + 1 for j in range(jumps)]


@pytest.fixture(scope="module")
def go1_pronk(written, tmp_path_factory):
    """The Go1 test model's pronk jump (MuJoCo, seed 1) as a generated file, made once: the jump
    test reads its attempts, the wrench test its data."""
    from symrom.sim.generation.generate import GenerateConfig, generate

    return generate(GenerateConfig(written["go1"], "pronk", 1, seed=1, engine="mujoco"),
                    tmp_path_factory.mktemp("go1") / "go1.h5")


@pytest.mark.slow
@pytest.mark.parametrize("motion", ["pronk", "froggy"])
@pytest.mark.parametrize("name", NAMES)
def test_pronk_and_froggy_jump_each_test_robot_as_written(written, name, motion, request):
    """A checked jump (the common checks and the motion's own) of each motion on each test model
    with its own damping, friction loss and armature, in at most two attempts (seed 1: one;
    docs/simulation.md, "Your robot", has the attempts over six jumps)."""
    if (name, motion) == ("go1", "pronk"):  # the same jump as the wrench test's file: run once
        attempts = [r["attempt"] + 1 for r in request.getfixturevalue("go1_pronk").generator["jumps"]]
    else:
        attempts = _attempts(written[name], motion, 1, seed=1, max_attempts=2)
    assert max(attempts) <= 2, attempts


@pytest.fixture(scope="module")
def menagerie(tmp_path_factory):
    """robot init on each Menagerie copy (the keys it cannot infer given): name -> description path."""
    return {n: str(r.path) for n, r in init_copies(tmp_path_factory.mktemp("menagerie")).items()}


@pytest.mark.slow
@pytest.mark.parametrize("motion", ["pronk", "froggy"])
@pytest.mark.parametrize("name", list(COPIES))
def test_pronk_and_froggy_jump_each_menagerie_quadruped(menagerie, name, motion):
    """A checked jump of each motion on each of Menagerie's quadrupeds as published (mesh-free),
    in at most four attempts (seed 1: one; docs/simulation.md, "Your robot", has the attempts over
    six jumps)."""
    attempts = _attempts(menagerie[name], motion, 1, seed=1, max_attempts=4)
    assert max(attempts) <= 4, attempts


@pytest.mark.slow
def test_without_the_longer_push_weak_legs_do_not_froggy(menagerie, monkeypatch):
    """The planted fault: froggy's push as long as the A1's on Barkour vB (18 N m for 14.5 kg,
    0.43 of the A1's torque for its mass and leg length) never leaves the ground long enough."""
    from symrom.sim.controllers import froggy
    from symrom.sim.generation.runner import GenerationError

    assert (froggy.scaled(froggy.FroggyParams(), menagerie["barkour_vb"]).t_push_all
            > 1.4 * froggy.FroggyParams().t_push_all)
    monkeypatch.setattr(froggy, "_PUSH", ())
    with pytest.raises(GenerationError, match="no valid jump in 3 attempts"):
        _attempts(menagerie["barkour_vb"], "froggy", 1, seed=1, max_attempts=3)


@pytest.mark.slow
def test_without_the_feed_forward_the_menagerie_go1_does_not_pronk(written, monkeypatch):
    """The planted fault: the same robot, the feed-forward off, fails every attempt (flights
    too short: the damping takes the push's torque)."""
    from symrom.sim.controllers import actuators
    from symrom.sim.generation.runner import GenerationError

    monkeypatch.setattr(actuators.Compensation, "__init__", lambda self, robot: (
        setattr(self, "effects", ActuatorEffects()), setattr(self, "active", False))[-1])
    with pytest.raises(GenerationError, match="no valid jump in 3 attempts"):
        _attempts(written["go1"], "pronk", 1, seed=1, max_attempts=3)


@pytest.mark.slow
def test_the_datasets_wrench_is_that_of_the_torques_reaching_the_joints(go1_pronk):
    """u's summed ground force is the engine's to within the legs' weight and inertia on a robot
    whose joints take a damping of 2 N m s/rad: derived from the motors' torques it would not be."""
    from symrom.data.preprocess import input_from_torques

    # one jump: its RMS (31 N; 153 N from the motors) is as far from 45 N as two jumps' (28; 156)
    ds = go1_pronk
    engine = ds.contact_force.sum(axis=1)[:, 2]
    motors = input_from_torques(ds.robot, ds.q, ds.tau, ds.contact, ds.foot_pos)
    rms = lambda u: float(np.sqrt(np.mean((u[:, 14] - engine) ** 2)))  # noqa: E731
    assert np.array_equal(ds.u[:, :12], ds.tau)  # u's torques stay the logged ones
    assert rms(ds.u) < 45.0 < 3 * rms(ds.u) < rms(motors), (rms(ds.u), rms(motors))
