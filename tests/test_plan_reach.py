"""Reach, said plainly: the model's bounds give the farthest jump, the training jumps' envelope
narrows it, an out-of-reach target is refused with nothing written, ``--closest`` plans the
closest reachable jump and says so in landing.json; a model that cannot plan fails in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import one_line_error
from test_plan import planted_model
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.dataset import Dataset
from symrom.data.envelope import jump_envelope
from symrom.model.persistence import save_model
from symrom.plan.dynamics import PlanModelError, PointMass
from symrom.plan.problem import JumpPlanner

ENVELOPE = {"jumps": 9, "travel_x_m": [0.1, 0.35], "apex_z_m": [0.40, 0.47], "liftoff_z_m": 0.33,
            "touchdown_z_m": 0.33, "push_s": [0.15, 0.2]}
GO1_LIKE = ([{"nu1": 0.062, "nu2": -0.0075}, {"nu2": 0.085, "1": -9.68}], [{}, {"1": -10.2}])


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("reach") / "model.json"
    save_model(planted_model(*GO1_LIKE, info={"envelope": ENVELOPE}), path)
    return path


def test_the_model_bounds_give_the_farthest_jump():
    """The reach's farthest landing is where the NLP can still land; 5 cm farther it cannot."""
    m = 13.1
    nlp = JumpPlanner(PointMass(m), mass=m, torque_map=(np.array([[0.0, 0.05], [0.03, 0.04]]), np.array([14.0, 16.0])))
    s0 = np.array([0.0, 0.21, 0.0, 0.0])
    r = nlp.reach(s0, 0.33, 0.43)
    assert 0.2 < r.x_max < 3.0 and abs(r.x_min) < 1e-3 and r.z_max > 0.43
    at = nlp.solve(s0, r.x_max, z_liftoff=0.33, min_apex=0.43, warm=False)
    assert at.success and at.landing_x == pytest.approx(r.x_max, abs=2e-3)
    beyond = nlp.solve(s0, r.x_max + 0.05, z_liftoff=0.33, min_apex=0.43, warm=False)
    assert beyond.landing_x < r.x_max + 0.01
    high = nlp.solve(s0, 0.2, z_liftoff=0.33, apex=r.z_max + 0.05, warm=False)
    assert high.apex_z < r.z_max + 0.01


def test_out_of_reach_is_refused_and_nothing_written(tmp_path, model_path):
    out = tmp_path / "j"
    res = CliRunner().invoke(app, ["jump", str(model_path), "--target-x", "1.5", "--out", str(out)])
    one_line_error(res, "out of the learned planner's reach", "0.100-0.350 m forward", "--closest")
    assert not out.exists()
    res = CliRunner().invoke(app, ["jump", str(model_path), "--target-x", "0.2", "--target-z", "2.0",
                                   "--out", str(out)])
    one_line_error(res, "apex 2 m", "0.400-0.470 m")
    assert not out.exists()


def test_closest_plans_the_closest_reachable_jump(tmp_path, model_path):
    out = tmp_path / "j"
    res = CliRunner().invoke(app, ["jump", str(model_path), "--target-x", "1.5", "--target-z", "2.0", "--closest",
                                   "--out", str(out), "--no-trajectory"])
    assert res.exit_code == 0, res.output
    assert "warning" in res.output and "out of" in res.output
    d = json.loads((out / "landing.json").read_text())
    assert d["target_reachable"] is False and d["target_x"] == 1.5 and d["target_z"] == 2.0
    assert d["planned_target_x"] == pytest.approx(0.35) and d["planned_target_z"] == pytest.approx(0.47)
    assert d["reach"]["x_m"] == pytest.approx([0.1, 0.35]) and d["reach"]["training_data"]["x_m"] == [0.1, 0.35]
    assert d["plan"]["landing_x_m"] == pytest.approx(0.35, abs=5e-3)
    assert d["error_x"] == pytest.approx(d["landing_x"] - 1.5)
    assert d["control"] == "plan" and d["disturbances"] == {"payload_kg": 0.0, "friction": None, "motor_scale": 1.0}


def test_an_apex_past_the_training_jumps_is_out_of_reach_not_unplannable():
    """A target apex the model's bounds allow but its training jumps never reached, at which the
    model's forward range misses the training jumps' (0.3-0.4 m), is out of reach at the highest
    apex the data hold, not a model that cannot plan: refused naming that reach, or with
    ``closest`` planned at that apex."""
    from symrom.plan.jump import OutOfReach, aim, make_planner

    env = dict(ENVELOPE, travel_x_m=[0.3, 0.4])
    planner = make_planner("learned", "go1", model=planted_model(*GO1_LIKE, info={"envelope": env}))
    reach = planner.reach(0.9)
    assert reach.apex == pytest.approx(0.47) and reach.z_max == pytest.approx(0.47)
    assert reach.x_min == pytest.approx(0.3) and reach.x_max == pytest.approx(0.4)
    with pytest.raises(OutOfReach, match="apex 0.9 m is out of the learned planner's reach.*apex 0.400-0.470 m"):
        aim(planner, 0.35, 0.9)
    x, z, _, inside = aim(planner, 0.35, 0.9, closest=True)
    assert not inside and z == pytest.approx(0.47, abs=5e-3) and x == pytest.approx(0.35, abs=5e-3)


def test_a_model_that_cannot_plan_fails_in_one_line(tmp_path):
    """A model whose push cannot lift the base (its vertical force gain is negative)."""
    path = tmp_path / "model.json"
    save_model(planted_model([{"nu1": 0.062}, {"nu2": -0.085, "1": -9.68}], [{}, {"1": -10.2}]), path)
    out = tmp_path / "j"
    res = CliRunner().invoke(app, ["jump", str(path), "--target-x", "0.2", "--out", str(out)])
    one_line_error(res, "cannot plan")
    assert not out.exists()
    from symrom.model.persistence import load_model
    from symrom.plan.jump import make_planner

    with pytest.raises(PlanModelError):
        make_planner("learned", "go1", model=load_model(path)).reach()


def test_the_envelope_of_planted_jumps():
    """Two jumps drawn by hand: crouch, push, flight, landing; travel from the crouch's bottom."""
    rows = []
    for j, (travel, apex) in enumerate(((0.2, 0.44), (0.3, 0.46))):
        n = 300
        t = np.arange(n) * 0.002
        x = np.zeros(n)
        z = np.full(n, 0.3)
        phase = np.zeros(n, int)
        z[:100] = 0.3 - 0.1 * np.sin(np.pi * np.arange(100) / 198)  # crouch, lowest at row 99
        lo, td = 150, 250
        x[100:td] = np.linspace(0.0, travel, td - 100)
        x[td:] = travel
        z[100:lo] = np.linspace(z[99], 0.33, lo - 100)
        z[lo:td] = 0.33 + (apex - 0.33) * np.sin(np.pi * np.arange(td - lo) / (td - lo))
        x[:100] = 0.0
        phase[lo:td] = 1
        q = np.zeros((n, 18))
        q[:, 12], q[:, 14] = x + 0.01 * j, z
        rows.append((np.full(n, j), t, q, phase))
    jump, t, q, phase = (np.concatenate(v) for v in zip(*rows))
    N = len(t)
    # the input's wrench: fx, fz, my of 10 + j, 200 + 50 j, -3 + j in the push (rows 99-149 of
    # each jump), far larger in the crouch and the landing, which the push range leaves out
    u = np.zeros((N, 18))
    u[:, [12, 14, 16]] = [900.0, 900.0, 900.0]
    for j in (0, 1):
        push = (jump == j) & (np.arange(N) % 300 >= 99) & (np.arange(N) % 300 < 150)
        u[push, 12], u[push, 14], u[push, 16] = 10.0 + j, np.linspace(200.0, 250.0 + 50 * j, 51), -3.0 + j
    ds = Dataset("go1", "pronk", "sim", ["contact", "flight"], jump.astype(np.int32), t, q, np.zeros((N, 18)),
                 np.zeros((N, 18)), np.zeros((N, 12)), np.ones((N, 4), np.uint8), u,
                 phase.astype(np.int8), np.array(["train", "train"]))
    env = jump_envelope(ds, [0, 1])
    assert env["jumps"] == 2
    assert env["travel_x_m"] == pytest.approx([0.2, 0.3], abs=2e-3)
    assert env["apex_z_m"] == pytest.approx([0.44, 0.46], abs=1e-3)
    assert env["liftoff_z_m"] == pytest.approx(0.33) and env["touchdown_z_m"] == pytest.approx(0.3)
    assert env["push_s"] == pytest.approx([0.102, 0.102])
    # each jump's lift-off (the flight's first row, 150) and its travel to the touchdown (row 250)
    lo = env["liftoffs"]
    assert np.array(lo["q"]) == pytest.approx(q[[150, 450]]) and np.array(lo["dq"]).shape == (2, 18)
    assert lo["travel_x_m"] == pytest.approx([q[250, 12] - q[150, 12], q[550, 12] - q[450, 12]])
    assert lo["travel_x_m"][1] > lo["travel_x_m"][0] > 0.05
    pushed = env["push_wrench"]
    assert pushed["components"] == ["fx", "fz", "my"] and list(pushed["phases"]) == ["contact"]
    assert pushed["phases"]["contact"]["min"] == pytest.approx([10.0, 200.0, -3.0])
    assert pushed["phases"]["contact"]["max"] == pytest.approx([11.0, 300.0, -2.0])
    assert jump_envelope(ds, [0])["push_wrench"]["phases"]["contact"]["max"] == pytest.approx([10.0, 250.0, -3.0])
    assert jump_envelope(ds, []) is None
    assert env["release"] is None  # no row of the push pulls the base down
    # the release: the push's last rows pull down (fz < 0), 5 rows on jump 0 and 4 on jump 1
    for j, (n_rel, fx, fz) in enumerate(((5, 8.0, -50.0), (4, 12.0, -70.0))):
        rel = (jump == j) & (np.arange(N) % 300 >= 150 - n_rel) & (np.arange(N) % 300 < 150)
        u[rel, 12], u[rel, 14] = fx, fz
    released = jump_envelope(ds, [0, 1])["release"]
    assert released["s"] == pytest.approx(4 * 0.002) and released["phase"] == "contact"  # floor of the median 4.5
    assert released["force_n"] == pytest.approx([10.0, -60.0])
    assert jump_envelope(ds, [0])["release"]["s"] == pytest.approx(5 * 0.002)


def test_a_learned_pronk_lifts_off_and_lands_at_its_training_jumps_heights():
    """A learned model's pronk takes its envelope's median lift-off and touchdown heights for its
    height guards; without an envelope, or for a baseline not given any, the pronk's take-off
    height; a baseline given heights takes them (the benchmark's same care); bad heights are
    refused naming them."""
    from symrom.plan.jump import make_planner, training_heights

    env = {**ENVELOPE, "liftoff_z_m": 0.345, "touchdown_z_m": 0.347}
    model = planted_model(*GO1_LIKE, info={"envelope": env})
    assert training_heights(model) == (0.345, 0.347)
    learned = make_planner("learned", "go1", model=model)
    assert (learned.liftoff_height, learned.touchdown_height) == (0.345, 0.347)
    plain = make_planner("learned", "go1", model=planted_model(*GO1_LIKE))
    assert training_heights(planted_model(*GO1_LIKE)) is None
    assert plain.liftoff_height == plain.touchdown_height == pytest.approx(0.33)
    pm = make_planner("point-mass", "go1")
    assert pm.liftoff_height == pm.touchdown_height == pytest.approx(0.33)
    # on another robot of its build the model's heights are not that robot's: its own take-off height
    other = make_planner("learned", "a1", model=model)  # the A1 is of the Go1's build
    assert other.liftoff_height == pytest.approx(make_planner("point-mass", "a1").liftoff_height)
    given = make_planner("point-mass", "go1", heights=training_heights(model))
    assert (given.liftoff_height, given.touchdown_height) == (0.345, 0.347)
    # the plan's lift-off is at the new height: the planned push ends where the base reaches it
    plan = learned.plan(learned.motion.q_crouch, np.zeros(18), 0.2)
    assert plan.success and plan.nodes[learned.nlp._n_knots][1] == pytest.approx(0.345, abs=1e-6)
    with pytest.raises(ValueError, match="heights must be positive"):
        make_planner("point-mass", "go1", heights=(0.33, float("nan")))


def test_a_learned_pronk_plans_its_training_jumps_release():
    """A learned model's pronk on its own robot follows its planned push with its envelope's
    release (``training_release``); none without one, on another robot, or for a baseline not
    given it; a baseline given it takes it (the benchmark's same care). The plan's push then ends
    below the lift-off height, which the release reaches."""
    from symrom.plan.jump import make_planner, training_release
    from symrom.plan.problem import Release

    env = {**ENVELOPE, "liftoff_z_m": 0.345, "touchdown_z_m": 0.347,
           "release": {"s": 0.01, "force_n": [10.0, -60.0], "phase": "contact"}}
    model = planted_model(*GO1_LIKE, info={"envelope": env})
    assert training_release(model) == Release(0.01, (10.0, -60.0))
    learned = make_planner("learned", "go1", model=model)
    assert learned.nlp.release == Release(0.01, (10.0, -60.0))
    assert make_planner("learned", "go1", model=planted_model(*GO1_LIKE)).nlp.release is None
    assert make_planner("learned", "a1", model=model).nlp.release is None
    assert make_planner("point-mass", "go1").nlp.release is None
    assert make_planner("point-mass", "go1", release=training_release(model)).nlp.release == learned.nlp.release
    plan = learned.plan(learned.motion.q_crouch, np.zeros(18), 0.2)
    assert plan.success and plan.nodes[learned.nlp._n_knots][1] < 0.345 - 1e-3
    with pytest.raises(ValueError, match="positive length"):
        Release(0.0, (10.0, -60.0))
    bad = planted_model(*GO1_LIKE, info={"envelope": {**env, "release": {**env["release"], "s": 0.0}}})
    with pytest.raises(ValueError, match=r"envelope\.release .*positive length"):
        make_planner("learned", "go1", model=bad)
