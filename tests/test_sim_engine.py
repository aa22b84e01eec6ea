"""The engine seam: both worlds speak the same coordinates, forces and holds; MuJoCo generates
jumps that pass PyBullet's checks; actuator effects from the description."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import h5py
import numpy as np
import pytest
from _simdata import tmp_path
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.preprocess import foot_positions_world
from symrom.robots import ActuatorEffects, get_robot
from symrom.robots.description import RobotDescriptionError, load_description
from symrom.robots.kinematics import rpy_to_matrix
from symrom.robots.stance import start_pose
from symrom.sim.diagnostics.forces import NoContactForceError, force_error
from symrom.sim.engines.registry import ENGINES, UnknownEngineError, make_world
from symrom.sim.engines.world import World, euler_rate_matrix
from symrom.sim.generation.generate import GenerateConfig, GenerationError, generate, run_record_path

STAND = np.tile([0.0, 0.8, -1.6], 4)


@pytest.fixture(params=list(ENGINES))
def engine(request):
    return request.param


def _hold_pose(world, q0, n, push=None, kp=100.0):
    """Run n ticks of a joint PD to q0's joints (and an optional base push); the last applied torque."""
    for _ in range(n):
        s = world.state()
        if push is not None:
            world.apply_base_force(push)
        applied = world.step(kp * (q0[:12] - s.q[:12]) - 2.0 * s.dq[:12])
    return applied


def test_reset_state_round_trip(engine):
    rng = np.random.default_rng(0)
    q = np.zeros(18)
    q[:12] = STAND + rng.normal(0, 0.05, 12)
    q[12:15], q[15:] = [0.1, -0.2, 0.5], [0.1, -0.2, 0.3]
    dq = rng.normal(0, 1.0, 18)
    with make_world(engine, "a1") as w:
        assert isinstance(w, World) and w.engine == engine
        w.reset(q, dq)
        s = w.state()
        np.testing.assert_allclose(s.q, q, atol=1e-6)
        np.testing.assert_allclose(s.dq, dq, atol=1e-6)
        np.testing.assert_allclose(s.R, rpy_to_matrix(q[15:])[0], atol=1e-6)
        np.testing.assert_allclose(s.omega, euler_rate_matrix(q[15:]) @ dq[15:], atol=1e-6)
        np.testing.assert_allclose(s.foot_pos, foot_positions_world("a1", q[None])[0], atol=1e-6)
        np.testing.assert_allclose(w.joint_velocities(), dq[:12], atol=1e-9)
        assert not s.contact.any()
        # every engine sees the same robot
        assert w.mass == pytest.approx(get_robot("a1").mass, rel=1e-6)
        assert w.foot_radius == pytest.approx(get_robot("a1").foot_radius)


def test_true_contact_forces_balance_weight_and_push(engine):
    """Standing still under a steady sideways push, the ground's forces on the feet carry the
    weight and cancel the push: the engine's forces have the right signs and frame."""
    push = np.array([20.0, 10.0, 0.0])
    with make_world(engine, "go1") as w:
        q0 = start_pose("go1")
        w.reset(q0)
        _hold_pose(w, q0, 1500, push)
        f = w.contact_forces()
        assert w.state().contact.all() and f.shape == (4, 3)
        np.testing.assert_allclose(f.sum(axis=0), [-20.0, -10.0, w.mass * 9.81], rtol=0.03, atol=1.0)
        w.reset(start_pose("go1") + np.r_[np.zeros(14), 0.3, np.zeros(3)])  # in the air
        w.step(np.zeros(12))
        assert not w.contact_forces().any()


def test_held_joints_stay_and_report_their_torque(engine):
    with make_world(engine, "a1") as w:
        q0 = start_pose("a1")
        w.hold_joints([0, 3, 6, 9])
        w.reset(q0)
        for _ in range(600):  # the other joints go limp; the held ones keep their angle
            applied = w.step(np.full(12, 5.0))
        s = w.state()
        assert np.abs(s.q[[0, 3, 6, 9]] - q0[[0, 3, 6, 9]]).max() < 0.02
        assert np.all(applied[[1, 2]] == 5.0)  # driven joints: the request
        assert np.all(np.abs(applied[[0, 3, 6, 9]]) <= get_robot("a1").torque_limit[0] + 1e-9)
        assert np.any(applied[[0, 3, 6, 9]] != 5.0)  # held joints: what held them


@pytest.mark.parametrize("engine, effect, value", [
    ("mujoco", "damping", 0.5), ("mujoco", "armature", 0.02), ("mujoco", "friction_loss", 1.0),
    ("pybullet", "damping", 0.5), ("pybullet", "friction_loss", 1.0)])
def test_actuator_effects_slow_a_driven_leg(engine, effect, value):
    """A thigh driven by a constant torque in the air turns slower with joint damping, armature
    or friction loss (``ActuatorEffects``, as each engine models them)."""
    q = start_pose("go1") + np.r_[np.zeros(14), 0.5, np.zeros(3)]  # well above the ground
    tau = np.zeros(12)
    tau[1] = 3.0
    speeds = []
    for effects in (ActuatorEffects(), ActuatorEffects(**{effect: (0.0, value, 0.0)})):
        with make_world(engine, "go1", effects=effects) as w:
            w.reset(q)
            for _ in range(30):
                w.step(tau)
            speeds.append(w.state().dq[1])
    assert speeds[0] > 1.0 and speeds[1] < 0.8 * speeds[0]


def test_bullet_refuses_armature_and_unknown_engines_are_named():
    with pytest.raises(ValueError, match="no armature"):
        make_world("pybullet", "go1", effects=ActuatorEffects(armature=(0.01, 0.01, 0.02)))
    with pytest.raises(UnknownEngineError, match="unknown engine 'ode'; known: pybullet, mujoco"):
        make_world("ode", "go1")
    with pytest.raises(GenerationError, match="unknown engine 'ode'"):
        generate(GenerateConfig("go1", "pronk", 1, engine="ode"), tmp_path("x.h5"))


def test_description_actuators_and_mjcf_keys(tmp_path):
    a1 = get_robot("a1").source.read_text().replace('urdf = "pybullet_data:a1/a1.urdf"',
                                                     'urdf = "pybullet_data:a1/a1.urdf"\nmjcf = "a1.xml"')
    (tmp_path / "a1.xml").write_text("<mujoco/>")
    path = tmp_path / "a1.toml"
    path.write_text(a1 + "\n[actuators]\ndamping = [0.1, 0.2, 0.3]\narmature = 0.01\n")
    d = load_description(path)
    assert d.actuators.damping == (0.1, 0.2, 0.3) * 4 and d.actuators.armature == (0.01,) * 12
    assert d.actuators.friction_loss == (0.0,) * 12  # left out: none
    assert d.mjcf_path == (tmp_path / "a1.xml").resolve()
    assert get_robot("a1").actuators.ideal and get_robot("a1").mjcf_path is None  # format 1 as before
    path.write_text(a1 + "\n[actuators]\ndamping = -1\n")
    with pytest.raises(RobotDescriptionError, match="actuators.damping"):
        load_description(path)
    path.write_text(a1.replace("a1.xml", "missing.xml"))
    with pytest.raises(RobotDescriptionError, match="'mjcf'.*no such file"):
        load_description(path)


@pytest.mark.parametrize("robot, motion", [("go1", "pronk"), ("a1", "froggy")])
def test_mujoco_generates_jumps_that_pass_the_checks(robot, motion):
    out = tmp_path(f"{robot}_{motion}_mj.h5")
    # one jump: the checks are the same for every jump, and its forces correlate as two jumps' do
    ds = generate(GenerateConfig(robot, motion, 1, seed=1, engine="mujoco", max_attempts=2), out)
    assert ds.n_jumps == 1
    assert ds.generator["engine"] == "mujoco" and ds.generator["config"]["engine"] == "mujoco"
    assert json.loads(run_record_path(out).read_text())["engine"] == "mujoco"
    z = ds.q[:, 14]
    for a, b in ds.jump_bounds():  # the common checks, as the runner applied them
        assert z[a:b].max() - z[a] > 0.05 and ds.q[b - 1, 12] - ds.q[a, 12] > 0.1
        assert (ds.contact[a:b].sum(axis=1) == 0).sum() * ds.dt >= 0.12
    assert np.all(np.abs(ds.tau) <= np.asarray(get_robot(robot).torque_limit) + 1e-9)
    with h5py.File(out) as f:
        assert "engine" in f.attrs["generator"]
    # the engine's contact forces, logged beside the torque-derived wrench
    assert ds.contact_force.shape == (ds.n_samples, 4, 3)
    assert not ds.contact_force[ds.contact.sum(axis=1) == 0].any()  # none in flight
    r = force_error(ds)
    assert r.engine == "mujoco" and r.axes["z"].corr > 0.9  # the same loading, roughly
    assert r.axes["z"].rms < 0.5 * r.weight
    res = CliRunner().invoke(app, ["forces", str(out)])
    assert res.exit_code == 0 and "Fz: RMS error" in res.output and "mujoco" in res.output
    with pytest.raises(NoContactForceError, match="contact_force"):
        force_error(replace(ds, contact_force=None))


def test_the_engine_is_part_of_the_fingerprint():
    """Parts made by another engine (or before true contact forces were logged) never resume."""
    cfg = GenerateConfig("go1", "pronk", 3)
    assert cfg.fingerprint() != "da2ee9fbcbe958d6"  # the same options' fingerprint in version 2
    assert cfg.fingerprint() != replace(cfg, engine="mujoco").fingerprint()
    assert cfg.to_dict()["engine"] == "pybullet"


def test_the_mpc_solver_is_the_engines_unless_named(tmp_path):
    """PyBullet keeps OSQP (its files bitwise as before), MuJoCo takes DAQP; a named solver wins,
    the file records the one used, and an unknown one is refused in one line before any work."""
    assert GenerateConfig("go1", "pronk", 3).mpc_solver == "osqp"
    assert GenerateConfig("go1", "pronk", 3, engine="mujoco").mpc_solver == "daqp"
    named = GenerateConfig("go1", "pronk", 3, mpc_solver="daqp")
    assert named.to_dict()["mpc_solver"] == "daqp"
    assert named.fingerprint() != GenerateConfig("go1", "pronk", 3).fingerprint()
    out = tmp_path / "bad.h5"
    res = CliRunner().invoke(app, ["generate", "--robot", "go1", "--motion", "pronk", "--jumps", "1",
                                   "--mpc-solver", "qpoases", "--out", str(out)])
    assert res.exit_code != 0 and "unknown MPC solver 'qpoases'" in res.output and not out.exists()


ROBOTS_DIR = __import__("pathlib").Path(__file__).parent / "robots"


@pytest.mark.parametrize("engine", list(ENGINES))
@pytest.mark.parametrize("robot", ["aliengo", "mini_cheetah"])
def test_pronk_on_user_written_descriptions(robot, engine):
    """Pronk scales itself to robots it was not tuned on, in both engines (one jump each)."""
    path = ROBOTS_DIR / f"{robot}.toml"
    ds = generate(GenerateConfig(str(path), "pronk", 1, seed=2, engine=engine, max_attempts=3),
                  tmp_path(f"{robot}_{engine}.h5"))
    assert ds.robot == str(path.resolve()) and ds.n_jumps == 1
    assert ds.q[:, 14].max() - ds.q[0, 14] > 0.05 and ds.q[-1, 12] - ds.q[0, 12] > 0.1


def test_froggy_scales_to_the_aliengo():
    """Unscaled, the A1's froggy thrust barely lifts the Aliengo (no flight); scaled, it jumps."""
    from symrom.sim.controllers.froggy import FroggyParams, sample_params, scales

    path = str(ROBOTS_DIR / "aliengo.toml")
    m, l = scales(path)
    p = sample_params(np.random.default_rng(0), path)
    a1 = sample_params(np.random.default_rng(0), "a1")
    assert p.stand_height == pytest.approx(FroggyParams.stand_height * l)
    assert a1.force_all * m * 0.75 < p.force_all < a1.force_all * m  # torque capacity lowers it
    assert sample_params(np.random.default_rng(0)) == a1  # the A1's own: unchanged
    ds = generate(GenerateConfig(path, "froggy", 1, seed=0, max_attempts=6), tmp_path("aliengo_froggy.h5"))
    assert (ds.contact.sum(axis=1) == 0).sum() * ds.dt >= 0.12


def test_mujoco_runs_without_pybullet():
    """The engine layer names no engine but the one asked for: a MuJoCo world steps, and a froggy
    controller (whose model of the robot needs no body source) runs on it through the episode
    loop, with PyBullet never imported. (The pronk's body model reads the URDF through PyBullet,
    on any engine: ``sim.controllers.body``.)"""
    code = """
import sys
import numpy as np
from symrom.robots.stance import start_pose
from symrom.sim.controllers.froggy import FroggyController, FroggyParams
from symrom.sim.engines.registry import make_world
from symrom.sim.generation.episode import run_episode
import symrom.sim.generation.generate, symrom.sim.diagnostics.render
world = make_world("mujoco", "go1")
world.reset(start_pose("go1"))
for _ in range(20):
    world.step(np.zeros(12))
s = world.state()
assert abs(s.t - 0.02) < 1e-12 and s.contact.all(), (s.t, s.contact)
world = make_world("mujoco", "a1")
ctrl = FroggyController("a1", FroggyParams())
end = run_episode(world, ctrl, ctrl.reset(world), 0.05)
assert end.ticks == 51 and ctrl.phase == "settle", (end, ctrl.phase)
assert "pybullet" not in sys.modules, "pybullet was imported"
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr

