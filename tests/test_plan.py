"""Jump planning: the NLP on planted models, the point mass against its closed form, the force
distribution of the execution, and ``symrom jump`` end to end on a small planted model."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.hybrid import HybridModel
from symrom.model.library import Library
from symrom.model.persistence import save_model
from symrom.model.provenance import DataRecord, Provenance
from symrom.plan.dynamics import GRAVITY, LearnedDynamics, PlanModelError, PointMass
from symrom.plan.problem import JumpPlanner, PlanError
from symrom.sim.controllers.pronk import distribute_wrench

X, Z = 12, 14  # base x and z in q


def planted_model(contact: list[dict[str, float]], flight: list[dict[str, float]],
                  phases=("contact", "flight"), third: list[dict[str, float]] | None = None,
                  info: dict | None = None) -> HybridModel:
    """l = 2 latents reading the base's x and z exactly; equations by feature name, per phase in
    ``phases``' order: ``contact``, then ``third`` (a middle phase, e.g. ``partial``) if given,
    then ``flight``."""
    lib = Library.standard(2, poly_order=1, trig=False, inputs=True)
    W_e = np.zeros((2, 18))
    W_e[0, X] = W_e[1, Z] = 1.0
    ae = LinearAutoencoder(W_e, np.zeros(2), W_e.T.copy(), np.zeros(18))
    names = lib.feature_names
    eqs = (contact, third, flight) if third is not None else (contact, flight)
    Xi = np.zeros((len(eqs), lib.n_features, 2))
    for k, rows in enumerate(eqs):
        for j, eq in enumerate(rows):
            for feat, c in eq.items():
                Xi[k, names.index(feat), j] = c
    data = DataRecord(**{"robot": "go1", **(info or {})})  # info: DataRecord's fields (robot, motion, envelope)
    return HybridModel(ae, lib, list(phases), Xi, Xi != 0, np.ones(4), provenance=Provenance(data))


# a linear planted law: forward damping and gains other than 1/m, so no closed form plans it
GAIN_X, DAMP_X, GAIN_Z, G_C = 0.07, -0.8, 0.09, -9.7
PLANTED = planted_model([{"nu1": GAIN_X, "dxi1": DAMP_X}, {"nu2": GAIN_Z, "1": G_C}],
                        [{}, {"1": -GRAVITY}])


def _simulate_planted(plan, s0, z_lo):
    """Integrate the planted law (written out here, not through the model) with the plan's forces
    to the touchdown at z_lo; returns (x at touchdown, apex z)."""
    s = np.array([s0[0], s0[1], s0[2], s0[3]], float)  # x, z, vx, vz
    n = len(plan.forces)
    for k in range(n):
        Fx, Fz = plan.forces[k]

        def stance(t, y):
            return [y[2], y[3], GAIN_X * Fx + DAMP_X * y[2], GAIN_Z * Fz + G_C]

        s = solve_ivp(stance, (0, plan.t_stance / n), s, rtol=1e-11, atol=1e-12).y[:, -1]

    def land(t, y):
        return y[1] - z_lo

    land.terminal, land.direction = True, -1
    sol = solve_ivp(lambda t, y: [y[2], y[3], 0.0, -GRAVITY], (0, 2.0), s, events=land, rtol=1e-11,
                    atol=1e-12, dense_output=True, max_step=1e-3)
    return float(sol.y_events[0][0][0]), float(sol.y[1].max())


@pytest.mark.parametrize("target", [0.15, 0.4])
def test_learned_nlp_lands_a_planted_model_on_its_target(target):
    dyn = LearnedDynamics(PLANTED, np.eye(2))  # nu = F
    nlp = JumpPlanner(dyn, mass=13.0)
    q0 = np.zeros(18)
    q0[X], q0[Z] = 0.5, 0.21
    s0 = dyn.initial_state(q0, np.zeros(18))
    plan = nlp.solve(s0, target, z_liftoff=0.33, min_apex=0.43)
    assert plan.success, plan.status
    x_td, apex = _simulate_planted(plan, [0.5, 0.21, 0.0, 0.0], 0.33)
    assert x_td - 0.5 == pytest.approx(target, abs=2e-3)  # RK4 with 2 substeps per interval
    assert plan.landing_x == pytest.approx(target, abs=1e-5)
    assert apex >= 0.43 - 2e-3
    F = plan.forces
    assert np.all(np.abs(F[:, 0]) <= nlp.config.mu * F[:, 1] + 1e-6)
    # an apex target is met as well
    plan2 = nlp.solve(s0, target, z_liftoff=0.33, apex=0.47)
    x2, apex2 = _simulate_planted(plan2, [0.5, 0.21, 0.0, 0.0], 0.33)
    assert x2 - 0.5 == pytest.approx(target, abs=2e-3) and apex2 == pytest.approx(0.47, abs=2e-3)


def test_learned_guards_set_lift_off_and_touchdown():
    """The model's own switches: lift-off when xi2 >= 0.32, touchdown when xi2 <= 0.35."""
    from dataclasses import replace

    from symrom.model.guards import Guard
    from symrom.plan.guards import LearnedGuards

    model = replace(PLANTED, guards=[Guard("contact", "flight", ["xi2"], np.array([1.0]), -0.32, 0.1),
                                     Guard("flight", "contact", ["xi2"], np.array([-1.0]), 0.35, 0.1)])
    dyn = LearnedDynamics(model, np.eye(2))
    nlp = JumpPlanner(dyn, mass=13.0, guards=LearnedGuards.of(model))
    q0 = np.zeros(18)
    q0[Z] = 0.21
    plan = nlp.solve(dyn.initial_state(q0, np.zeros(18)), 0.3, z_liftoff=0.33, min_apex=0.43)
    assert plan.success, plan.status
    n = len(plan.forces)
    assert plan.nodes[n, 1] == pytest.approx(0.32, abs=1e-6)  # lift-off node
    assert plan.nodes[-1, 1] == pytest.approx(0.35, abs=1e-6)  # touchdown node
    assert plan.landing_x == pytest.approx(0.3, abs=1e-5)
    with pytest.raises(ValueError, match="no learned"):
        LearnedGuards.of(PLANTED)


def test_learned_plan_agrees_with_the_models_own_prediction():
    """The plan's force profile fed to ``HybridModel.predict_path`` as u, its guards deciding the
    phases, touches down where the plan said."""
    from dataclasses import replace

    from symrom.model.guards import Guard
    from symrom.plan.guards import LearnedGuards

    model = replace(PLANTED, guards=[Guard("contact", "flight", ["xi2"], np.array([1.0]), -0.32, 0.1),
                                     Guard("flight", "contact", ["xi2"], np.array([-1.0]), 0.35, 0.1)])
    dyn = LearnedDynamics(model, np.eye(2))
    q0 = np.zeros(18)
    q0[Z] = 0.21
    plan = JumpPlanner(dyn, mass=13.0, guards=LearnedGuards.of(model)).solve(
        dyn.initial_state(q0, np.zeros(18)), 0.35, z_liftoff=0.33, min_apex=0.43)

    def inputs(t, state):
        u = np.zeros(18)
        u[X], u[Z] = plan.force_at(t)  # u's wrench: F_x, F_y, F_z at columns 12-14, as nu = (u[12], u[14])
        return u

    dt = 1e-3
    path = model.predict_path(q0, np.zeros(18), inputs, dt, n=1000, phase0="contact", dwell0=1.0)
    landed = [sw for sw in path.switches if sw["target"] == "contact"]
    assert [sw["target"] for sw in path.switches][:2] == ["flight", "contact"]
    k = landed[0]["k"]
    assert path.q[k, X] == pytest.approx(plan.landing_x, abs=3e-3)  # within a sample's travel
    assert path.t[k] == pytest.approx(plan.t_stance + plan.t_rise + plan.t_fall, abs=2 * dt)


def test_point_mass_plan_matches_the_closed_form():
    m = 13.1
    nlp = JumpPlanner(PointMass(m), mass=m)
    plan = nlp.solve(np.array([0.0, 0.21, 0.0, 0.0]), 0.3, z_liftoff=0.33, min_apex=0.43)
    assert plan.success
    # constant force per interval: each stance interval is a parabola; then a ballistic flight
    x, z, vx, vz = 0.0, 0.21, 0.0, 0.0
    dt = plan.t_stance / len(plan.forces)
    for Fx, Fz in plan.forces:
        ax, az = Fx / m, Fz / m - GRAVITY
        x, z, vx, vz = x + vx * dt + ax * dt ** 2 / 2, z + vz * dt + az * dt ** 2 / 2, vx + ax * dt, vz + az * dt
    assert z == pytest.approx(0.33, abs=1e-9)
    t_air = 2 * vz / GRAVITY  # back to the lift-off height
    assert plan.landing_x == pytest.approx(x + vx * t_air, abs=1e-9)
    assert plan.landing_x == pytest.approx(0.3, abs=1e-6)
    assert plan.apex_z == pytest.approx(z + vz ** 2 / (2 * GRAVITY), abs=1e-9)
    assert plan.t_rise + plan.t_fall == pytest.approx(t_air, abs=1e-9)


def test_torque_limits_bound_the_force():
    m = 13.1
    A = np.array([[0.0, 0.05], [0.03, 0.04]])  # two joints' torques per N of (F_x, F_z)
    lim = np.array([8.0, 9.0])
    nlp = JumpPlanner(PointMass(m), mass=m, torque_map=(A, lim))
    plan = nlp.solve(np.array([0.0, 0.21, 0.0, 0.0]), 0.45, z_liftoff=0.33, apex=0.45)
    assert np.all(np.abs(plan.forces @ A.T) <= lim + 1e-6)
    assert np.max(np.abs(plan.forces @ A.T) / lim) > 0.99  # the bound is what holds it back
    free = JumpPlanner(PointMass(m), mass=m).solve(np.array([0.0, 0.21, 0.0, 0.0]), 0.45, z_liftoff=0.33, apex=0.45)
    assert np.max(np.abs(free.forces @ A.T) / lim) > 1.0


def test_unreachable_target_is_reported_not_hung():
    m = 13.1
    nlp = JumpPlanner(PointMass(m), mass=m)
    plan = nlp.solve(np.array([0.0, 0.21, 0.0, 0.0]), 25.0, z_liftoff=0.33, apex=0.43)
    assert not plan.success or abs(plan.landing_x - 25.0) > 1.0  # the friction cone forbids it
    with pytest.raises(PlanError, match="start state"):
        nlp.solve(np.array([0.0, np.nan, 0.0, 0.0]), 0.3, z_liftoff=0.33, min_apex=0.43)


def test_model_without_a_flight_phase_is_refused():
    model = planted_model([{"nu1": 1.0}, {"nu2": 1.0}], [{}, {}], phases=("contact", "partial"))
    with pytest.raises(PlanModelError, match="'flight'"):
        LearnedDynamics(model, np.eye(2))


def test_distribute_sums_to_the_force_and_the_moment():
    rng = np.random.default_rng(0)
    r = rng.normal(0, 0.2, (4, 3))
    F, M = np.array([40.0, -3.0, 200.0]), np.array([1.0, -2.0, 0.5])
    f = distribute_wrench(F, M, r)
    assert f.sum(axis=0) == pytest.approx(F, abs=1e-9)
    assert np.cross(r, f).sum(axis=0) == pytest.approx(M, abs=1e-9)


def test_jump_cli_end_to_end(tmp_path):
    """A small planted model with Go1-like gains plans and executes one jump in PyBullet."""
    from typer.testing import CliRunner

    from symrom.cli import app

    model = planted_model([{"nu1": 0.062, "nu2": -0.0075}, {"nu2": 0.085, "1": -9.68}],
                          [{}, {"1": -10.2}])
    save_model(model, tmp_path / "model.json")
    out = tmp_path / "jump"
    res = CliRunner().invoke(app, ["jump", str(tmp_path / "model.json"), "--robot", "go1", "--target-x", "0.3",
                                   "--out", str(out)])
    assert res.exit_code == 0, res.output
    d = json.loads((out / "landing.json").read_text())
    assert d["format_version"] == 6 and d["planner"] == "learned"
    # a planted model without training jumps plans at the pronk's take-off height
    assert d["heights"] == {"liftoff_z": pytest.approx(0.33), "touchdown_z": pytest.approx(0.33)}
    assert d["release"] is None and d["flight_bias"] is None
    assert d["upright"] and d["rest"]["z"] > 0.2 and abs(d["rest"]["pitch"]) < 0.3
    assert d["error_x"] == pytest.approx(d["landing_x"] - 0.3)
    assert abs(d["error_x"]) < 0.06  # Go1-like gains land near the target
    assert 0.38 < d["apex_z"] < 0.5 and 0 < d["solve_time_s"] < 1.0
    tr = json.loads((out / "trajectory.json").read_text())
    assert len(tr["t"]) == len(tr["base"]) > 100
    # bad input: one clear line
    res = CliRunner().invoke(app, ["jump", "--planner", "aslip", "--target-x", "0.2", "--out", str(tmp_path / "j2")])
    assert res.exit_code != 0 and "params.json" in res.output
