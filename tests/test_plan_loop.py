"""The closed loop's re-planning (``plan.replan``) on planted models: it lands a disturbed system
that the open-loop plan misses, re-plans within its time budget, and keeps the plan when nothing
is disturbed; the froggy's two-stance problem; disturbances on both engines."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import one_line_error
from test_plan import DAMP_X, G_C, GAIN_X, GAIN_Z, PLANTED, X, Z, planted_model

from symrom.plan.dynamics import GRAVITY, LearnedDynamics
from symrom.plan.problem import JumpPlanner, Release, Stance
from symrom.plan.replan import Replanner

Z_LO = 0.33


def _fly(s: np.ndarray, z_td: float = Z_LO) -> float:
    """x where the ballistic flight from s = [x, z, vx, vz] comes down through z_td."""
    x, z, vx, vz = s
    t = (vz + np.sqrt(vz ** 2 + 2 * GRAVITY * (z - z_td))) / GRAVITY
    return float(x + vx * t)


def _run(force_at, end_at, gain_scale: float, replan=None, period: float = 0.01, dt: float = 1e-4,
         offset: tuple[float, float] = (0.0, 0.0)):
    """Integrate the planted contact law with its force gains times ``gain_scale`` and an
    acceleration ``offset`` (x, z) m/s² added (the world differs from the model) under the force
    F(tau), to the push's end; with ``replan(s, tau)`` called every ``period`` s from the measured
    state. Returns the landing x and the re-plans."""
    s = np.array([0.5, 0.21, 0.0, 0.0])
    tau, last, n = 0.0, 0.0, 0
    while tau < end_at():
        if replan is not None and tau - last >= period - 1e-12 and tau > 0:
            replan(s.copy(), tau)
            last, n = tau, n + 1
        Fx, Fz = force_at(tau)

        def f(v, Fx=Fx, Fz=Fz):
            return np.array([v[2], v[3], gain_scale * GAIN_X * Fx + DAMP_X * v[2] + offset[0],
                             gain_scale * GAIN_Z * Fz + G_C + offset[1]])

        k1 = f(s)
        k2 = f(s + dt / 2 * k1)
        k3 = f(s + dt / 2 * k2)
        k4 = f(s + dt * k3)
        s = s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        tau += dt
    return _fly(s) - 0.5, n


@pytest.fixture(scope="module")
def planted_nlp():
    dyn = LearnedDynamics(PLANTED, np.eye(2))  # nu = F
    return JumpPlanner(dyn, mass=13.0)


def _plan(nlp, target):
    q0 = np.zeros(18)
    q0[X], q0[Z] = 0.5, 0.21
    s0 = nlp.dyn.initial_state(q0, np.zeros(18))
    plan = nlp.solve(s0, target, z_liftoff=Z_LO, min_apex=0.43, warm=False)
    assert plan.success, plan.status
    return plan


@pytest.mark.parametrize("scale", [0.93, 1.1])
def test_replanning_lands_a_disturbed_system_the_plan_misses(planted_nlp, scale):
    target = 0.3
    plan = _plan(planted_nlp, target)
    # open loop: the plan's forces on a world whose force gains are off by ``scale``
    open_x, _ = _run(plan.force_at, lambda: plan.t_stance, scale)
    assert abs(open_x - target) > 0.01
    rp = Replanner(planted_nlp)
    rp.begin(plan, target, plan.x0, Z_LO, Z_LO, None, 0.43)
    closed_x, n = _run(lambda tau: rp.schedule.force_at(tau), lambda: rp.schedule.end, scale,
                       replan=lambda s, tau: rp.step(s, tau))
    assert n >= 10 and len(rp.stats.solve_time_s) == n
    # every QP solved; at the very end of the push the guards may only be met as closely as can be
    assert all(st in ("ok", "softened") for st in rp.stats.status) and rp.stats.status[:-2].count("ok") == n - 2
    assert abs(closed_x - target) < 0.2 * abs(open_x - target)
    assert abs(closed_x - target) < 4e-3
    # every schedule keeps the force within the friction pyramid and its bounds
    for F in rp.schedule.forces:
        assert np.all(F[:, 1] >= -1e-6) and np.all(np.abs(F[:, 0]) <= 0.6 * F[:, 1] + 1e-6)


def test_replanning_keeps_the_plan_when_nothing_is_disturbed(planted_nlp):
    target = 0.25
    plan = _plan(planted_nlp, target)
    rp = Replanner(planted_nlp)
    rp.begin(plan, target, plan.x0, Z_LO, Z_LO, None, 0.43)
    x, _ = _run(lambda tau: rp.schedule.force_at(tau), lambda: rp.schedule.end, 1.0,
                replan=lambda s, tau: rp.step(s, tau))
    assert abs(x - target) < 2e-3
    assert np.allclose(rp.stats.landing_x, target, atol=2e-3)  # each re-plan still predicts the target


def test_a_release_after_the_push_is_planned_and_replanned(planted_nlp):
    """A world whose feet leave only after a release (10 ms under a fixed pull, as a pronk's held
    legs read in its data): a plan that carries the release (``Release``) lands there open loop, its
    re-plans each predict the target, and its closed loop lands too; the plan without the release
    lifts off at the height the world's release begins at and lands short."""
    release = Release(0.01, (10.0, -60.0))
    nlp = JumpPlanner(LearnedDynamics(PLANTED, np.eye(2)), mass=13.0, release=release)
    target = 0.3

    def world(force_at, end_at, replan=None):
        return _run(lambda tau: force_at(tau) if tau < end_at() else np.array(release.force),
                    lambda: end_at() + release.duration, 1.0, replan=replan)

    plan = _plan(nlp, target)
    x, _ = world(plan.force_at, lambda: plan.t_stance)
    assert abs(x - target) < 2e-3
    rp = Replanner(nlp)
    rp.begin(plan, target, plan.x0, Z_LO, Z_LO, None, 0.43)
    x, n = world(lambda tau: rp.schedule.force_at(tau), lambda: rp.schedule.end,
                 replan=lambda s, tau: rp.step(s, tau) if tau < rp.schedule.end else None)
    assert n >= 10 and abs(x - target) < 2e-3
    assert np.allclose(rp.stats.landing_x, target, atol=2e-3)
    unaware = _plan(planted_nlp, target)
    x, _ = world(unaware.force_at, lambda: unaware.t_stance)
    assert x - target < -0.005


def test_the_disturbance_estimate_takes_up_what_the_model_lacks():
    """A world with an acceleration the model lacks (a drag and a load, through the push and the
    release after it, which no re-plan can correct): re-planned with the disturbance estimate the
    jump lands on the target and the estimate finds the planted acceleration; without it, the last
    10 ms of the push and the release carry the world's error into the landing."""
    release = Release(0.01, (10.0, -60.0))
    nlp = JumpPlanner(LearnedDynamics(PLANTED, np.eye(2)), mass=13.0, release=release)
    target, offset = 0.3, (-1.0, -3.0)
    plan = _plan(nlp, target)
    errors = {}
    for gain in (0.0, 0.5):
        rp = Replanner(nlp, disturbance_gain=gain)
        rp.begin(plan, target, plan.x0, Z_LO, Z_LO, None, 0.43)
        x, n = _run(lambda tau: rp.schedule.force_at(tau) if tau < rp.schedule.end else np.array(release.force),
                    lambda: rp.schedule.end + release.duration, 1.0, offset=offset,
                    replan=lambda s, tau: rp.step(s, tau) if tau < rp.schedule.end else None)
        errors[gain] = abs(x - target)
        assert n >= 10
    assert rp.disturbance == pytest.approx(offset, abs=0.05)  # the latents read x and z: the same units
    assert errors[0.0] > 4e-3 and errors[0.5] < 0.2 * errors[0.0]
    with pytest.raises(ValueError, match=r"disturbance_gain must lie in \[0, 1\]"):
        Replanner(nlp, disturbance_gain=1.5)


def test_replan_is_fast(planted_nlp):
    """A re-plan (linearisation, QP, update) takes well under the 10 ms between re-plans."""
    plan = _plan(planted_nlp, 0.3)
    rp = Replanner(planted_nlp)
    rp.begin(plan, 0.3, plan.x0, Z_LO, Z_LO, None, 0.43)
    s = plan.states[2]
    for k in range(20):
        rp.step(s, 0.01 + 1e-4 * k)
    assert np.median(rp.stats.solve_time_s[1:]) < 5e-3


def test_two_stances_plan_and_replan():
    """A push on four feet then on the rear feet alone, each with its own law (the partial
    phase's force gain half the contact's): the plan keeps each part within its bounds and
    lands on the target; the model's own rollout of the plan lands there too."""
    contact = [{"nu1": GAIN_X, "dxi1": DAMP_X}, {"nu2": GAIN_Z, "1": G_C}]
    partial = [{"nu1": GAIN_X / 2}, {"nu2": GAIN_Z / 2, "1": G_C}]
    model = planted_model(contact, [{}, {"1": -GRAVITY}], phases=("contact", "partial", "flight"), third=partial)
    dyn = LearnedDynamics(model, {"contact": np.eye(2), "partial": np.eye(2)})
    stances = (Stance("contact", 3, 0.05, 0.15), Stance("partial", 3, 0.04, 0.10))
    nlp = JumpPlanner(dyn, mass=13.0, stances=stances)
    q0 = np.zeros(18)
    q0[Z] = 0.21
    s0 = dyn.initial_state(q0, np.zeros(18))
    plan = nlp.solve(s0, 0.3, z_liftoff=Z_LO, min_apex=0.43, z_touchdown=0.30)
    assert plan.success, plan.status
    assert 0.05 - 1e-9 <= plan.durations[0] <= 0.15 + 1e-9 and 0.04 - 1e-9 <= plan.durations[1] <= 0.10 + 1e-9
    assert plan.phase_at(plan.durations[0] - 1e-6) == 0 and plan.phase_at(plan.durations[0] + 1e-6) == 1
    # roll the plan out by hand: contact law, then the partial law, then ballistic to z = 0.30
    s, dt = np.array([0.0, 0.21, 0.0, 0.0]), 1e-5
    for tau in np.arange(0.0, plan.t_stance, dt):
        Fx, Fz = plan.force_at(tau)
        g = 1.0 if plan.phase_at(tau) == 0 else 0.5
        a = np.array([g * GAIN_X * Fx + (DAMP_X * s[2] if g == 1.0 else 0.0), g * GAIN_Z * Fz + G_C])
        s = s + dt * np.array([s[2], s[3], *a])
    assert s[1] == pytest.approx(Z_LO, abs=2e-3)
    assert _fly(s, 0.30) == pytest.approx(0.3, abs=4e-3)
    # the re-planner runs through the switch from one stance to the next
    rp = Replanner(nlp)
    rp.begin(plan, 0.3, plan.x0, Z_LO, 0.30, None, 0.43)
    for tau in np.arange(0.01, plan.t_stance, 0.01):
        k = min(int(tau / plan.t_stance * (len(plan.states) - 5)), len(plan.states) - 6)
        rp.step(plan.states[k + 1], tau)
    assert rp.schedule.first == 1 and all(st in ("ok", "softened") for st in rp.stats.status)


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_disturbances_change_the_world(engine):
    from symrom.robots.stance import start_pose
    from symrom.sim.engines.registry import make_world
    from symrom.sim.engines.world import WorldConfig
    from symrom.sim.proxy import Disturbances, DisturbedWorld

    q0 = start_pose("go1")

    def standing(d):
        """Stand 0.5 s under a joint PD: the summed vertical ground force at the end, the
        torques applied at the last tick for the PD's command, the world's mass."""
        w = make_world(engine, "go1", WorldConfig())
        w = DisturbedWorld(w, d) if d is not None else w
        try:
            w.reset(q0)
            for _ in range(500):
                s = w.state()
                tau = 60.0 * (q0[:12] - s.q[:12]) - 2.0 * s.dq[:12]
                applied = w.step(tau)
            return w.contact_forces().sum(axis=0)[2], tau, applied, w.mass
        finally:
            w.close()

    fz0, _, _, m0 = standing(None)
    fz1, _, _, m1 = standing(Disturbances(payload=2.0))
    assert m1 == m0  # the controller's mass stays the nominal one
    assert fz0 == pytest.approx(m0 * 9.81, rel=0.05)
    assert fz1 - fz0 == pytest.approx(2.0 * 9.81, rel=0.1)  # the ground carries the load
    _, tau, applied, _ = standing(Disturbances(motor_scale=0.85))
    assert applied == pytest.approx(0.85 * tau)
    with pytest.raises(ValueError, match="motor_scale"):
        Disturbances(motor_scale=0.0)


def test_jump_cli_closed_loop_under_a_payload(tmp_path):
    """``symrom jump --control mpc --payload``: the closed loop lands a loaded Go1 whose open-loop
    plan hardly lifts it (the base never rises above its lift-off height, the feet barely leave
    the ground and come down far short), and landing.json records the control, the disturbances
    and every re-plan's solve time."""
    import json

    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.model.persistence import save_model

    save_model(planted_model([{"nu1": 0.062, "nu2": -0.0075}, {"nu2": 0.085, "1": -9.68}], [{}, {"1": -10.2}]),
               tmp_path / "model.json")
    args = ["jump", str(tmp_path / "model.json"), "--target-x", "0.3", "--engine", "mujoco", "--payload", "2.6",
            "--no-trajectory"]
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "open")])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "open" / "landing.json").read_text())
    assert d["control"] == "plan" and d["apex_z"] < 0.33 and d["error_x"] < -0.1
    res = CliRunner().invoke(app, [*args, "--control", "mpc", "--out", str(tmp_path / "mpc")])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "mpc" / "landing.json").read_text())
    assert d["control"] == "mpc" and d["disturbances"]["payload_kg"] == 2.6 and d["motion"] == "pronk"
    assert abs(d["error_x"]) < 0.04
    r = d["replans"]
    assert r["rate_hz"] == 100.0 and r["count"] == len(r["solve_time_s"]) == len(r["t_s"]) >= 10
    assert np.allclose(np.diff(r["t_s"]), 0.01, atol=1.5e-3)  # every 10 ms of the push
    assert 0 < r["solve_time_median_s"] < 0.01
    assert r["disturbance_gain"] == 0.0 and r["disturbance"] == [[0.0, 0.0]] * r["count"]
    # with the disturbance estimate: the load reads as a downward acceleration the model lacks
    res = CliRunner().invoke(app, [*args, "--control", "mpc", "--disturbance-gain", "1", "--out", str(tmp_path / "d")])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "d" / "landing.json").read_text())
    r = d["replans"]
    assert r["disturbance_gain"] == 1.0 and len(r["disturbance"]) == r["count"] and abs(d["error_x"]) < 0.04
    assert r["disturbance"][-1][1] < -0.5  # m/s², on the latent that reads the base's height
    one_line_error(CliRunner().invoke(app, [*args, "--disturbance-gain", "1", "--out", str(tmp_path / "x")]),
                   "needs control 'mpc', not 'plan'")
    one_line_error(CliRunner().invoke(app, [*args, "--control", "mpc", "--disturbance-gain", "2",
                                            "--out", str(tmp_path / "x")]), "must lie in [0, 1], got 2")
    assert not (tmp_path / "x").exists()


def test_a_faster_closed_loop_records_its_own_rate(tmp_path):
    """``symrom jump --control mpc --replan-hz 200`` re-plans every 5 ms, and landing.json says
    200 Hz; a rate below 100 Hz is refused in one line and nothing is written."""
    import json

    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.model.persistence import save_model

    save_model(planted_model([{"nu1": 0.062, "nu2": -0.0075}, {"nu2": 0.085, "1": -9.68}], [{}, {"1": -10.2}]),
               tmp_path / "model.json")
    args = ["jump", str(tmp_path / "model.json"), "--target-x", "0.25", "--engine", "mujoco", "--control", "mpc",
            "--no-trajectory"]
    res = CliRunner().invoke(app, [*args, "--replan-hz", "50", "--out", str(tmp_path / "slow")])
    assert res.exit_code != 0 and "100 Hz or faster, got 50" in res.output and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "slow").exists()
    res = CliRunner().invoke(app, [*args, "--replan-hz", "200", "--out", str(tmp_path / "fast")])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "fast" / "landing.json").read_text())["replans"]
    assert d["rate_hz"] == 200.0 and d["count"] >= 20
    assert np.allclose(np.diff(d["t_s"]), 0.005, atol=1.5e-3)


def test_froggy_jump_end_to_end(tmp_path):
    """A froggy model (Newton's law on the A1's mass in each phase) plans four feet then the rear
    feet alone and the A1 executes it: the rear feet push alone before the flight, it lands."""
    import json

    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.model.persistence import save_model

    m = 1 / 12.5
    law = [{"nu1": m}, {"nu2": m, "1": -9.81}]
    model = planted_model(law, [{}, {"1": -9.81}], phases=("contact", "partial", "flight"), third=law,
                          info={"robot": "a1", "motion": "froggy"})
    save_model(model, tmp_path / "model.json")
    out = tmp_path / "frog"
    res = CliRunner().invoke(app, ["jump", str(tmp_path / "model.json"), "--robot", "a1", "--target-x", "0.35",
                                   "--control", "mpc", "--out", str(out)])
    assert res.exit_code == 0, res.output
    d = json.loads((out / "landing.json").read_text())
    assert d["motion"] == "froggy" and [s["phase"] for s in d["plan"]["stances"]] == ["contact", "partial"]
    assert d["landing_x"] > 0.1 and d["replans"]["count"] >= 10
    tr = json.loads((out / "trajectory.json").read_text())
    c = np.asarray(tr["contact"])
    first_air = int(np.flatnonzero(c.sum(axis=1) == 0)[0])
    before = c[first_air - 10:first_air]  # the 20 ms before the flight: the rear feet alone
    assert np.all(before[:, :2] == 0) and np.all(before[:, 2:].sum(axis=1) > 0)
    phases = tr["phase"]
    assert "push_all" in phases and "push_rear" in phases and phases[-1] == "land"
    # this planted law is free of the rear push's pitching moment: the trunk spins in flight and
    # lands upside down, which landing.json and the command's warning say
    assert not d["upright"]
    assert "fell after landing" in res.output


@pytest.mark.parametrize(("end", "upright"), [((0.29, 0.0, 0.03), True), ((0.08, np.pi, -0.18), False),
                                              ((0.25, 0.0, 1.2), False), ((0.27, 0.0, -0.45), False),
                                              ((0.12, 0.0, 0.0), False)])
def test_upright_reads_roll_pitch_and_height_at_the_end(end, upright):
    """An executed jump ended upright only on its feet: not pitched over (nose or tail), not
    upside down (roll pi, pitch near 0: the pitch alone would pass it), not lying low."""
    from symrom.plan.execute import Execution

    base = np.zeros((3, 6))
    base[:, 2] = 0.29  # standing when the run began
    base[-1, 2], base[-1, 3], base[-1, 4] = end
    ex = Execution(0.3, 0.4, 0.3, 1.0, 1.3, True, None, np.zeros(4), trajectory={"base": base})
    assert ex.upright is upright
    assert ex.rest == {"z": end[0], "roll": end[1], "pitch": end[2]}


def test_a_pitch_blind_model_keeps_the_rear_push_s_pitching_moment_to_its_data():
    """A froggy model whose latents read base x and z only (Newton's law on the A1's mass) plans
    the rear feet's push within the pitching moment its training pushes made (``push_wrench``),
    in the plan and in every re-plan; without that record, or for a model that reads the pitch,
    the rear push is planned free of it (and here leaves it)."""
    from dataclasses import replace

    from symrom.model.autoencoder import LinearAutoencoder
    from symrom.plan.inputs import holds_pitch, pitch_moment_map
    from symrom.plan.jump import make_planner, reads_pitch

    assert holds_pitch((0, 1, 2, 3)) and not holds_pitch((2, 3)) and not holds_pitch((0, 1))
    m = 1 / 12.5
    law = [{"nu1": m}, {"nu2": m, "1": -9.81}]
    low, high = 1.0, 4.0  # N m: the rear pushes' pitching moment in the training data
    envelope = {"jumps": 9, "travel_x_m": [0.25, 0.45], "apex_z_m": [0.33, 0.45], "liftoff_z_m": 0.325,
                "touchdown_z_m": 0.29, "push_s": [0.15, 0.2],
                "push_wrench": {"components": ["fx", "fz", "my"],
                                "phases": {"contact": {"min": [0.0, 0.0, -50.0], "max": [300.0, 400.0, 50.0]},
                                           "partial": {"min": [-80.0, -80.0, low], "max": [150.0, 200.0, high]}}}}
    model = planted_model(law, [{}, {"1": -9.81}], phases=("contact", "partial", "flight"), third=law,
                          info={"robot": "a1", "motion": "froggy", "envelope": envelope})
    assert not reads_pitch(model)

    def rear_moments(planner, target=0.35):
        mp = planner.motion
        plan, *_ = planner_plan(planner, target)
        k0 = mp.stances[0].knots
        M = pitch_moment_map("a1", [mp.q_crouch], (2, 3))[0]
        return plan, plan.forces[k0:] @ M

    def planner_plan(planner, target):
        from symrom.plan.jump import plan_jump

        return plan_jump(planner, planner.motion.q_crouch, np.zeros(18), target)

    bounded = make_planner("learned", "a1", model=model)
    plan, moments = rear_moments(bounded)
    assert plan.success and moments.min() >= low - 1e-6 and moments.max() <= high + 1e-6
    rp = bounded.replanner
    rp.begin(plan, 0.35, plan.x0, bounded.liftoff_height, bounded.touchdown_height, None, bounded.nominal_apex)
    M = pitch_moment_map("a1", [bounded.motion.q_crouch], (2, 3))[0]
    checked = 0
    for tau in np.arange(0.01, plan.t_stance, 0.01):
        k = min(int(tau / plan.t_stance * (len(plan.states) - 5)), len(plan.states) - 6)
        s = plan.states[k + 1].copy()
        s[3] *= 0.98  # rising slower than planned: the re-plan pushes harder
        sch = rp.step(s, tau)
        for i, F in enumerate(sch.forces):
            if sch.first + i == 1 and rp.stats.status[-1] == "ok":  # a softened QP has every bound soft
                assert (F @ M).max() <= high + 1e-6 and (F @ M).min() >= low - 1e-6
                checked += 1
    assert checked >= 5 and rp.schedule.first == 1
    # free of it: no record, or latents that read the pitch
    no_record = replace(model, provenance=replace(model.provenance, data=replace(
        model.provenance.data, envelope={k: v for k, v in envelope.items() if k != "push_wrench"})))
    W_e = model.autoencoder.W_e.copy()
    W_e[1, 16] = 1e-3  # the second latent weighs the pitch a little
    ae = model.autoencoder
    reading = replace(model, autoencoder=LinearAutoencoder(W_e, ae.B_e, ae.W_d, ae.B_d))
    assert reads_pitch(reading)
    for free in (no_record, reading):
        plan, moments = rear_moments(make_planner("learned", "a1", model=free))
        assert plan.success and moments.max() > high + 1.0


def test_a_planned_pronk_hands_over_to_its_flight_as_its_own_push_does():
    """The pronk's own push ends its ground force about ``release_time`` before its flight, and
    its feet leave the ground in between; a planned push is followed by the same hold, so the
    flight's joint PD starts with the feet already off the ground (started at the push's end, it
    would swing the legs to the landing posture while the feet are still down)."""
    from symrom.plan.jump import jump, make_planner
    from symrom.sim.controllers.pronk import PronkGains, release_time

    ex = jump(make_planner("point-mass", "go1"), 0.2, engine="mujoco").execution
    t, contact = ex.trajectory["t"], ex.trajectory["contact"]
    phase = np.asarray(ex.trajectory["phase"])
    t_end = ex.t_push + ex.push_s
    first = np.flatnonzero(phase == "flight")[0]
    assert release_time(PronkGains()) == pytest.approx(0.02)
    assert t[first] - t_end == pytest.approx(0.02, abs=2.5e-3)
    assert contact[np.searchsorted(t, t_end)].all()  # four feet down when the push's force ends
    assert not contact[first].any()  # none when the flight begins
    assert np.isfinite(ex.landing_x) and ex.apex_z > 0.38


def test_a_later_stances_replans_take_their_own_proximal_weight():
    """``prox_later`` weighs the step of a re-plan made within the rear-only part and no other:
    in the first stance the schedule is the same whatever it is; within the later one, whose law
    has a weak force gain (a fifth of the contact's), a larger weight moves the forces less from
    the last schedule's."""
    contact = [{"nu1": GAIN_X, "dxi1": DAMP_X}, {"nu2": GAIN_Z, "1": G_C}]
    partial = [{"nu1": GAIN_X / 5}, {"nu2": GAIN_Z / 5, "1": G_C}]
    model = planted_model(contact, [{}, {"1": -GRAVITY}], phases=("contact", "partial", "flight"), third=partial)
    dyn = LearnedDynamics(model, {"contact": np.eye(2), "partial": np.eye(2)})
    nlp = JumpPlanner(dyn, mass=13.0, stances=(Stance("contact", 3, 0.05, 0.15), Stance("partial", 3, 0.04, 0.10)))
    q0 = np.zeros(18)
    q0[Z] = 0.21
    plan = nlp.solve(dyn.initial_state(q0, np.zeros(18)), 0.3, z_liftoff=Z_LO, min_apex=0.43, z_touchdown=0.30)
    assert plan.success, plan.status
    d0, d1 = plan.durations  # plan.states: the push's start, then each knot's end (3 and 3)
    moved = {}
    for weight in (0.03, 0.2, 2.0):
        rp = Replanner(nlp, prox_later=weight)
        rp.begin(plan, 0.3, plan.x0, Z_LO, 0.30, None, 0.43)
        behind = np.array([1.0, 1.0, 0.98, 0.98])  # velocities behind the plan's
        first = rp.step(plan.states[1] * behind, d0 / 3)
        tau = d0 + d1 / 3
        warm = rp._warm(tau, 1)[3:].reshape(-1, 2) * 13.0 * GRAVITY  # the last schedule's forces, N
        after = rp.step(plan.states[4] * behind, tau)
        assert after.first == 1 and rp.stats.status == ["ok", "ok"]
        # the forward force: the vertical one is held by the lift-off guard whatever the weight
        moved[weight] = (np.concatenate(first.forces), float(np.abs(after.forces[0][:, 0] - warm[:, 0]).mean()))
    assert np.array_equal(moved[0.03][0], moved[0.2][0]) and np.array_equal(moved[0.03][0], moved[2.0][0])
    assert moved[0.03][1] > moved[0.2][1] > moved[2.0][1] > 0
