"""A quadruped that is not one of the paper's, given only as a pybullet_data URDF and a
description file: checked pronking jumps, then a model trained and evaluated on them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import read_dataset
from symrom.robots import ROBOTS, get_robot
from symrom.sim.controllers.flight import longest_run

pytestmark = pytest.mark.slow
DESCRIPTION = str(ROBOTS["laikago"])  # given by path: no registry needed


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("laikago") / "laikago.h5"
    # three jumps to train on, one to test: no validation jump, which would only pick the
    # contact guards (picked on the training jumps without one)
    r = CliRunner().invoke(app, ["generate", "--robot", DESCRIPTION, "--motion", "pronk", "--jumps", "4",
                                 "--split", "3,0,1", "--seed", "2", "--out", str(out)])
    assert r.exit_code == 0, r.output
    return out


def test_generates_checked_pronking_jumps(data):
    ds = read_dataset(data)
    desc = get_robot(DESCRIPTION)
    assert ds.robot == DESCRIPTION and ds.motion == "pronk" and desc.name == "laikago"
    assert ds.generator["robot_description"] == open(DESCRIPTION).read()
    limit = np.asarray(desc.torque_limit)
    for j, (a, b) in enumerate(ds.jump_bounds()):
        q, c = ds.q[a:b], ds.contact[a:b]
        fa, fb = longest_run(c.sum(axis=1) == 0)
        assert (fb - fa) * ds.dt >= 0.15, f"jump {j}: real flight"
        assert q[:, 14].max() - q[0, 14] >= 0.08, f"jump {j}: apex gain"
        assert q[-1, 12] - q[0, 12] >= 0.1, f"jump {j}: forward travel"
        assert np.abs(q[:, 15:17]).max() < 0.5 and q[-1, 14] > 0.3, f"jump {j}: fell"
        assert np.all(np.abs(ds.tau[a:b]) <= limit + 1e-9)
    assert q[0, 14] == pytest.approx(desc.start_height, abs=1e-3)  # its own stance, not the Go1's


def test_trains_and_evaluates_with_no_code_change(data, tmp_path):
    runner = CliRunner()
    r = runner.invoke(app, ["train", str(data), "--latent-dim", "2", "--out", str(tmp_path / "m"),
                            "--encoder-components", "x,y,z", "--decoded-weight", "0", "--alpha", "1e-3"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["evaluate", str(tmp_path / "m" / "model.json"), str(data), "--integrator", "rk4",
                            "--out", str(tmp_path / "e")])
    assert r.exit_code == 0, r.output
    metrics = json.loads((tmp_path / "e" / "metrics.json").read_text())
    full = metrics["horizons"]["full"]
    assert metrics["n_jumps"] == 1 and full["diverged_jumps"] == 0
    assert full["components"]["z"]["rmse"] < 0.05 and full["components"]["x"]["rmse"] < 0.1
    r = runner.invoke(app, ["aslip", str(data), "--integrator", "rk4", "--out", str(tmp_path / "a")])
    assert r.exit_code == 0, r.output
    params = json.loads((tmp_path / "a" / "params.json").read_text())
    assert params["m"] == pytest.approx(get_robot(DESCRIPTION).mass) and params["m"] == pytest.approx(25.567)
