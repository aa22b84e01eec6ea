"""Robot description files: built-ins, joint signs, and one clear error per bad key."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.robots import ROBOTS, RobotDescriptionError, get_robot, leg_kinematics, robot_key, total_mass
from symrom.robots.description import load_description
from symrom.robots.stance import leg_length, start_pose

GO1 = ROBOTS["go1"]


def test_built_ins_load_with_their_facts():
    go1, a1 = get_robot("go1"), get_robot("a1")
    assert go1.key == "go1" and go1.name == "go1" and go1.base_link == "trunk"
    assert go1.mass == pytest.approx(13.1) and total_mass("go1") == go1.mass
    assert go1.torque_limit == (23.7, 23.7, 35.55) * 4 and a1.torque_limit == (33.5,) * 12
    assert go1.joint_names[:3] == ("FR_hip_joint", "FR_thigh_joint", "FR_calf_joint")
    assert go1.foot_links == ("FR_foot", "FL_foot", "RR_foot", "RL_foot")
    assert go1.foot_radius == 0.02 and go1.start_height == 0.3165
    assert leg_length("go1") == pytest.approx(0.426)
    assert set(ROBOTS) >= {"go1", "a1", "laikago"}


def test_a_path_names_the_robot_by_its_absolute_path(tmp_path):
    rel = Path(GO1).relative_to(Path.cwd()) if Path(GO1).is_relative_to(Path.cwd()) else GO1
    assert robot_key(str(rel)) == str(GO1.resolve())
    assert get_robot(str(rel)).mass == get_robot("go1").mass
    with pytest.raises(RobotDescriptionError, match=r"unknown robot 'b2'; known: \['a1', 'go1', 'laikago'\]"):
        get_robot("b2")


def test_signs_turn_the_laikago_right_abduction_axes_around():
    """A positive hx swings every foot to the robot's left (+y), as on the Go1, although
    the Laikago URDF turns its right legs' abduction joints about -x."""
    for robot in ("go1", "laikago"):
        kin = leg_kinematics(robot)
        q = np.tile(get_robot(robot).stance_joints[:3], 4)[None]
        q_hx = q.copy()
        q_hx[:, 0::3] += 0.1
        dy = kin.foot_positions(q_hx)[0, :, 1] - kin.foot_positions(q)[0, :, 1]
        assert np.all(dy > 0.01), (robot, dy)
    assert get_robot("laikago").joint_signs[0::3] == (-1.0, 1.0, -1.0, 1.0)


def test_start_pose_stands_level_at_the_start_height():
    for robot in ROBOTS:
        desc = get_robot(robot)
        q = start_pose(robot)
        feet = leg_kinematics(robot).foot_positions(q[None, :12])[0]
        np.testing.assert_allclose(feet[:, 2], -(desc.start_height + 5e-4 - desc.foot_radius), atol=1e-6)
        assert np.all((q[2::3][:4] >= desc.knee_range[0]) & (q[2::3][:4] <= desc.knee_range[1]))


# ------------------------------------------------------------------ bad files
GOOD = Path(GO1).read_text().replace('urdf = "go1.urdf"', f'urdf = "{Path(GO1).parent / "go1.urdf"}"')


def _bad(tmp_path: Path, old: str, new: str) -> Path:
    assert old in GOOD, old
    p = tmp_path / "robot.toml"
    p.write_text(GOOD.replace(old, new, 1))
    return p


BAD = [  # (old text, new text, key named in the error, what it says)
    ("format = 1", "format = 3", "format", "not supported"),
    ("[feet]", "[feet]\npoint = [0, 0, 0]", "feet.point", "needs format = 2"),
    ('link = "{leg}_foot"', 'geom = "{leg}"', "feet.geom", "needs format = 2"),
    ("height = 0.3165 ", "", "stance.height", "missing"),
    ("height = 0.3165", "heigth = 0.3165", "stance.heigth", "unknown key"),
    ("torque = [23.7, 23.7, 35.55]", "torque = [23.7, 23.7]", "limits.torque", "expected 3 or 12 numbers"),
    ("torque = [23.7, 23.7, 35.55]", 'torque = [23.7, "x", 35.55]', "limits.torque", "expected a number"),
    ("hx = 1", "hx = [1, 1, 2, 1]", "signs.hx", "1 or -1"),
    ('hy = "{leg}_thigh_joint"', 'hy = "{leg}_thigh"', "joints.hy", "no joint 'FR_thigh'"),
    ('hx = "{leg}_hip_joint"', 'hx = "{leg}_foot_fixed"', "joints.hx", "is fixed, not revolute"),
    ('link = "{leg}_foot"', 'link = "{side}_foot"', "feet.link", "placeholder {leg}"),
    ('base_link = "trunk"', 'base_link = "body"', "base_link", "no link 'body'"),
    ("knee = [-2.8, -0.3]", "knee = [-0.3, -2.8]", "stance.knee", "lower < upper"),
    ("[legs]", "[arms]", "arms", "unknown key"),
]


@pytest.mark.parametrize("old, new, key, what", BAD, ids=[b[2] + ":" + b[3][:12] for b in BAD])
def test_a_bad_file_gets_one_error_naming_the_key(tmp_path, old, new, key, what):
    path = _bad(tmp_path, old, new)
    with pytest.raises(RobotDescriptionError) as e:
        load_description(path)
    msg = str(e.value)
    assert f"key {key!r}" in msg and what in msg and str(path) in msg and "\n" not in msg


def test_unreadable_files(tmp_path):
    with pytest.raises(RobotDescriptionError, match="no such file"):
        load_description(tmp_path / "none.toml")
    (tmp_path / "x.toml").write_text("format = [")
    with pytest.raises(RobotDescriptionError, match="not valid TOML"):
        load_description(tmp_path / "x.toml")
    p = _bad(tmp_path, f'urdf = "{Path(GO1).parent / "go1.urdf"}"', 'urdf = "pybullet_data:b2/b2.urdf"')
    with pytest.raises(RobotDescriptionError, match=r"key 'urdf': no such file .*b2\.urdf"):
        load_description(p)


def test_cli_generate_names_the_bad_key(tmp_path):
    path = _bad(tmp_path, "hx = 1", "hx = 0")
    r = CliRunner().invoke(app, ["generate", "--robot", str(path), "--motion", "pronk", "--jumps", "1",
                                 "--out", str(tmp_path / "x.h5")])
    one_line_error(r, "signs.hx", "1 or -1", "robot.toml")
    assert not (tmp_path / "x.h5.parts").exists()
