"""ROS 1 bags, ROS 2 bags (sqlite3 and mcap storage) and MCAP files of a planted jump, written
here with rosbags: each imports to the same dataset as the CSV log of the same jump, to 1e-12."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from _logs import jump, sim_go1, write_plain, write_ros1, write_ros2
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.bags import parse_topics, read_bag
from symrom.data.importers import import_logs, log_kind
from symrom.data.io import read_dataset

runner = CliRunner()
ARRAYS = ("jump", "t", "q", "dq", "ddq", "tau", "contact", "u", "phase")


def _import(*args):
    return runner.invoke(app, ["import", *(str(a) for a in args)])


@pytest.fixture(scope="module")
def planted(tmp_path_factory):
    """Jump 0 of the simulated Go1 (stance, flight, landing) as a CSV log (no accelerations,
    as a bag has none) and its import."""
    d = tmp_path_factory.mktemp("bags")
    m = jump(sim_go1(), 0)
    csv = write_plain(d / "jump.csv", [m], accelerations=False)
    return d, m, import_logs([csv], robot="go1", split="1,0,0")[0]


@pytest.fixture(scope="module")
def bags(planted):
    """The planted jump's bag of a kind, written once for the tests that only read it."""
    d, m, _ = planted
    return cache(lambda kind: _bag(kind, d, m))


def _bag(kind: str, d, m, **kw):
    if kind == "ros1":
        return write_ros1(d / f"{kind}.bag", m, **kw)
    if kind == "mcap":  # the .mcap file of a ROS 2 bag with mcap storage, read on its own
        return next(write_ros2(d / "for_mcap", m, storage="mcap", **kw).glob("*.mcap"))
    return write_ros2(d / kind, m, storage=kind.split("-")[1], **kw)


@pytest.mark.parametrize("kind, layout", [("ros1", "ros1 bag"), ("ros2-sqlite3", "ros2 bag"),
                                          ("ros2-mcap", "ros2 bag"), ("mcap", "mcap")])
def test_a_bag_imports_as_its_csv_log(planted, bags, kind, layout):
    _, _, want = planted
    bag = bags(kind)
    assert log_kind(bag) == layout.split()[0]
    got, _ = import_logs([bag], robot="go1", split="1,0,0")
    for key in ARRAYS:
        np.testing.assert_allclose(getattr(got, key), getattr(want, key), rtol=0, atol=1e-12, err_msg=key)
    assert got.dt == want.dt == 0.002
    f = got.generator["files"][0]
    assert f["layout"] == layout and f["topics"] == {"joints": "/joint_states", "base": "/odom",
                                                     "contacts": "topic /foot_contacts"}
    assert f["checks"] == [] and f["consistency"] == [] and len(f["sha256"]) == 64


def test_the_command_reads_a_bag_and_names_its_topics(planted, bags, tmp_path):
    _, _, want = planted
    bag = bags("ros1")
    out = tmp_path / "d.h5"
    r = _import(bag, "--robot", "go1", "--out", out)
    assert r.exit_code == 0, r.output
    assert "ros1.bag: ros1 bag, joints /joint_states, base /odom, contacts topic /foot_contacts" in \
        " ".join(r.output.split())
    np.testing.assert_allclose(read_dataset(out).q, want.q, rtol=0, atol=1e-12)


def test_contacts_without_a_topic_come_from_the_legs_forces(planted, tmp_path):
    _, m, _ = planted
    lg = read_bag(_bag("ros2-sqlite3", tmp_path, m, contacts=False), "go1")
    assert lg.topics["contacts"].startswith("derived")
    assert (lg.contact == m["contact"]).mean() > 0.99  # 19 of 2928 foot-rows differ, at touch-down


def test_other_topic_names_by_option_and_by_mapping_file(planted, tmp_path):
    _, m, want = planted
    names = {"joints": "/go1/joints", "base": "/state_estimator/odom", "contacts": "/go1/feet"}
    bag = _bag("ros2-sqlite3", tmp_path, m, topics=names)
    one_line_error(_import(bag, "--robot", "go1", "--out", tmp_path / "x.h5"),
                   "no message on the joints topic /joint_states", "/go1/joints (sensor_msgs/msg/JointState)",
                   "/state_estimator/odom (nav_msgs/msg/Odometry)")
    assert not (tmp_path / "x.h5").exists()
    spec = ",".join(f"{k}={v}" for k, v in names.items())
    got, _ = import_logs([bag], robot="go1", split="1,0,0", topics=parse_topics(spec))
    np.testing.assert_allclose(got.u, want.u, rtol=0, atol=1e-12)
    mapping = tmp_path / "go1_topics.toml"
    mapping.write_text("[topics]\n" + "".join(f'{k} = "{v}"\n' for k, v in names.items()))
    r = _import(bag, "--robot", "go1", "--out", tmp_path / "m.h5", "--mapping", mapping)
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(read_dataset(tmp_path / "m.h5").q, want.q, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="'feet=/x' is not ROLE=/topic"):
        parse_topics("feet=/x")


def test_joint_states_in_the_urdf_sign_convention(planted, tmp_path):
    """The Laikago's FR and RR hip abduction joints turn the other way in its URDF (its
    description's joint_signs): a bag holds the URDF's angle, symrom the opposite."""
    from _logs import ros_messages

    _, m, _ = planted
    msgs = [x for x in ros_messages(m, robot="laikago", contacts=False) if x[0] == "/joint_states"]
    first = msgs[0][3]
    fr_hip = list(first.name).index("FR_hip_motor_2_chassis_joint")
    assert first.position[fr_hip] == -m["q"][0, 0] and first.effort[fr_hip] == -m["tau"][0, 0]
    lg = read_bag(write_ros1(tmp_path / "laikago.bag", m, robot="laikago"), "laikago")
    np.testing.assert_array_equal(lg.q[:, :12], m["q"][:, :12])
    np.testing.assert_array_equal(lg.tau, m["tau"])


def test_a_ros2_database_given_alone_names_its_folder(bags, tmp_path):
    folder = bags("ros2-sqlite3")
    (db,) = folder.glob("*.db3")
    one_line_error(_import(db, "--robot", "go1", "--out", tmp_path / "x.h5"),
                   "the database of a ROS 2 bag; give its folder", str(folder))
