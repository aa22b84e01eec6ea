"""`symrom robot init` on robot models alone: the Menagerie-style MJCF test models (Go1, Go2, A1,
ANYmal C), the mesh-free copies of MuJoCo Menagerie's eight quadrupeds (tests/robots/menagerie)
and URDFs give descriptions that load, whose kinematics are MuJoCo's, whose body model is
MuJoCo's; models symrom cannot describe are refused in one line naming what is missing (a key,
missing mesh files); an MJCF-only robot stands in the MuJoCo engine and is refused by PyBullet;
the script making the copies keeps all but the meshes. (The motions on these models:
tests/test_robot_motions.py.)"""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

import mujoco
import numpy as np
import pytest
from _menagerie import COPIES, FOLDER, init_copies, model_path
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.robots import get_robot, leg_kinematics
from symrom.robots.description import RobotDescriptionError, load_description, pybullet_data_path
from symrom.robots.init import CHECK_TOL, RobotInitError, init_robot
from symrom.robots.mjcf import BASE_INERTIA, FOOT_LINK, cache_dir, colliding, foot_frames
from symrom.robots.show import robot_summary
from symrom.robots.stance import standing_joints, start_pose
from symrom.sim.engines.registry import EngineRobotError, make_world

MODELS = Path(__file__).parent / "robots"
GO1_URDF = Path(__file__).parents[1] / "src" / "symrom" / "robots" / "go1" / "go1.urdf"

# per test model: the leg prefixes FR FL RR RL, joint names, how the feet are named, signs (12),
# torque limits (3), damping (3), the knee range of FR and RR (symrom's signs)
EXPECTED = {
    "go1": dict(legs=("FR", "FL", "RR", "RL"), joints=("{leg}_hip_joint", "{leg}_thigh_joint", "{leg}_calf_joint"),
                feet=("geom", "{leg}"), signs=(1,) * 12, torque=(23.7, 23.7, 35.55), damping=(1.0, 2.0, 2.0),
                knees=((-2.818, -0.888), (-2.818, -0.888))),
    "go2": dict(legs=("FR", "FL", "RR", "RL"), joints=("{leg}_hip_joint", "{leg}_thigh_joint", "{leg}_calf_joint"),
                feet=("geom", "{leg}"), signs=(1,) * 12, torque=(23.7, 23.7, 45.43), damping=(2.0, 2.0, 2.0),
                knees=((-2.7227, -0.83776), (-2.7227, -0.83776))),
    "a1": dict(legs=("FR", "FL", "RR", "RL"), joints=("{leg}_hip_joint", "{leg}_thigh_joint", "{leg}_calf_joint"),
               feet=("body", "{leg}_calf"), signs=(1,) * 12, torque=(33.5, 33.5, 33.5), damping=(1.0, 2.0, 2.0),
               knees=((-2.69653, -0.916298), (-2.69653, -0.916298))),
    "anymal_c": dict(legs=("RF", "LF", "RH", "LH"), joints=("{leg}_HAA", "{leg}_HFE", "{leg}_KFE"),
                     feet=("body", "{leg}_SHANK"), signs=(1,) * 12, torque=(80.0, 80.0, 80.0),
                     damping=(1.0, 1.0, 1.0), knees=((-2.8, -0.3), (0.3, 2.8))),
}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """robot init on each test model, once: name -> RobotInit."""
    folder = tmp_path_factory.mktemp("robots")
    return {name: init_robot(MODELS / f"{name}.xml", folder / f"{name}.toml") for name in EXPECTED}


def _mujoco_feet(model, data, name: str) -> np.ndarray:
    """(4, 3) m, FR FL RR RL, world: MuJoCo's foot positions found without symrom's foot code:
    the sphere geom at the end of each leg's last body (every model here has one)."""
    legs = EXPECTED[name]["legs"]
    kn = EXPECTED[name]["joints"][2]
    out = []
    for leg in legs:
        body = model.joint(kn.format(leg=leg)).bodyid[0]
        spheres = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body
                   and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE]
        assert len(spheres) == 1
        out.append(data.geom_xpos[spheres[0]].copy())
    return np.array(out)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_the_description_holds_the_models_roles(written, name):
    e, r = EXPECTED[name], written[name]
    doc = tomllib.loads(r.text)
    desc = load_description(r.path)
    assert doc["format"] == 2 and "urdf" not in doc and desc.urdf_derived and desc.mjcf_path == (MODELS / f"{name}.xml")
    assert tuple(doc["legs"].values()) == e["legs"] and tuple(doc["joints"].values()) == e["joints"]
    assert (desc.feet.kind, doc["feet"][desc.feet.kind]) == e["feet"]
    assert desc.joint_signs == e["signs"]
    assert desc.torque_limit == e["torque"] * 4 and desc.actuators.damping == e["damping"] * 4
    assert desc.knee_ranges[0] == e["knees"][0] and desc.knee_ranges[2] == e["knees"][1]
    model = mujoco.MjModel.from_xml_path(str(desc.mjcf_path))
    assert desc.mass == pytest.approx(model.body_subtreemass[1], rel=1e-12)
    assert desc.foot_links == tuple(FOOT_LINK.format(leg=leg) for leg in ("fr", "fl", "rr", "rl"))
    assert r.kinematics_error <= CHECK_TOL
    # every value says where it came from
    for line in r.text.splitlines():
        if "=" in line and not line.startswith(("#", "[", "format", "hx", "hy", "kn")):
            assert "#" in line, line


@pytest.mark.parametrize("name", list(EXPECTED))
def test_kinematics_match_mujoco_over_random_joint_angles(written, name):
    """symrom's leg kinematics (the URDF derived from the MJCF, symrom's angles) against MuJoCo's
    forward kinematics of the MJCF itself (the model's angles = sign x symrom's)."""
    desc = written[name].description
    kin = leg_kinematics(desc.key)
    model = mujoco.MjModel.from_xml_path(str(desc.mjcf_path))
    data = mujoco.MjData(model)
    qadr = [model.jnt_qposadr[model.joint(n).id] for n in desc.joint_names]
    rng = np.random.default_rng(7)
    q = rng.uniform(-1.5, 1.5, size=(50, 12))
    ours = kin.foot_positions(q)
    worst = 0.0
    for i in range(len(q)):
        data.qpos[:] = 0.0
        data.qpos[3] = 1.0  # the free base at the origin, unturned: the world is the base frame
        data.qpos[qadr] = q[i] * desc.signs
        mujoco.mj_kinematics(model, data)
        worst = max(worst, np.abs(ours[i] - _mujoco_feet(model, data, name)).max())
    assert worst < 1e-9, worst
    if name == "go1":  # its sites sit where its foot geoms are
        assert np.allclose(data.site_xpos[[model.site(n).id for n in ("FR", "FL", "RR", "RL")]], ours[-1], atol=1e-12)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_the_controllers_body_model_is_the_mjcfs(written, name):
    """Mass, centre of mass and composite inertia (PyBullet reading the derived URDF) and the legs'
    gravity torques equal MuJoCo's of the MJCF, standing."""
    from symrom.sim.controllers.body import LegGravity, body_model

    desc = written[name].description
    model = mujoco.MjModel.from_xml_path(str(desc.mjcf_path))
    data = mujoco.MjData(model)
    data.qpos[:7] = (0, 0, 0, 1, 0, 0, 0)  # the base at the origin, unturned
    q = standing_joints(desc.key)
    data.qpos[[model.jnt_qposadr[model.joint(n).id] for n in desc.joint_names]] = q * desc.signs
    mujoco.mj_forward(model, data)
    bm = body_model(desc.key)
    com = data.subtree_com[1]
    inertia = np.zeros((3, 3))
    for b in range(1, model.nbody):
        R, r = data.ximat[b].reshape(3, 3), data.xipos[b] - com
        inertia += R @ np.diag(model.body_inertia[b]) @ R.T + model.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
    assert bm.mass == pytest.approx(model.body_subtreemass[1], rel=1e-12)
    np.testing.assert_allclose(bm.com_base, com, atol=1e-12)
    np.testing.assert_allclose(bm.inertia, inertia, atol=1e-9)
    vadr = [model.jnt_dofadr[model.joint(n).id] for n in desc.joint_names]
    np.testing.assert_allclose(LegGravity(desc.key).torques(q, np.eye(3)), data.qfrc_bias[vadr] * desc.signs,
                               atol=1e-9)
    text = desc.urdf_path.read_text()
    assert f'<link name="{BASE_INERTIA}">' in text and desc.urdf_path.parent == cache_dir()


def test_the_stances_come_from_the_keyframes(written):
    go1, anymal = written["go1"].description, written["anymal_c"].description
    assert go1.stance_joints == (0.0, 0.9, -1.8) * 4
    # the keyframe's feet (0.213 m links at 0.9, -1.8 rad) 0.023 m spheres on the ground
    assert go1.start_height == pytest.approx(2 * 0.213 * np.cos(0.9) + 0.023, abs=1e-4)
    assert anymal.stance_joints == (0.0, 0.8, -1.3) * 2 + (0.0, -0.8, 1.3) * 2  # knees inwards
    for r in written.values():  # the leg IK stands each at its height, level, knees in range
        d = r.description
        q = start_pose(d.key)
        feet = leg_kinematics(d.key).foot_positions(q[None, :12])[0]
        np.testing.assert_allclose(feet[:, 2], -(d.start_height + 5e-4 - d.foot_radius), atol=1e-6)
        lo, hi = d.knee_range
        assert np.all((q[2:12:3] >= lo) & (q[2:12:3] <= hi))
    assert np.all(start_pose(anymal.key)[[2, 5]] < 0) and np.all(start_pose(anymal.key)[[8, 11]] > 0)


def test_the_derived_urdf_is_cached_by_the_models_content(written, tmp_path):
    model = tmp_path / "go1.xml"
    model.write_text((MODELS / "go1.xml").read_text())
    r = init_robot(model, tmp_path / "go1.toml")
    urdf = r.description.urdf_path
    assert urdf == written["go1"].description.urdf_path  # same content, same file
    mtime = urdf.stat().st_mtime_ns
    assert load_description(r.path).urdf_path == urdf and urdf.stat().st_mtime_ns == mtime  # read, not rewritten
    model.write_text(model.read_text().replace('mass="5.204"', 'mass="6.204"'))
    d = load_description(r.path)
    assert d.urdf_path != urdf and d.mass == pytest.approx(written["go1"].description.mass + 1.0)


# ------------------------------------------------------------------ the URDF route
def test_a_urdf_gives_the_built_in_descriptions_roles_and_signs(tmp_path):
    r = init_robot(GO1_URDF, tmp_path / "go1.toml")
    d, go1 = r.description, get_robot("go1")
    assert not d.urdf_derived and d.urdf_path == go1.urdf_path and d.mjcf_path is None
    for field in ("base_link", "joint_names", "foot_links", "joint_signs", "torque_limit", "start_height"):
        assert getattr(d, field) == getattr(go1, field), field
    assert d.mass == go1.mass and r.kinematics_error <= CHECK_TOL
    assert "\n[actuators]" not in r.text and not tomllib.loads(r.text).get("actuators")  # the URDF states none
    # the Laikago's right abduction axes point backwards: its signs, found from the axes
    r = init_robot(pybullet_data_path("laikago/laikago_toes_zup.urdf"), tmp_path / "laikago.toml",
                   overrides={"stance.knee": [-2.8, -0.3]})
    assert r.text.startswith("#") and 'urdf = "pybullet_data:laikago/laikago_toes_zup.urdf"' in r.text
    for field in ("joint_names", "foot_links", "joint_signs"):
        assert getattr(r.description, field) == getattr(get_robot("laikago"), field), field
    assert r.description.joint_signs[0::3] == (-1.0, 1.0, -1.0, 1.0)


# ------------------------------------------------------------------ refusals
GO1_XML = (MODELS / "go1.xml").read_text()


def _leg_block(text: str, leg: str) -> str:
    a = text.index(f'      <body name="{leg}_hip"')
    b = text.index("\n\n", a)
    return text[a:b]


def _variant(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "variant.xml"
    p.write_text(text)
    return p


REFUSED = {
    "missing foot": (lambda t: t.replace('            <geom name="RL" class="foot"/>\n', "")
                     .replace('            <site name="RL" pos="0 0 -0.213"/>\n', ""),
                     ["leg RL", "no foot", "'RL_calf_joint'"]),
    "fifth leg": (lambda t: t.replace(_leg_block(t, "FR"), _leg_block(t, "FR") + "\n" + _leg_block(t, "FR")
                                      .replace("FR", "XR").replace('pos="0.1881 -0.04675 0"', 'pos="0 -0.1 0"')),
                  ["5 legs", "XR_hip", "four"]),
    "unactuated knee": (lambda t: re.sub(r'\s+ctrl="[^"]*"', "", t)  # the keyframe's controls go with it
                        .replace('    <position class="kn" name="FL_calf" joint="FL_calf_joint"/>\n', ""),
                        ["'FL_calf_joint'", "knee of leg FL", "no actuator"]),
    "knee about x": (lambda t: t.replace('<joint name="RR_calf_joint" class="kn"/>',
                                         '<joint name="RR_calf_joint" class="kn" axis="1 0 0"/>'),
                     ["'RR_calf_joint'", "knee", "not the base's y axis"]),
    "no torque bound": (lambda t: t.replace('<position kp="100" forcerange="-23.7 23.7"/>', '<position kp="100"/>'),
                        ["'FR_hip_joint'", "bounds no torque", "'limits.torque'"]),
    "a scene": (lambda t: t.replace("<worldbody>", '<worldbody>\n    <geom name="floor" type="plane" size="0 0 1"/>'),
                ["world holds geoms", "scene"]),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_models_symrom_cannot_describe_are_refused_in_one_line(tmp_path, case):
    edit, needles = REFUSED[case]
    text = edit(GO1_XML)
    assert text != GO1_XML
    model = _variant(tmp_path, text)
    with pytest.raises(RobotInitError) as e:
        init_robot(model, tmp_path / "x.toml")
    msg = str(e.value)
    assert "\n" not in msg and str(model) in msg, msg
    for needle in needles:
        assert needle in msg, (needle, msg)
    assert not (tmp_path / "x.toml").exists()


def test_a_knee_bending_either_way_needs_a_keyframe_or_its_range(tmp_path):
    text = re.sub(r"\n  <keyframe>.*</keyframe>", "", (MODELS / "anymal_c.xml").read_text(), flags=re.S)
    model = _variant(tmp_path, text)
    with pytest.raises(RobotInitError, match=r"knee joint 'RF_KFE' of leg FR may bend either way.*'stance.knee'") as e:
        init_robot(model, tmp_path / "x.toml")
    assert e.value.key == "stance.knee"
    r = CliRunner().invoke(app, ["robot", "init", str(model), "--out", str(tmp_path / "x.toml")])
    one_line_error(r, "RF_KFE", "--set stance.knee=VALUE")
    knees = [[-2.8, -0.3], [-2.8, -0.3], [0.3, 2.8], [0.3, 2.8]]  # front knees back, hind knees forward
    r = init_robot(model, tmp_path / "x.toml", overrides={"stance.knee": knees})
    d = r.description
    assert r.given == ("stance.knee",) and "# given" in r.text and d.knee_ranges == tuple(map(tuple, knees))
    assert "no standing keyframe" in r.text  # its height: in proportion to leg length; its joints: the leg IK's
    q = standing_joints(d.key)
    assert np.all(q[[2, 5]] < 0) and np.all(q[[8, 11]] > 0)
    assert d.stance_joints == tuple(round(x, 4) + 0.0 for x in q)


# ------------------------------------------------------------------ the description format
def test_format_2_keys_are_checked(written, tmp_path):
    text = written["a1"].text
    cases = [
        (text.replace('body = "{leg}_calf"', 'geom = "{leg}_calf"'), "feet.point", "only with feet.body"),
        (text.replace('body = "{leg}_calf"', 'link = "{leg}_calf"'), "feet.link", "no URDF"),
        (text.replace('body = "{leg}_calf"', 'body = "{leg}_shin"'), "feet.body", "no body 'FR_shin'"),
        (text.replace('hy = "{leg}_thigh_joint"', 'hy = "{leg}_upper_joint"'), "joints.hy",
         "no joint 'FR_upper_joint'"),
        (text.replace("format = 2", "format = 1"), "urdf", "format = 2"),
        (text.replace("knee = [-2.69653, -0.916298]", "knee = [[-2.7, -0.9], [-2.7, -0.9]]"), "stance.knee",
         "4 of them"),
    ]
    for bad, key, what in cases:
        assert bad != text, key
        p = tmp_path / "bad.toml"
        p.write_text(bad)
        with pytest.raises(RobotDescriptionError) as e:
            load_description(p)
        msg = str(e.value)
        assert f"key {key!r}" in msg and what in msg and "\n" not in msg, (key, msg)


# ------------------------------------------------------------------ engines
def test_the_mujoco_engine_stands_an_mjcf_only_robot_on_its_feet(written):
    for name in ("go1", "a1", "anymal_c"):  # feet as named geoms, as points in bodies
        d = written[name].description
        with make_world("mujoco", d.key) as w:
            assert w.model.nu == 12 and w.foot_radius == d.foot_radius
            q = start_pose(d.key)
            w.reset(q)
            s = w.state()
            feet = leg_kinematics(d.key).foot_positions(q[None, :12])[0] + q[12:15]
            np.testing.assert_allclose(s.foot_pos, feet, atol=1e-12)
            assert s.contact.tolist() == [1, 1, 1, 1]
            fz = []
            for i in range(600):  # the legs held at the stance by a joint PD: the feet carry the weight
                st = w.state()
                w.step(300.0 * (q[:12] - st.q[:12]) - 5.0 * st.dq[:12])
                if i >= 300:
                    fz.append(w.contact_forces()[:, 2])
            assert w.state().contact.tolist() == [1, 1, 1, 1]
            fz = np.mean(fz, axis=0)  # N per foot, over the last 0.3 s
            assert fz.sum() == pytest.approx(d.mass * 9.81, rel=0.05) and np.all(fz > 0.5 * fz.sum() / 4), fz
            # the model's own contact parameters: the foot spheres' priority and condim stay
            feet_geoms = [g for g in range(w.model.ngeom) if w._leg_of_geom[g] >= 0]
            assert len(feet_geoms) == 4 and set(w.model.geom_condim[feet_geoms]) == {6}


def test_pybullet_refuses_an_mjcf_only_robot_in_one_line(written, tmp_path):
    d = written["go2"].description
    with pytest.raises(EngineRobotError, match="given as an MJCF alone.*use the mujoco engine"):
        make_world("pybullet", d.key)
    r = CliRunner().invoke(app, ["generate", "--robot", str(d.source), "--motion", "pronk", "--jumps", "1",
                                 "--out", str(tmp_path / "x.h5")])
    one_line_error(r, "go2", "MJCF alone", "mujoco")


# ------------------------------------------------------------------ robot show
def test_robot_show_prints_the_description_as_symrom_reads_it(written, monkeypatch):
    # rich fixes a console's width from COLUMNS when it is made; a CI shell's 80 columns would wrap the names
    from symrom.cli.common import out_console
    monkeypatch.setattr(out_console.real(), "width", 200)
    d = written["anymal_c"].description
    s = robot_summary(d.source)
    assert s.name == "anymal_c" and s.urdf_derived and s.model == d.mjcf_path and s.format == 2
    assert [leg.joints[0] for leg in s.legs] == ["RF_HAA", "LF_HAA", "RH_HAA", "LH_HAA"]
    assert s.mass == pytest.approx(sum(leg.mass for leg in s.legs) + s.base_mass)
    assert s.base_mass == pytest.approx(19.2035) and s.legs[0].mass == pytest.approx(2.781 + 3.071 + 0.58842)
    assert s.legs[0].foot.startswith("body 'RF_SHANK' at (0.01305, 0.08795")
    assert s.legs[2].knee_range == (0.3, 2.8) and s.legs[2].stance[2] > 0
    go1 = robot_summary("go1")
    assert go1.leg_length == pytest.approx(0.426) and go1.legs[0].foot == "link 'FR_foot'" and not go1.urdf_derived
    r = CliRunner().invoke(app, ["robot", "show", str(d.source)])
    assert r.exit_code == 0, r.output
    for needle in ("anymal_c", "format 2", "URDF derived", "RF_KFE", "LH_HFE", "44.965 kg", "[0.3, 2.8]"):
        assert needle in r.output, needle


def test_robot_init_on_the_command_line(tmp_path):
    out = tmp_path / "a1.toml"
    r = CliRunner().invoke(app, ["robot", "init", str(MODELS / "a1.xml"), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "wrote" in r.output and "a1" in r.output and out.is_file()
    r = CliRunner().invoke(app, ["robot", "init", str(MODELS / "a1.xml"), "--out", str(out)])
    one_line_error(r, "exists", "--force")
    r = CliRunner().invoke(app, ["robot", "init", str(MODELS / "a1.xml"), "--out", str(out), "--force",
                                 "--set", "limits.torque=[30.0, 30.0, 30.0]", "--name", "my_a1"])
    assert r.exit_code == 0, r.output
    d = load_description(out)
    assert d.torque_limit == (30.0,) * 12 and d.name == "my_a1"
    r = CliRunner().invoke(app, ["robot", "init", str(MODELS / "a1.xml"), "--out", str(out), "--force",
                                 "--set", "limits.torque"])
    one_line_error(r, "--set 'limits.torque'", "KEY=VALUE")



# ------------------------------------------------------------------ MuJoCo Menagerie's quadrupeds
@pytest.fixture(scope="module")
def menagerie(tmp_path_factory):
    """robot init on each mesh-free copy of a Menagerie quadruped, once: name -> RobotInit."""
    return init_copies(tmp_path_factory.mktemp("menagerie"))


def _feet_by_table(model, data, desc) -> np.ndarray:
    """(4, 3) m, FR FL RR RL, world: MuJoCo's points of the feet the description's [feet] table
    names (its geoms', sites' or bodies' points), read from MuJoCo's data alone."""
    f = desc.feet
    if f.kind == "geom":
        return np.array([data.geom_xpos[model.geom(n).id] for n in f.names])
    if f.kind == "site":
        return np.array([data.site_xpos[model.site(n).id] for n in f.names])
    pts = f.points or ((0.0, 0.0, 0.0),) * 4
    return np.array([data.xpos[model.body(n).id] + data.xmat[model.body(n).id].reshape(3, 3) @ np.asarray(p)
                     for n, p in zip(f.names, pts)])


@pytest.mark.parametrize("name", list(COPIES))
def test_robot_init_describes_each_menagerie_quadruped(menagerie, name):
    """The legs, joints, feet, limits and mass of the published model; its kinematics MuJoCo's
    to 1e-9 m over random joint angles (MuJoCo's feet read by the [feet] table, not symrom's
    foot code); the leg IK stands it at its height with its knees in range."""
    e, r = COPIES[name], menagerie[name]
    desc = load_description(r.path)
    doc = tomllib.loads(r.text)
    assert tuple(doc["legs"].values()) == e["legs"] and (desc.feet.kind, doc["feet"][desc.feet.kind]) == e["feet"]
    assert desc.torque_limit == e["torque"] * 4 and r.given == tuple(e.get("given", ()))
    model = mujoco.MjModel.from_xml_path(str(model_path(name)))
    base = model.body(desc.base_link).id
    assert model.jnt_type[model.body_jntadr[base]] == mujoco.mjtJoint.mjJNT_FREE
    assert desc.mass == pytest.approx(model.body_subtreemass[base], rel=1e-12)
    data = mujoco.MjData(model)
    qadr = [model.jnt_qposadr[model.joint(n).id] for n in desc.joint_names]
    q = np.random.default_rng(11).uniform(-1.5, 1.5, size=(40, 12))
    ours = leg_kinematics(desc.key).foot_positions(q)
    worst = 0.0
    for i in range(len(q)):
        data.qpos[:] = 0.0
        data.qpos[3] = 1.0  # the free base at the origin, unturned: the world is the base frame
        data.qpos[qadr] = q[i] * desc.signs
        mujoco.mj_kinematics(model, data)
        worst = max(worst, np.abs(ours[i] - _feet_by_table(model, data, desc)).max())
    assert worst < 1e-9 and r.kinematics_error <= CHECK_TOL, worst
    q = start_pose(desc.key)
    feet = leg_kinematics(desc.key).foot_positions(q[None, :12])[0]
    np.testing.assert_allclose(feet[:, 2], -(desc.start_height + 5e-4 - desc.foot_radius), atol=1e-6)
    lo, hi = desc.knee_range
    assert np.all((q[2:12:3] >= lo) & (q[2:12:3] <= hi)) and desc.foot_radius > 0.0


def test_menagerie_models_name_what_robot_init_cannot_infer(tmp_path):
    """ANYmal B and C (knees free both ways, no keyframe) and Barkour v0 (servos with no force
    limit) are refused in one line naming the key to give."""
    for name, key in (("anymal_b", "stance.knee"), ("anymal_c", "stance.knee"), ("barkour_v0", "limits.torque")):
        with pytest.raises(RobotInitError) as e:
            init_robot(model_path(name), tmp_path / "x.toml")
        assert e.value.key == key and f"give key {key!r}" in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert "(no range)" in str(pytest.raises(RobotInitError, init_robot, model_path("anymal_b"), tmp_path / "x.toml")
                               .value)


@pytest.mark.parametrize("name", list(COPIES))
def test_each_menagerie_quadruped_stands_on_its_feet(menagerie, name):
    """At symrom's start pose the geoms of each foot (spheres; Barkour vB's rounded ends around
    its foot sites, whose radius is how far they reach past the site) meet the ground, pressed
    into it by at most 2 mm, and nothing else of the robot is lower: MuJoCo's distances."""
    desc = menagerie[name].description
    spec = mujoco.MjSpec.from_file(str(desc.mjcf_path))
    spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    model = spec.compile()
    data = mujoco.MjData(model)
    q = start_pose(desc.key)
    data.qpos[:4] = (*q[12:15], 1.0)
    data.qpos[[model.jnt_qposadr[model.joint(n).id] for n in desc.joint_names]] = q[:12] * desc.signs
    mujoco.mj_forward(model, data)
    ground = model.geom("ground").id
    feet = [f.geoms for f in foot_frames(model, desc.feet)]
    gap = [min(mujoco.mj_geomDistance(model, data, g, ground, 0.5, None) for g in geoms) for geoms in feet]
    assert all(-0.002 <= d <= 0.0 for d in gap), gap
    others = [g for g in range(model.ngeom) if g != ground and colliding(model, g) and not any(g in f for f in feet)]
    assert min(mujoco.mj_geomDistance(model, data, g, ground, 0.5, None) for g in others) > 0.005


def test_a_model_whose_mesh_files_are_missing_is_refused_in_one_line(tmp_path):
    """The Go1 as published (its meshes named) with no assets folder beside it."""
    text = model_path("go1").read_text()
    text = text.replace('<material name="dark"', '<mesh class="go1" file="trunk.stl"/>\n    <mesh class="go1" '
                        'file="hip.stl"/>\n    <material name="dark"')
    text = text.replace("<freejoint/>", '<freejoint/>\n      <geom class="visual" mesh="trunk"/>', 1)
    model = _variant(tmp_path, text)
    with pytest.raises(RobotInitError) as e:
        init_robot(model, tmp_path / "x.toml")
    msg = str(e.value)
    for needle in (str(model), "assets/trunk.stl, assets/hip.stl", "missing", "assets folder"):
        assert needle in msg, (needle, msg)
    r = CliRunner().invoke(app, ["robot", "init", str(model), "--out", str(tmp_path / "x.toml")])
    one_line_error(r, "assets/trunk.stl", "missing")


def test_a_servo_range_says_which_way_a_free_knee_bends(tmp_path):
    """ANYmal C's knees are free both ways and it has no keyframe; servos whose control range lies
    on one side of zero say the side (front knees back, hind knees forward)."""
    text = model_path("anymal_c").read_text()
    for leg, rng in (("LF", "-2.5 -0.2"), ("RF", "-2.5 -0.2"), ("LH", "0.2 2.5"), ("RH", "0.2 2.5")):
        text = text.replace(f'<position class="affine" joint="{leg}_KFE" name="{leg}_KFE"/>',
                            f'<position class="affine" joint="{leg}_KFE" name="{leg}_KFE" ctrlrange="{rng}"/>')
    r = init_robot(_variant(tmp_path, text), tmp_path / "x.toml")
    assert r.description.knee_ranges == ((-2.8, -0.3),) * 2 + ((0.3, 2.8),) * 2
    assert "servo's ctrlrange" in r.text


# ------------------------------------------------------------------ strip_meshes.py
def _strip():
    spec = importlib.util.spec_from_file_location("strip_meshes", FOLDER / "strip_meshes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _obj(path: Path, vertices: np.ndarray) -> None:
    """A convex mesh (OBJ) of the vertices' hull."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    lines = [f"v {x} {y} {z}" for x, y, z in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in tri) for tri in hull.simplices]
    path.write_text("\n".join(lines) + "\n")


def test_strip_meshes_keeps_all_but_the_meshes(tmp_path):
    """A model with a visual mesh, three colliding ones (a slab, a rod, a disc) and a texture
    file: the copy drops the visual mesh and the texture, fits a box, a capsule (MuJoCo's own fit)
    and a sphere (the disc's rim) in their bodies' frames, keeps every other line, and compiles
    with no file beside it."""
    src = tmp_path / "robot"
    (src / "assets").mkdir(parents=True)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    _obj(src / "assets" / "slab.obj", corners * [0.05, 0.04, 0.03])
    _obj(src / "assets" / "rod.obj", corners * [0.01, 0.012, 0.1])
    a = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    ring = np.stack([0.02 * np.cos(a), 0.02 * np.sin(a), np.zeros_like(a)], axis=1)
    _obj(src / "assets" / "disc.obj", np.concatenate([ring + [0, 0, 0.006], ring - [0, 0, 0.006]]))
    _obj(src / "assets" / "shell.obj", corners * 0.1)
    (src / "assets" / "skin.png").write_bytes(b"")
    (src / "LICENSE").write_text("a licence\n")
    xml = """<mujoco model="toy">
  <compiler meshdir="assets" texturedir="assets"/>
  <default>
    <default class="toy">
      <geom type="mesh" friction="0.7"/>
      <default class="visual">
        <geom contype="0" conaffinity="0" mesh="shell"/>
      </default>
    </default>
  </default>
  <asset>
    <texture name="skin" type="2d" file="skin.png"/>
    <material name="paint" texture="skin" rgba="1 0 0 1"/>
    <mesh file="shell.obj"/>
    <mesh file="slab.obj"/>
    <mesh file="rod.obj"/>
    <mesh file="disc.obj"/>
  </asset>
  <worldbody>
    <body name="base" pos="0 0 0.5" childclass="toy">
      <freejoint/>
      <geom class="visual" material="paint"/>
      <geom name="slab" mesh="slab" pos="0.1 0 0" quat="0.9238795 0 0.3826834 0" solimp="0.9 0.95 0.001"/>
      <geom type="sphere" size="0.01" pos="0 0.2 0"/>
      <body name="leg" pos="0 0 -0.1">
        <joint name="hinge" axis="0 1 0"/>
        <geom mesh="rod" pos="0 0 -0.1"/>
        <geom mesh="disc" pos="0 0 -0.2" quat="0.7071068 0.7071068 0 0"/>
        <site name="tip" pos="0 0 -0.22"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""
    (src / "toy.xml").write_text(xml)
    out = _strip().strip(src / "toy.xml", tmp_path / "copy")
    text = out.read_text()
    assert ((tmp_path / "copy" / "LICENSE").read_text() == "a licence\n"
            and sorted(p.name for p in out.parent.iterdir()) == ["LICENSE", "toy.xml"])
    kept = [line for line in xml.splitlines() if not re.search(r"mesh|skin|paint", line)]
    copy_lines = text.splitlines()
    assert all(line in copy_lines for line in kept)  # every other line as published
    assert not re.search(r"<mesh|mesh=|<texture|texture=", text)  # the compiler's folders may stay
    assert '<material name="paint" rgba="1 0 0 1"/>' in text
    m = mujoco.MjModel.from_xml_path(str(out))  # no files beside it
    G = mujoco.mjtGeom
    assert m.ngeom == 4 and {G(t) for t in m.geom_type} == {G.mjGEOM_BOX, G.mjGEOM_CAPSULE, G.mjGEOM_SPHERE}
    slab = m.geom("slab").id
    np.testing.assert_allclose(np.sort(m.geom_size[slab]), [0.03, 0.04, 0.05], atol=1e-9)  # a box's own box
    assert m.geom_friction[slab, 0] == 0.7 and np.allclose(m.geom_solimp[slab, :3], [0.9, 0.95, 0.001])
    np.testing.assert_allclose(m.geom_pos[slab], [0.1, 0, 0], atol=1e-9)
    # the rod: the capsule MuJoCo fits to it, where MuJoCo puts it
    ref = mujoco.MjModel.from_xml_string(xml.replace('<geom mesh="rod"', '<geom type="capsule" mesh="rod"').replace(
        'meshdir="assets"', f'meshdir="{src / "assets"}"').replace('texturedir="assets"', "")
        .replace('<texture name="skin" type="2d" file="skin.png"/>', "").replace('texture="skin" ', ""))
    leg = m.body("leg").id
    cap = next(g for g in range(m.ngeom) if m.geom_type[g] == G.mjGEOM_CAPSULE)
    rcap = next(g for g in range(ref.ngeom) if ref.geom_type[g] == G.mjGEOM_CAPSULE)
    assert m.geom_bodyid[cap] == leg
    np.testing.assert_allclose(m.geom_size[cap, :2], ref.geom_size[rcap, :2], rtol=1e-5)
    np.testing.assert_allclose(m.geom_pos[cap], ref.geom_pos[rcap], atol=1e-6)
    disc = next(g for g in range(m.ngeom) if m.geom_type[g] == G.mjGEOM_SPHERE and m.geom_bodyid[g] == leg)
    assert m.geom_size[disc, 0] == pytest.approx(0.02, rel=1e-5)  # the disc's rim
    np.testing.assert_allclose(m.geom_pos[disc], [0, 0, -0.2], atol=1e-6)
