"""The whole path on a robot symrom has never seen: `robot init` on a Menagerie-style model (and on
Menagerie's Barkour vB as published), then generate, train, evaluate and `symrom jump` from the
description it wrote, with no code change;
a model planning for another robot of its build (a Menagerie Go1 for a model of symrom's Go1)
and refused for a robot of another build, in one line; a nominal apex no plan holds within the
torque limits gives way to what the model reaches."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _menagerie import model_path
from conftest import one_line_error
from test_plan import planted_model
from typer.testing import CliRunner

from symrom.cli import app
from symrom.model.persistence import load_model, save_model
from symrom.plan.dynamics import GRAVITY
from symrom.plan.inputs import force_input_map
from symrom.plan.jump import REACH_SHARE, make_planner, plan_jump, pronk_params
from symrom.robots import get_robot
from symrom.robots.init import init_robot
from symrom.robots.stance import start_pose

MODELS = Path(__file__).parent / "robots"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("robots")
    return {name: str(init_robot(MODELS / f"{name}.xml", folder / f"{name}.toml").path)
            for name in ("go1", "go2", "anymal_c")}


def _weak(gain_z: float):
    """A planted model of the Go1 whose vertical law z'' = gain_z F_z - 9.7 needs gain_z F_z to
    hold the apex: small gains ask more force than the Go1's knees give."""
    return planted_model([{"nu1": 0.07, "dxi1": -0.8}, {"nu2": gain_z, "1": -9.7}], [{}, {"1": -GRAVITY}])


def test_a_nominal_apex_out_of_reach_gives_way_to_what_the_model_reaches():
    q = start_pose("go1", pronk_params("go1").crouch_height)
    strong = make_planner("learned", "go1", model=_weak(0.025))
    plan, rule, floor = plan_jump(strong, q, np.zeros(18), 0.3, warm=False)
    assert rule == "at least nominal" and floor == strong.nominal_apex
    assert plan.success and plan.apex_z >= strong.nominal_apex - 1e-6
    weak = make_planner("learned", "go1", model=_weak(0.02))
    held = weak.plan(q, np.zeros(18), 0.3, warm=False)
    assert not held.success and held.status == "Infeasible_Problem_Detected"
    top = weak.plan(q, np.zeros(18), 0.3, weak.nominal_apex, warm=False)  # as high as it goes
    plan, rule, floor = plan_jump(weak, q, np.zeros(18), 0.3, warm=False)
    assert rule == "at least reachable" and plan.success
    assert floor == pytest.approx(weak.liftoff_height + REACH_SHARE * (top.apex_z - weak.liftoff_height))
    assert top.apex_z < weak.nominal_apex - 0.02 and plan.apex_z >= floor - 1e-6
    assert abs(plan.landing_x - 0.3) < 1e-3  # the target met, the apex given way
    plan, rule, floor = plan_jump(weak, q, np.zeros(18), 0.3, target_z=0.38, warm=False)
    assert rule == "target" and floor is None and plan.success and abs(plan.apex_z - 0.38) < 1e-3


def test_a_model_plans_for_another_robot_of_its_build(written, tmp_path):
    """A model of symrom's Go1 plans for the Menagerie-style Go1 (2.7 % lighter) with that robot's
    legs and heights; a Go2 (16 % heavier) and an ANYmal C (knees bending both ways) are refused."""
    model = _weak(0.09)  # trained on 'go1'
    go1 = written["go1"]
    planner = make_planner("learned", go1, model=model)
    p = pronk_params(go1)
    q = start_pose(go1, p.crouch_height)
    assert np.array_equal(planner.dyn.B, force_input_map(model, go1, q))
    assert (planner.crouch_height, planner.liftoff_height) == (p.crouch_height, p.takeoff_height)
    assert planner.nlp.mass == get_robot(go1).mass
    path = tmp_path / "model.json"
    save_model(model, path)
    for name, needles in (("go2", ("mass 15.2 kg", "+16 %", "at most 10 %")),
                          ("anymal_c", ("knees bend different ways",))):
        r = CliRunner().invoke(app, ["jump", str(path), "--robot", written[name], "--engine", "mujoco",
                                     "--target-x", "0.3", "--out", str(tmp_path / name)])
        one_line_error(r, "trained on 'go1'", *needles)


@pytest.mark.slow
def test_the_whole_path_on_a_robot_from_its_model_alone(tmp_path):
    """robot init, generate (4 jumps, MuJoCo), train (l = 2), evaluate and jump (the model's own
    robot, by default) on the Go2 test model, all through the command line."""
    run = CliRunner().invoke
    desc, data, model, ev = (tmp_path / n for n in ("go2.toml", "go2.h5", "model", "eval"))
    steps = [["robot", "init", str(MODELS / "go2.xml"), "--out", str(desc)],
             ["generate", "--robot", str(desc), "--motion", "pronk", "--jumps", "4", "--engine", "mujoco",
              "--out", str(data)],
             ["train", str(data), "--out", str(model), "--latent-dim", "2", "--encoder-components", "x,y,z",
              "--decoded-weight", "0", "--alpha", "1e-3"],
             ["evaluate", str(model / "model.json"), str(data), "--integrator", "rk4", "--out", str(ev)],
             ["jump", str(model / "model.json"), "--engine", "mujoco", "--target-x", "0.17", "--out",
              str(tmp_path / "jump")]]
    for args in steps:
        r = run(app, args)
        assert r.exit_code == 0, (args[0], r.output)
    metrics = json.loads((ev / "metrics.json").read_text())
    assert metrics["n_jumps"] >= 1
    landing = json.loads((tmp_path / "jump" / "landing.json").read_text())
    assert landing["robot"] == str(desc.resolve()) and landing["engine"] == "mujoco"
    assert landing["apex_rule"] == "at least nominal" and landing["target_reachable"]
    assert abs(landing["error_x"]) < 0.05, landing["error_x"]  # 4.9 cm short (2 training jumps)


@pytest.mark.slow
def test_the_whole_path_on_a_menagerie_quadruped(tmp_path):
    """Menagerie's Barkour vB as published (mesh-free): feet as sites, knees bending forward, 18 N m
    motors; robot init, generate (4 jumps), train (l = 2) and a jump to the middle of the training jumps' travel, all
    through the command line with no key given."""
    run = CliRunner().invoke
    desc, data, model = (tmp_path / n for n in ("barkour.toml", "barkour.h5", "model"))
    steps = [["robot", "init", str(model_path("barkour_vb")), "--out", str(desc)],
             ["generate", "--robot", str(desc), "--motion", "pronk", "--jumps", "4", "--engine", "mujoco",
              "--out", str(data)],
             ["train", str(data), "--out", str(model), "--latent-dim", "2", "--encoder-components", "x,y,z",
              "--decoded-weight", "0", "--alpha", "1e-3"],
             ["jump", str(model / "model.json"), "--engine", "mujoco", "--target-x", None, "--out",
              str(tmp_path / "jump")]]
    for args in steps:
        if args[0] == "jump":  # the middle of what the training jumps did, inside the planner's reach
            lo, hi = load_model(model / "model.json").provenance.data.envelope["travel_x_m"]
            target = round(0.5 * (lo + hi), 3)
            args[args.index(None)] = str(target)
        r = run(app, args)
        assert r.exit_code == 0, (args[0], r.output)
    landing = json.loads((tmp_path / "jump" / "landing.json").read_text())
    assert landing["robot"] == str(desc.resolve()) and landing["settled"]
    lo, hi = landing["reach"]["x_m"]
    assert lo < target < hi and abs(landing["error_x"]) < 0.05, (landing["reach"], landing["error_x"])
