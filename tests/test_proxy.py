"""The proxy's new effects reach both engines; the randomised variant is recorded and reproducible;
the sim-to-real targets are checked as stated."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from _simdata import tmp_path

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS
from symrom.robots import ActuatorEffects
from symrom.robots.kinematics import rpy_to_matrix
from symrom.sim.engines.registry import make_world
from symrom.sim.engines.world import RobotState
from symrom.sim.proxy import (
    JUMP_FIELDS,
    PROXY_RANGES,
    RANDOMIZED_RANGES,
    ROBOT_FIELDS,
    ProxyConfig,
    ProxyWorld,
    SensorModel,
    TorqueChannel,
    for_engine,
    robot_constants,
    sample_proxy,
    sample_robot,
)

ENGINES = ("pybullet", "mujoco")
KNEE = 2  # FR knee


def _spin(world, ticks: int = 40) -> float:
    """|knee rate| (rad/s) after ``ticks`` free ticks of a robot in the air whose FR knee starts
    at 8 rad/s (free fall: no gravity torque on the joints)."""
    q = world.standing_q(np.asarray(world.spec.stance_joints))
    q[BASE_POS.start + 2] += 1.0
    dq = np.zeros(18)
    dq[JOINTS.start + KNEE] = 8.0
    world.reset(q, dq)
    for _ in range(ticks):
        world.step(np.zeros(12), report=False)
    return abs(world.joint_velocities()[KNEE])


@pytest.mark.parametrize("engine", ENGINES)
def test_damping_and_friction_loss_slow_a_joint(engine):
    free = make_world(engine, "go1")
    v_free = _spin(free)
    for effects in (ActuatorEffects(damping=(0.5,) * 3), ActuatorEffects(friction_loss=(0.8,) * 3)):
        w = make_world(engine, "go1")
        w.set_actuator_effects(effects)
        assert _spin(w) < 0.8 * v_free, (engine, effects)
        w.close()
    free.close()


def test_armature_in_mujoco_refused_by_pybullet():
    def accel(effects):
        w = make_world("mujoco", "go1")
        if effects is not None:
            w.set_actuator_effects(effects)
        q = w.standing_q(np.asarray(w.spec.stance_joints))
        q[BASE_POS.start + 2] += 1.0
        w.reset(q)
        tau = np.zeros(12)
        tau[KNEE] = 5.0
        for _ in range(5):
            w.step(tau, report=False)
        return abs(w.joint_velocities()[KNEE])

    # a knee link's own inertia about its axis is ~0.005 kg m^2: 0.05 of armature slows it severalfold
    assert accel(ActuatorEffects(armature=(0.05,) * 3)) < 0.5 * accel(None)
    w = make_world("pybullet", "go1")
    with pytest.raises(ValueError, match="no armature"):
        w.set_actuator_effects(ActuatorEffects(armature=(0.01,) * 3))
    w.close()


@pytest.mark.parametrize("engine", ENGINES)
def test_soft_ground_contact_lets_the_robot_sink(engine):
    def height(soft: bool) -> float:
        w = make_world(engine, "go1")
        if soft:
            w.set_ground_contact(5e3, 300.0)
        w.hold_joints(list(range(12)))
        w.reset(w.standing_q(np.asarray(w.spec.stance_joints)))
        for _ in range(500):
            w.step(np.zeros(12), report=False)
        z = w.state().q[BASE_POS][2]
        w.close()
        return z

    # ~31 N per foot at 5 kN/m: 6 mm lower than on the rigid ground in PyBullet; MuJoCo's
    # regularised contact sinks less than its spring says (2.5 mm measured)
    assert height(True) < height(False) - 0.0015
    w = make_world(engine, "go1")
    with pytest.raises(ValueError, match="stiffness > 0"):
        w.set_ground_contact(-1.0, 10.0)
    w.close()


@pytest.mark.parametrize("engine", ENGINES)
def test_measured_and_commanded_torque_logs(engine):
    tau = np.linspace(-3.0, 3.0, 12)  # far below the limits: nothing saturates
    bias = (0.2, -0.1, 0.3)
    cfg = ProxyConfig(torque_log="measured", torque_bias=bias, torque_scale=0.9)
    w = ProxyWorld(make_world(engine, "go1"), cfg)
    w.reset(w.standing_q(np.asarray(w.spec.stance_joints)))
    logged = w.step(tau)
    np.testing.assert_allclose(logged, np.tile(bias, 4) + 0.9 * tau, rtol=0, atol=1e-12)
    assert np.all(w.logged_torque_bound >= w.torque_limit * 0.9)
    w.close()
    # commanded: the request itself, although latency holds it back from the joints
    w = ProxyWorld(make_world(engine, "go1"), ProxyConfig(torque_log="commanded", latency=0.004))
    w.reset(w.standing_q(np.asarray(w.spec.stance_joints)))
    np.testing.assert_allclose(w.step(tau), tau)
    assert np.all(w.motors.buffer[-1] == tau) and not np.any(w.motors.buffer[0])  # still on its way
    w.close()
    with pytest.raises(ValueError, match="torque_log"):
        ProxyConfig(torque_log="exact")


def _readings_one_by_one(cfg: ProxyConfig, rng: np.random.Generator, state: RobotState) -> RobotState:
    """The sensor model written reading by reading: one normal draw per reading."""
    c, n = cfg, rng.normal
    q, dq = state.q.copy(), state.dq.copy()
    drift = np.array([c.drift_vel[0] * state.t, c.drift_vel[1] * state.t, 0.0])
    q[JOINTS] += n(0.0, c.noise_q, N_JOINTS)
    dq[JOINTS] += n(0.0, c.noise_dq, N_JOINTS)
    q[BASE_POS] += drift + n(0.0, c.noise_pos, 3)
    q[BASE_RPY] += n(0.0, c.noise_rpy, 3) + np.array([0.0, 0.0, c.drift_yaw_rate * state.t])
    dq[BASE_POS] += n(0.0, c.noise_vel, 3) + np.array([*c.drift_vel, 0.0])
    dq[BASE_RPY] += n(0.0, c.noise_omega, 3)
    R = rpy_to_matrix(q[BASE_RPY])[0]
    omega = state.omega + n(0.0, c.noise_omega, 3)
    return RobotState(t=state.t, q=q, dq=dq, omega=omega, R=R, contact=state.contact,
                      foot_pos=state.foot_pos + drift + n(0.0, c.noise_pos, (4, 3)),
                      foot_vel=state.foot_vel + n(0.0, c.noise_vel, (4, 3)))


@pytest.mark.parametrize("ranges, distinct", [(PROXY_RANGES, False), (RANDOMIZED_RANGES, True), (None, False)])
def test_readings_are_the_one_by_one_draws_bit_for_bit(ranges, distinct):
    """The sensor model draws every reading's noise in one call per tick; the readings are those
    of one draw per reading, to the last bit (a dataset does not change with the speed-up), over
    many ticks of one stream; the torque channel's limit is the clipped line it states, and the
    torque it delivers NumPy's clip to it, bit for bit (signed zeros and NaN included)."""
    rng = np.random.default_rng(7)
    cfg = ProxyConfig(seed=11) if ranges is None else sample_proxy(rng, ranges)
    now = TorqueChannel(replace(cfg, latency=0.0), np.full(12, 30.0), 0.001)  # no delay: apply's clip
    if distinct:  # every reading's own deviation, so that a reading given another's noise shows
        cfg = replace(cfg, noise_q=0.001, noise_dq=0.03, noise_pos=0.002, noise_rpy=0.005, noise_vel=0.02,
                      noise_omega=0.04)
    model, reference = SensorModel(cfg), np.random.default_rng(cfg.seed)
    motors = TorqueChannel(cfg, np.full(12, 30.0), 0.001)
    w0 = np.tile(cfg.no_load_speed, 4)
    for tick in range(300):
        state = RobotState(t=0.001 * tick, q=rng.normal(0.0, 0.5, 18), dq=rng.normal(0.0, 3.0, 18),
                           omega=rng.normal(0.0, 2.0, 3), R=np.eye(3), contact=np.array([1, 0, 1, 1], np.uint8),
                           foot_pos=rng.normal(0.0, 0.3, (4, 3)), foot_vel=rng.normal(0.0, 1.0, (4, 3)))
        got, want = model.corrupt(state), _readings_one_by_one(cfg, reference, state)
        for field in ("q", "dq", "omega", "R", "foot_pos", "foot_vel"):
            a, b = getattr(got, field), getattr(want, field)
            assert a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64)), (tick, field)
        assert got.t == state.t and got.contact is state.contact
        tau, v = rng.normal(0.0, 40.0, 12), rng.uniform(-1.2, 1.2, 12) * w0
        if tick % 3 == 0:  # signed zeros, speeds at the no-load speed and past it, NaN
            tau[:4], v[4:8], v[8] = (0.0, -0.0, 31.0, -31.0), (w0[4], -w0[5], 0.0, -0.0), np.nan
            tau[9] = np.nan
        frac = np.clip((w0 - np.abs(v)) / (w0 - cfg.knee_speed_frac * w0), 0.0, 1.0)
        limit = np.where(np.sign(tau) == np.sign(v), 30.0 * frac, 30.0)
        assert np.array_equal(motors.available(tau, v), limit, equal_nan=True)
        clipped = np.clip(tau, -limit, limit)
        assert np.array_equal(now.apply(tau, v).view(np.uint64), clipped.view(np.uint64)), tick


def test_ranges_and_engines():
    rng = np.random.default_rng(0)
    for ranges in (PROXY_RANGES, RANDOMIZED_RANGES):
        for _ in range(20):
            c = sample_proxy(rng, ranges)
            for name in ("damping", "armature", "friction_loss", "torque_bias"):
                lo, hi = getattr(ranges, name)
                assert all(lo <= v <= hi for v in getattr(c, name)), name
            assert ranges.contact_stiffness[0] <= c.contact_stiffness <= ranges.contact_stiffness[1]
            assert ranges.friction[0] <= c.friction <= ranges.friction[1]
    # the randomised source covers the proxy target's ranges on every side
    for name in ("trunk_mass_scale", "leg_mass_scale", "inertia_scale", "friction", "latency", "damping",
                 "armature", "friction_loss", "contact_stiffness", "contact_damping", "torque_bias", "torque_scale"):
        (lo, hi), (rlo, rhi) = getattr(PROXY_RANGES, name), getattr(RANDOMIZED_RANGES, name)
        assert rlo <= lo and hi <= rhi, name
    c = sample_proxy(np.random.default_rng(1))
    assert any(c.armature) and not any(for_engine(c, "pybullet").armature)
    assert for_engine(c, "mujoco") == c
    assert ProxyConfig().effects.ideal  # the default is the nominal world


def test_randomized_variant_recorded_and_reproducible():
    from symrom.data.io import read_dataset
    from symrom.sim.generation.generate import GenerateConfig, GenerationError, generate

    cfg = GenerateConfig("go1", "pronk", 2, seed=3, randomize=True, splits=(1, 0, 1))
    a = generate(cfg, tmp_path("rand_a.h5"))
    out = tmp_path("rand_b.h5")
    generate(cfg, out)
    b = read_dataset(out)  # as written
    assert a.generator["config"]["randomize"] is True and a.source == "sim"
    jumps = a.generator["jumps"]
    for rec in jumps:
        p = rec["params"]
        assert p["randomized"] is True and p["proxy"]["torque_log"] == "measured"
        assert p["proxy"]["armature"] == [0.0, 0.0, 0.0]  # PyBullet: none, and the record says so
        assert p["proxy"]["contact_stiffness"] is not None
    assert jumps[0]["params"]["pitch"] != jumps[1]["params"]["pitch"]
    assert list(a.split) == ["train", "test"] and a.generator["splits"] == {"train": 1, "val": 0, "test": 1}
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.tau, b.tau)
    with pytest.raises(GenerationError, match=r"splits \(1, 1, 1\) must be three jump counts"):
        generate(replace(cfg, splits=(1, 1, 1)), tmp_path("rand_s.h5"))
    with pytest.raises(GenerationError, match="choose one"):
        generate(replace(cfg, proxy=True), tmp_path("rand_c.h5"), force=True)
    # froggy's randomised jumps vary the length of the rear-only phase: a quick push and a real
    # froggy's long one (each kind's ranges covering the hardware-like froggy's on every side)
    from symrom.sim.controllers.froggy import MOTION as FROGGY
    from symrom.sim.controllers.froggy import RANDOMIZED_LONG, RANDOMIZED_QUICK, REAL_MOTION, FroggyParams, FroggyRanges

    nominal, drawn = FroggyParams(), FroggyRanges().draw(np.random.default_rng(0))
    assert all(getattr(drawn, f) == pytest.approx(getattr(nominal, f)) for f in nominal.__dataclass_fields__
               if f != "proxy")
    for f in REAL_MOTION.__dataclass_fields__:
        (lo, hi), (wlo, whi) = getattr(REAL_MOTION, f), getattr(RANDOMIZED_LONG, f)
        assert wlo <= lo and hi <= whi, f
    rear = [FROGGY.sample_params(np.random.default_rng(s), "a1", "randomized") for s in range(16)]
    assert all(p.randomized and p.proxy is not None for p in rear)
    quick = [p.t_push_rear for p in rear if p.t_push_rear <= RANDOMIZED_QUICK.t_push_rear[1]]
    long = [p.t_push_rear for p in rear if p.t_push_rear >= RANDOMIZED_LONG.t_push_rear[0]]
    assert len(quick) + len(long) == len(rear) and len(quick) >= 4 and len(long) >= 4
    real = FROGGY.sample_params(np.random.default_rng(1), "a1", "proxy", np.random.default_rng(2))
    assert not real.randomized and real.proxy.torque_log == "measured" and FROGGY.source(real) == "proxy"
    assert REAL_MOTION.t_push_rear[0] <= real.t_push_rear <= REAL_MOTION.t_push_rear[1]


def test_proxy_is_one_robot_per_dataset():
    """The proxy target's hardware constants are drawn once from the generation seed (the same in
    every jump and recorded once); ground friction, latency, noise and drift vary per jump; the
    randomised source still draws its hardware per jump."""
    from symrom.sim.generation.generate import GenerateConfig, generate
    from symrom.sim.generation.runner import dataset_seed

    assert set(ROBOT_FIELDS).isdisjoint(JUMP_FIELDS)
    assert set(ROBOT_FIELDS) | set(JUMP_FIELDS) == set(ProxyConfig.__dataclass_fields__)
    robot = sample_robot(np.random.default_rng(5))
    rng = np.random.default_rng(6)
    jumps = [sample_proxy(rng, robot=robot) for _ in range(3)]
    assert all(robot_constants(c) == robot_constants(robot) for c in jumps)
    assert len({c.friction for c in jumps}) == 3 and len({c.seed for c in jumps}) == 3
    free = [sample_proxy(rng) for _ in range(2)]  # without a robot: hardware per jump
    assert free[0].damping != free[1].damping and free[0].torque_bias != free[1].torque_bias

    ds = generate(GenerateConfig("go1", "pronk", 2, seed=4, proxy=True, splits=(1, 0, 1)), tmp_path("one_robot.h5"))
    recs = [r["params"]["proxy"] for r in ds.generator["jumps"]]
    expected = robot_constants(for_engine(sample_robot(np.random.default_rng(dataset_seed(4))), "pybullet"))
    assert ds.generator["proxy_robot"] == expected
    assert all({f: r[f] for f in ROBOT_FIELDS} == expected for r in recs)
    assert recs[0]["friction"] != recs[1]["friction"] and recs[0]["seed"] != recs[1]["seed"]
    other = sample_robot(np.random.default_rng(dataset_seed(5)))  # another seed: another robot
    assert robot_constants(other)["torque_bias"] != expected["torque_bias"]


def test_sim2real_checks():
    from symrom.experiments.reproduce import sim2real_checks

    def col(x, z, ratio=1.0, diverged=0):
        return {"x_rmse": x, "z_rmse": z, "diverged_jumps": diverged, "flight_ratio": ratio}

    good = {"source": col(0.1, 0.12), "fine_tuned": col(0.03, 0.04, 1.03), "target_alone": col(0.03, 0.035)}
    c = sim2real_checks(good)
    assert c["source_z"] and c["fine_tuned_z"] and c["not_above_source"] and c["flight_gravity"]
    assert c["vs_target_alone"] and c["scratch_ratio_z"] == pytest.approx(0.04 / 0.035)
    assert c["scratch_ratio_x"] == pytest.approx(1.0)
    bad = {**good, "fine_tuned": col(0.03, 0.06, 1.07), "source": col(0.1, 0.05)}
    c = sim2real_checks(bad)
    assert not (c["fine_tuned_z"] or c["not_above_source"] or c["flight_gravity"] or c["vs_target_alone"])
    c = sim2real_checks({**good, "fine_tuned": col(0.1, 0.03)})  # z fine, x 3.3x the target-alone's
    assert c["fine_tuned_z"] and not c["vs_target_alone"]
    c = sim2real_checks({**good, "source": col(0.1, 0.12, diverged=1)})
    assert c["source_z"] is None and c["not_above_source"] is None  # a diverged column is not a number
