"""Froggy on robots it was not tuned on: the built-in Laikago and the user-written Mini Cheetah
jump, land level enough and pass every check in both engines; the stance puts the feet under
the hips, which the Laikago's straight legs do not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _simdata import tmp_path

from symrom.robots import ROBOTS, leg_kinematics
from symrom.robots.stance import nominal_feet
from symrom.sim.controllers.flight import longest_run
from symrom.sim.controllers.froggy import FroggyParams, sample_params
from symrom.sim.engines.registry import ENGINES
from symrom.sim.generation.checks import JumpChecks
from symrom.sim.generation.generate import GenerateConfig, generate

pytestmark = pytest.mark.slow
ROBOTS_DIR = Path(__file__).parent / "robots"
FROGGY_ROBOTS = {"laikago": str(ROBOTS["laikago"]), "mini_cheetah": str(ROBOTS_DIR / "mini_cheetah.toml")}


def test_the_stance_puts_the_feet_under_the_hips():
    zero = np.zeros((1, 12))
    for robot in ("a1", "go1", str(ROBOTS_DIR / "mini_cheetah.toml")):  # straight legs are plumb: unchanged
        assert np.array_equal(nominal_feet(robot), leg_kinematics(robot).foot_positions(zero)[0])
    kin = leg_kinematics("laikago")
    straight, feet = kin.foot_positions(zero)[0], nominal_feet("laikago")
    assert np.all(straight[:, 0] < kin.hip_positions()[:, 0] - 0.15)  # its straight legs reach back
    np.testing.assert_array_equal(feet[:, 0], kin.hip_positions()[:, 0])
    np.testing.assert_array_equal(feet[:, 1:], straight[:, 1:])


def test_other_robots_crouch_level_and_the_a1_keeps_its_tuning():
    assert sample_params(np.random.default_rng(0)).crouch_pitch == FroggyParams.crouch_pitch > 0
    for path in FROGGY_ROBOTS.values():
        assert sample_params(np.random.default_rng(0), path).crouch_pitch == 0.0


@pytest.mark.parametrize("engine", list(ENGINES))
@pytest.mark.parametrize("robot", list(FROGGY_ROBOTS))
def test_froggy_on_other_robots_passes_the_checks(robot, engine):
    """One jump (the generator retries failed attempts; at most one retry is allowed here):
    a real flight after a rear-only push, landed without tipping over."""
    path = FROGGY_ROBOTS[robot]
    ds = generate(GenerateConfig(path, "froggy", 1, seed=1, engine=engine, max_attempts=2),
                  tmp_path(f"froggy_{robot}_{engine}.h5"))
    checks = JumpChecks()
    q, c = ds.q, ds.contact
    a, b = longest_run(c.sum(axis=1) == 0)
    assert (b - a) * ds.dt >= checks.min_flight
    assert (c[a - 1, :2] == 0).all() and c[a - 1, 2:].any()  # the rear feet pushed last
    assert np.abs(q[:, 16]).max() < checks.max_tilt and q[-1, 14] > 0.6 * q[0, 14]  # landed upright
    assert abs(q[-1, 16]) < 0.1  # and level again at the end
    assert q[-1, 12] - q[0, 12] >= checks.min_travel
