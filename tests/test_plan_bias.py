"""The flight bias: what a planner's flight misses of the base's travel from lift-off to touchdown,
fitted on the training jumps' lift-offs (``plan.bias``). A planted line is recovered from the
planner's own flight; the plan and its re-plans land the flight plus the line on the target; a
learned pronk on its own robot takes its training jumps' line, a baseline only when given it; a
malformed record is refused naming its key."""

from __future__ import annotations

import numpy as np
import pytest
from test_plan import planted_model
from test_plan_reach import ENVELOPE, GO1_LIKE

from symrom.names import BASE_POS
from symrom.plan.bias import LEAST_JUMPS, fit_flight_bias
from symrom.plan.dynamics import PointMass
from symrom.plan.problem import FlightBias, JumpPlanner
from symrom.plan.replan import Replanner

X, Z = BASE_POS.start, BASE_POS.start + 2
LINE = (0.017, -0.034, 0.005)  # m, s, s: the base travels this much further than a ballistic flight
Z_TD = 0.347


def planted_liftoffs(n: int = 12, g: float = 9.81, line=LINE, seed: int = 0) -> dict:
    """n lift-offs at 0.345 m with vx 0.2-0.9 m/s and vz 0.9-1.4 m/s whose base travels the ballistic
    flight's distance (gravity g) down to ``Z_TD`` plus ``line`` at the lift-off velocity."""
    rng = np.random.default_rng(seed)
    q, dq = np.zeros((n, 18)), np.zeros((n, 18))
    q[:, X], q[:, Z] = rng.uniform(-0.1, 0.1, n), 0.345
    dq[:, X], dq[:, Z] = rng.uniform(0.2, 0.9, n), rng.uniform(0.9, 1.4, n)
    vx, vz = dq[:, X], dq[:, Z]
    t = (vz + np.sqrt(vz ** 2 + 2 * g * (0.345 - Z_TD))) / g
    travel = vx * t + line[0] + line[1] * vx + line[2] * vz
    return {"q": q.tolist(), "dq": dq.tolist(), "travel_x_m": travel.tolist()}


def test_a_planted_line_is_recovered_from_the_planners_own_flight():
    lo = planted_liftoffs()
    bias = fit_flight_bias(PointMass(12.0), lo, Z_TD)
    assert (bias.offset, *bias.per_velocity) == pytest.approx(LINE, abs=2e-5)
    assert bias.jumps == 12 and bias.rms_m[0] > 5e-3 and bias.rms_m[1] < 1e-5
    # a learned model's flight (the planted one falls at 10.2 m/s²) is measured against its own law
    learned = fit_flight_bias(_learned().dyn, planted_liftoffs(g=10.2), Z_TD)
    assert (learned.offset, *learned.per_velocity) == pytest.approx(LINE, abs=2e-5)
    # measured against a flight that falls at another g, the line is not the planted one
    other = fit_flight_bias(PointMass(12.0), planted_liftoffs(g=10.2), Z_TD)
    assert abs(other.offset - LINE[0]) > 1e-3 or abs(other.per_velocity[1] - LINE[2]) > 1e-3
    assert fit_flight_bias(PointMass(12.0), planted_liftoffs(LEAST_JUMPS - 1), Z_TD) is None
    # a flight that never comes down to the touchdown height is left out
    assert fit_flight_bias(PointMass(12.0), lo, 0.9) is None


@pytest.mark.parametrize("key, value, said", [
    ("dq", [[0.0] * 17] * 12, r"liftoffs\.dq: expected finite numbers of shape \(n, 18\), got shape \(12, 17\)"),
    ("travel_x_m", [float("nan")] * 12, r"liftoffs\.travel_x_m: expected finite numbers"),
    ("q", None, r"liftoffs\.q: missing"),
    ("travel_x_m", [0.1] * 11, r"liftoffs: q, dq and travel_x_m hold 12, 12 and 11 jumps"),
])
def test_malformed_liftoffs_are_refused_naming_the_key(key, value, said):
    lo = planted_liftoffs()
    if value is None:
        del lo[key]
    else:
        lo[key] = value
    with pytest.raises(ValueError, match=said):
        fit_flight_bias(PointMass(12.0), lo, Z_TD)


def test_the_plan_and_its_replans_land_the_flight_plus_the_bias_on_the_target():
    m = 12.0
    tmap = (np.array([[0.0, 0.05], [0.03, 0.04]]), np.array([14.0, 16.0]))
    bias = FlightBias(0.03, (-0.02, 0.004))
    nlp = JumpPlanner(PointMass(m), mass=m, torque_map=tmap, bias=bias)
    plain = JumpPlanner(PointMass(m), mass=m, torque_map=tmap)
    s0 = np.array([0.0, 0.21, 0.0, 0.0])
    plan = nlp.solve(s0, 0.3, z_liftoff=0.33, min_apex=0.43, warm=False)
    assert plan.success and plan.landing_x == pytest.approx(0.3, abs=1e-4)
    n = nlp._n_knots
    flown = plan.states[-1][0] - plan.states[0][0]  # the ballistic flight's landing
    assert flown + bias.at(plan.states[n][2:4]) == pytest.approx(plan.landing_x, abs=1e-9)
    assert bias.at(plan.states[n][2:4]) > 0.01  # the flight lands that much short of the target
    assert plain.solve(s0, 0.3, z_liftoff=0.33, min_apex=0.43, warm=False).states[-1][0] == pytest.approx(0.3, abs=1e-4)
    # the re-plan from the plan's own start predicts the plan's landing, bias included
    rp = Replanner(nlp)
    rp.begin(plan, 0.3, 0.0, 0.33, 0.33, None, 0.43)
    sched = rp.step(s0, 0.0)
    assert sched.landing_x == pytest.approx(0.3, abs=2e-3)
    with pytest.raises(ValueError, match="finite offset"):
        FlightBias(float("nan"), (0.0, 0.0))


def _learned(env: dict | None = None, **kw):
    from symrom.plan.jump import make_planner

    env = {**ENVELOPE, "liftoff_z_m": 0.345, "touchdown_z_m": Z_TD,
           "liftoffs": planted_liftoffs(g=10.2)} if env is None else env
    return make_planner("learned", "go1", model=planted_model(*GO1_LIKE, info={"envelope": env}), **kw)


def test_a_learned_pronk_takes_its_training_jumps_flight_bias():
    from symrom.plan.jump import make_planner

    learned = _learned()
    b = learned.nlp.bias
    assert (b.offset, *b.per_velocity) == pytest.approx(LINE, abs=2e-5)
    plan = learned.plan(learned.motion.q_crouch, np.zeros(18), 0.2)
    n = learned.nlp._n_knots
    assert plan.success and plan.landing_x == pytest.approx(0.2, abs=1e-3)
    assert plan.states[-1][0] - plan.states[0][0] + b.at(plan.states[n][2:4]) == pytest.approx(plan.landing_x)
    model = planted_model(*GO1_LIKE, info={"envelope": {**ENVELOPE, "liftoffs": planted_liftoffs(g=10.2)}})
    # none when asked for none, on another robot, or without lift-offs
    assert _learned(bias=False).nlp.bias is None
    assert make_planner("learned", "a1", model=model).nlp.bias is None
    assert _learned(ENVELOPE).nlp.bias is None
    # a baseline takes none unless given it, then fits it with its own flight (g = 9.81)
    assert make_planner("point-mass", "go1", model=model).nlp.bias is None
    pm = make_planner("point-mass", "go1", model=model, heights=(0.345, Z_TD), bias=True).nlp.bias
    assert pm is not None and abs(pm.offset - LINE[0]) + abs(pm.per_velocity[1] - LINE[2]) > 1e-3
    with pytest.raises(ValueError, match="given no model"):
        make_planner("point-mass", "go1", bias=True)
    bad = {**ENVELOPE, "liftoffs": {**planted_liftoffs(), "q": [[0.0] * 18] * 3}}
    with pytest.raises(ValueError, match=r"provenance\.data\.envelope\.liftoffs: q, dq and travel_x_m hold 3, 12"):
        _learned(bad)
