"""``symrom robot init``: a robot description written from a robot model alone (an MJCF or a URDF).

The model is read through MuJoCo's compiler (``robots.mjcf.compile_model``) and its roles are
found from its kinematic tree and joint axes, not from names:

- the base: the body with the free joint (a URDF's root link);
- the legs: the limbs hanging from the base, each a chain of three hinges whose axes, at
  zero joint angles in the base frame, are the base's x (hip abduction) then y, y (hip
  flexion, knee); ordered FR FL RR RL by their hips' positions (x fore, y left);
- the feet: the point of each leg farthest from its knee axis among the colliding spheres' centres,
  the origins of other colliding geoms small beside their distance from the knee (a mesh
  foot's: ``FOOT_SIZE``, not a shank's), the sites and the bodies below the knee (a
  URDF's: its links), named as a geom, a site or a body (with the point in the body's frame
  when the geom is unnamed); the radius: a sphere's there, else how far the foot's geoms reach
  beyond the point (``mjcf.reach``);
- the signs: +1 where a joint's axis points along symrom's (hx +x, hy and kn +y), else -1;
- the torque limits: the actuators' ``forcerange``, a torque motor's ``ctrlrange``, the
  joints' ``actuatorfrcrange`` (a URDF's ``effort``); joint damping, armature and friction
  loss: the model's;
- the stance: a keyframe (``home``, ``stand``, ``standing``, ``default``, or the only one)
  with its feet on the ground, else the leg IK at the Go1's standing height in proportion
  to leg length; the knee range: the model's where it is one-sided, else the side the
  keyframe bends the knees to, else the side of a position servo's ``ctrlrange`` or of the
  joint's reference angle (``ref``); a knee free both ways with none of these is refused.

Every value is written with a comment saying where it came from. What cannot be inferred is
refused (``RobotInitError``, one line naming it and the description key to give, which
``overrides`` then supplies). The description written is checked before it is kept: it
loads, its kinematics are MuJoCo's (the feet over random joint angles), and the leg IK
stands it at its height with the knees in range.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symrom.atomic import atomic_path, check_output_file
from symrom.names import LEG_JOINTS, LEGS, N_LEGS
from symrom.robots.description import (
    PYBULLET_DATA,
    RobotDescription,
    RobotDescriptionError,
    load_description,
    pybullet_data_path,
)
from symrom.robots.kinematics import LegKinematics
from symrom.robots.mjcf import (
    BaseFrame,
    Feet,
    RobotModelError,
    actuated,
    colliding,
    compile_model,
    foot_frames,
    name_of,
    subtree,
    torque_bound,
    zero_pose,
)

AXIS_COS = math.cos(math.radians(10.0))  # a joint axis within 10 degrees of the base's x or y plays that role
MIN_FOOT = 0.05  # m: a foot is at least this far from its knee axis
FOOT_SIZE = 0.2  # a foot geom other than a sphere is within this share of its distance from the knee in size
STAND_RATIO = 0.3165 / 0.426  # the Go1's standing height over its leg length (go1.toml)
KEYFRAMES = ("home", "stand", "standing", "default")  # keyframe names taken for the stance, in this order
KNEE_SIDE = (0.3, 2.8)  # rad: the built-ins' knee range |bounds|, on the side a keyframe bends to
CHECK_CONFIGS = 64  # random joint configurations of the kinematics check
CHECK_TOL = 1e-9  # m: the description's feet must be MuJoCo's within this
OVERRIDABLE = ("name", "stance.height", "stance.joints", "stance.knee", "limits.torque",
               "actuators.damping", "actuators.armature", "actuators.friction_loss")
_ROLE = {"hx": "hip abduction", "hy": "hip flexion", "kn": "knee"}


class RobotInitError(ValueError):
    """A robot model ``robot init`` cannot describe; the message names the model, what is
    missing and the description key to give by hand (``key``; None where the model itself
    must change)."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class RobotInit:
    """What ``init_robot`` wrote: ``path`` (the description), its ``text``, the
    ``description`` as loaded, ``kinematics_error`` m (the largest distance between the
    description's feet and MuJoCo's over ``CHECK_CONFIGS`` random joint configurations)
    and ``given`` (the keys taken from ``overrides``)."""

    path: Path
    text: str
    description: RobotDescription
    kinematics_error: float
    given: tuple[str, ...]


@dataclass
class _Leg:
    joints: list[int]  # hinge ids hx hy kn
    hip: np.ndarray  # (3,) the hip flexion axis's anchor, base frame
    signs: list[int]
    foot: dict  # kind -> (name, body name, local point)
    foot_point: np.ndarray  # (3,) base frame


class _Doc:
    """The description being written: TOML lines with their comments."""

    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def table(self, name: str, comment: str = "") -> None:
        self.lines += [("", ""), (f"[{name}]", comment)]

    def key(self, key: str, value, comment: str = "") -> None:
        self.lines.append((f"{key} = {_toml(value)}", comment))

    def text(self, header: list[str]) -> str:
        out = [f"# {h}" if h else "#" for h in header]
        width = max(len(v) for v, _ in self.lines if v)
        width = min(width, 44)
        for v, c in self.lines:
            out.append(f"{v:<{width}}  # {c}".rstrip() if c and v else (f"# {c}" if c else v))
        return "\n".join(out).replace("\n\n\n", "\n\n") + "\n"


def _toml(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        return repr(x) if not x.is_integer() else f"{x:.1f}"
    return "[" + ", ".join(_toml(x) for x in v) + "]"


def _num(x: float, digits: int | None = None) -> float:
    """A float for the file: the model's own value (``digits`` None), else rounded."""
    x = float(x) if digits is None else round(float(x), digits)
    return 0.0 if x == 0 else x


def _collapse(values: list, per: int = 3):
    """12 values -> 3 (per joint kind) when the four legs share them, or 1 when all 12 agree
    (``per`` 1: 4 values -> 1)."""
    n = len(values) // per
    rows = [values[per * k:per * k + per] for k in range(n)]
    if all(r == rows[0] for r in rows):
        return rows[0][0] if per == 1 else rows[0]
    return values


def _v3(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x + 0.0:+.3g}" for x in np.round(v, 3)) + ")"


# ---------------------------------------------------------------------- the model's tree
def _base(m, path: Path, urdf: bool) -> int:
    import mujoco

    free = [m.jnt_bodyid[j] for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) > 1:
        raise _err(path, f"{len(free)} bodies with free joints ({', '.join(name_of(m, 'body', b) for b in free)}); "
                         f"give the robot alone")
    roots = [b for b in range(1, m.nbody) if m.body_parentid[b] == 0]
    if free:
        base = int(free[0])
        if m.body_parentid[base] != 0:
            raise _err(path, f"the free body {name_of(m, 'body', base)!r} hangs from another body")
    elif len(roots) == 1:
        base = roots[0]
    else:
        raise _err(path, "no free joint and no single root body: cannot tell the base")
    if not name_of(m, "body", base):
        raise _err(path, "the base body has no name; name it in the model")
    if not urdf and any(m.geom_bodyid[g] == 0 for g in range(m.ngeom)):
        raise _err(path, "the model's world holds geoms (a scene's floor?): give the robot's own MJCF, "
                         "not a scene that includes it")
    inside = set(subtree(m, base))
    others = [name_of(m, "body", b) or f"#{b}" for b in range(1, m.nbody) if b not in inside]
    if others:
        raise _err(path, f"bodies outside the base body's subtree ({', '.join(others[:4])}): give the robot alone")
    return base


def _err(path: Path, what: str, key: str | None = None) -> RobotInitError:
    return RobotInitError(f"robot init {path}: {what}", key)


def _limbs(m, path: Path, base: int) -> list[list[int]]:
    """The limbs hanging from the base: per limb, its hinges from the base outwards."""
    import mujoco

    inside = subtree(m, base)
    hinges = []
    for b in inside:
        n, a = m.body_jntnum[b], m.body_jntadr[b]
        if b == base:
            continue
        if n > 1:
            raise _err(path, f"body {name_of(m, 'body', b)!r} moves by {n} joints; symrom's legs have one hinge "
                             f"per body")
        if n == 1:
            if m.jnt_type[a] != mujoco.mjtJoint.mjJNT_HINGE:
                raise _err(path, f"joint {name_of(m, 'joint', a)!r} is not a hinge; symrom's legs have hinges only")
            hinges.append(a)

    def above(j: int) -> list[int]:  # hinges between the base and joint j's body
        out, b = [], m.body_parentid[m.jnt_bodyid[j]]
        while b != base:
            out += [h for h in hinges if m.jnt_bodyid[h] == b]
            b = m.body_parentid[b]
        return out

    firsts = [j for j in hinges if not above(j)]
    limbs = []
    for j1 in firsts:
        below = set(subtree(m, m.jnt_bodyid[j1]))
        chain = sorted((h for h in hinges if m.jnt_bodyid[h] in below), key=lambda h: m.jnt_bodyid[h])
        serial = all(m.jnt_bodyid[chain[i]] in set(subtree(m, m.jnt_bodyid[chain[i - 1]])) and
                     len(above(chain[i])) == i for i in range(1, len(chain)))
        body = name_of(m, "body", m.jnt_bodyid[j1]) or f"#{m.jnt_bodyid[j1]}"
        if len(chain) != 3 or not serial:
            names = ", ".join(name_of(m, "joint", h) or f"#{h}" for h in chain)
            branches = "" if serial else " in branches"
            raise _err(path, f"the limb at body {body!r} has {len(chain)} hinge joints{branches} ({names}); "
                             f"symrom's legs have three in a row (hip abduction, hip flexion, knee)")
        limbs.append(chain)
    if len(limbs) != N_LEGS:
        names = ", ".join(name_of(m, "body", m.jnt_bodyid[c[0]]) for c in limbs)
        raise _err(path, f"{len(limbs)} legs ({names}); symrom's quadrupeds have four")
    return limbs


def _legs(m, path: Path, data, bf: BaseFrame, limbs: list[list[int]]) -> list[_Leg]:
    """The legs in symrom's order FR FL RR RL, their joints' roles checked by their axes."""
    legs = []
    for chain in limbs:
        signs = []
        for j, (role, e) in zip(chain, (("hx", 0), ("hy", 1), ("kn", 1))):
            a = bf.vector(data.xaxis[j])
            a = a / np.linalg.norm(a)
            if abs(a[e]) < AXIS_COS:
                raise _err(path, f"joint {name_of(m, 'joint', j)!r} ({_ROLE[role]} by its place in its leg) turns "
                                 f"about {_v3(a)} in the base frame, not the base's {'xy'[e]} axis")
            signs.append(1 if a[e] > 0 else -1)
        legs.append(_Leg(list(chain), bf.point(data.xanchor[chain[1]]), signs, {}, np.zeros(3)))
    hips = np.array([leg.hip for leg in legs])
    order = np.argsort(-hips[:, 0], kind="stable")
    front, rear = list(order[:2]), list(order[2:])
    if not hips[front, 0].min() > hips[rear, 0].max() + 1e-6:
        raise _err(path, "cannot tell the front legs from the rear ones by their hips' positions (x)")
    out = []
    for pair in (front, rear):
        ys = hips[pair, 1]
        if not (ys.min() < -1e-6 and ys.max() > 1e-6):
            raise _err(path, "cannot tell the right legs from the left ones by their hips' positions (y)")
        right, left = (pair[0], pair[1]) if ys[0] < ys[1] else (pair[1], pair[0])
        out += [legs[right], legs[left]]
    return out


def _foot(m, path: Path, data, bf: BaseFrame, leg: _Leg, label: str, urdf: bool) -> None:
    """The foot of ``leg``: its point and every way to name it (kind -> (name, body, local point))."""
    import mujoco

    knee = leg.joints[2]
    kb = m.jnt_bodyid[knee]
    below = subtree(m, kb)
    cands = []  # (point base frame, kind, name, body, local point)
    for b in below[1:]:
        cands.append((bf.point(data.xpos[b]), "body", name_of(m, "body", b), b, np.zeros(3)))
    if not urdf:
        knee_at = data.xanchor[knee]
        for g in range(m.ngeom):  # a sphere's centre; another compact shape's (a mesh foot's) its frame's origin
            if m.geom_bodyid[g] not in below or not colliding(m, g) or m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
                continue
            sphere = m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
            if sphere or m.geom_rbound[g] <= FOOT_SIZE * np.linalg.norm(data.geom_xpos[g] - knee_at):
                cands.append((bf.point(data.geom_xpos[g]), "geom", name_of(m, "geom", g), int(m.geom_bodyid[g]),
                              m.geom_pos[g].copy()))
        for s in range(m.nsite):
            if m.site_bodyid[s] in below:
                cands.append((bf.point(data.site_xpos[s]), "site", name_of(m, "site", s), int(m.site_bodyid[s]),
                              m.site_pos[s].copy()))
    anchor = bf.point(data.xanchor[knee])
    dist = [np.linalg.norm(c[0] - anchor) for c in cands]
    what = "a link below it" if urdf else "a sphere geom, a site or a body below it"
    key = "feet.link" if urdf else "feet.geom, feet.site or feet.body"
    if not cands or max(dist) < MIN_FOOT:
        raise _err(path, f"leg {label}: no foot at the end of knee joint {name_of(m, 'joint', knee)!r} ({what}, at "
                         f"least {MIN_FOOT} m from the knee); add one to the model (key {key})")
    P = cands[int(np.argmax(dist))][0]
    at = [c for c in cands if np.linalg.norm(c[0] - P) < 1e-6]
    foot = {}
    for _p, kind, name, body, local in at:
        if name and kind not in foot:
            foot[kind] = (name, name_of(m, "body", body), local)
        if kind != "body" and name_of(m, "body", body) and "body+point" not in foot:
            foot["body+point"] = (name_of(m, "body", body), name_of(m, "body", body), local)
    if not foot:
        raise _err(path, f"leg {label}: its foot (at {_v3(P)} m in the base frame) has no name, nor has its body; "
                         f"name it in the model (key {key})")
    leg.foot, leg.foot_point = foot, P


# ---------------------------------------------------------------------- names as templates
def _boundary(names: list[str], p: int, s: int) -> tuple[int, int]:
    """Widen the varying middle [p, len - s) of ``names`` to whole words (alphanumeric runs)."""
    while p > 0 and all(n[p - 1].isalnum() for n in names):
        p -= 1
    while s > 0 and all(n[len(n) - s].isalnum() for n in names):
        s -= 1
    return p, s


def _token_sets(names: list[str]) -> list[list[str]]:
    p = len(os.path.commonprefix(names))
    s = len(os.path.commonprefix([n[::-1] for n in names]))
    short = min(len(n) for n in names)
    if p + s > short:
        s = short - p
    out = []
    for pp, ss in (_boundary(names, p, s), (p, s)):  # whole words first: 'front_right', not 'front_righ'
        toks = [n[pp:len(n) - ss] for n in names]
        if all(toks) and len(set(toks)) == len(toks) and toks not in out:
            out.append(toks)
    return out


def _template(names: list[str], tokens: list[str]) -> str | None:
    """The one template ``t`` with ``t.format(leg=token) == name`` for every leg, or None."""
    if any("{" in n or "}" in n for n in names):
        return None
    ts = {n.replace(t, "{leg}") for n, t in zip(names, tokens)}
    if len(ts) != 1:
        return None
    t = ts.pop()
    return t if "{leg}" in t and all(t.format(leg=tok) == n for n, tok in zip(names, tokens)) else None


def _tokens(families: list[list[str]]) -> list[str] | None:
    for fam in families:
        for toks in _token_sets(fam):
            if all(_template(f, toks) for f in families):
                return toks
    return None


# ---------------------------------------------------------------------- writing
def _rel(path: Path, folder: Path) -> str:
    """How the description names ``path``: inside pybullet_data with its prefix, below the
    description's folder relative to it, else absolute."""
    path = path.resolve()
    try:
        data = pybullet_data_path("").resolve()
        if path.is_relative_to(data):
            return PYBULLET_DATA + path.relative_to(data).as_posix()
    except ImportError:
        pass
    rel = os.path.relpath(path, folder.resolve())
    return rel if not rel.startswith("..") else str(path)


def _keyframe(m) -> int | None:
    names = [m.key(i).name for i in range(m.nkey)]
    for want in KEYFRAMES:
        if want in names:
            return names.index(want)
    return 0 if m.nkey == 1 else None


def _check_override(path: Path, overrides: dict) -> dict:
    for k in overrides:
        if k not in OVERRIDABLE:
            raise _err(path, f"cannot give key {k!r}; keys one may give: {', '.join(OVERRIDABLE)}")
    return dict(overrides)


def init_robot(model: str | os.PathLike, out: str | os.PathLike, *, name: str | None = None,
               overrides: dict | None = None, force: bool = False, seed: int = 0) -> RobotInit:
    """Write the robot description ``out`` (TOML, format 2) of the robot model ``model`` (an
    MJCF, or a ``.urdf``) and return what was written (see the module docstring).

    name: the robot's name (default the model's); overrides: description keys to take as
    given instead of inferring them (``OVERRIDABLE``: e.g. ``{"stance.knee": [[-2.8, -0.3],
    [-2.8, -0.3], [0.3, 2.8], [0.3, 2.8]]}``); force: replace an existing ``out``; seed: the
    random joint configurations of the kinematics check. ``RobotInitError`` (one line) if
    the model cannot be described; nothing is written then.
    """
    import mujoco

    path = Path(model)
    out = Path(out)
    given = _check_override(path, overrides or {})
    if not path.is_file():
        raise _err(path, "no such file")
    urdf = path.suffix.lower() == ".urdf"
    check_output_file(out, force, inputs=(path,))
    try:
        m = compile_model(path)
    except RobotModelError as e:
        raise RobotInitError(f"robot init {e}") from None
    base = _base(m, path, urdf)
    data = zero_pose(m)
    bf = BaseFrame(data, base)
    legs = _legs(m, path, data, bf, _limbs(m, path, base))
    labels = [leg.upper() for leg in LEGS]
    jname = [[name_of(m, "joint", j) for j in leg.joints] for leg in legs]
    for leg, label, names in zip(legs, labels, jname):
        for j, role, n in zip(leg.joints, LEG_JOINTS, names):
            if not n:
                raise _err(path, f"the {_ROLE[role]} joint of leg {label} has no name; name it in the model")
            if not urdf and not actuated(m, j):
                raise _err(path, f"joint {n!r} ({_ROLE[role]} of leg {label}) has no actuator; symrom drives "
                                 f"all 12 leg joints")
        _foot(m, path, data, bf, leg, label, urdf)
    tokens = _tokens([[jname[k][r] for k in range(N_LEGS)] for r in range(3)])
    if tokens is None:
        raise _err(path, f"the leg joints' names ({', '.join(n for names in jname for n in names[:1])}, ...) share "
                         f"no pattern with the leg as its only difference; rename them in the model (keys legs, "
                         f"joints)")
    templates = [_template([jname[k][r] for k in range(N_LEGS)], tokens) for r in range(3)]

    # the feet, named the first way all four legs share
    feet = None
    for kind in (("link",) if urdf else ("geom", "site", "body", "body+point")):
        src = "body" if kind == "link" else kind
        if not all(src in leg.foot for leg in legs):
            continue
        t = _template([leg.foot[src][0] for leg in legs], tokens)
        if t is None:
            continue
        if kind == "body+point":
            pts = [tuple(_num(x) for x in leg.foot[src][2]) for leg in legs]
            feet = ("body", t, pts[0] if all(p == pts[0] for p in pts) else pts)
        else:
            feet = (kind, t, None)
        break
    if feet is None:
        names = [next(iter(leg.foot.values()))[0] for leg in legs]
        raise _err(path, f"the feet's names ({', '.join(names)}) share no pattern with the legs' joints "
                         f"({', '.join(tokens)}); rename them in the model (key feet)")
    feet_rec = Feet(feet[0], tuple(feet[1].format(leg=tok) for tok in tokens),
                    None if feet[2] is None else (tuple(feet[2]) if isinstance(feet[2], list) else (feet[2],) * 4))
    frames = foot_frames(m, feet_rec)
    radius = frames[0].radius

    # torque limits, actuator effects
    torque, sources = [], set()
    for leg, label, names in zip(legs, labels, jname):
        for j, role, n in zip(leg.joints, LEG_JOINTS, names):
            bound, src = torque_bound(m, j)
            if not np.isfinite(bound) and "limits.torque" not in given:
                raise _err(path, f"joint {n!r} ({_ROLE[role]} of leg {label}): the model bounds no torque on it "
                                 f"(actuator forcerange, motor ctrlrange, joint actuatorfrcrange"
                                 f"{', URDF effort' if urdf else ''}); give key 'limits.torque'", "limits.torque")
            torque.append(_num(bound))
            sources |= {f"{w.split(' ')[0]} {w.split(' ')[-1]}" for w in src.split(", ") if w}
    dof = [m.jnt_dofadr[j] for leg in legs for j in leg.joints]
    effects = {"damping": [_num(m.dof_damping[d]) for d in dof],
               "armature": [_num(m.dof_armature[d]) for d in dof],
               "friction_loss": [_num(m.dof_frictionloss[d]) for d in dof]}
    signs = [s for leg in legs for s in leg.signs]
    jids = [j for leg in legs for j in leg.joints]
    qadr = [int(m.jnt_qposadr[j]) for j in jids]

    # the stance: a keyframe, else the leg IK at a height in proportion to leg length
    key = None if urdf else _keyframe(m)
    kq = None if key is None else np.asarray(m.key_qpos[key])[qadr] * np.asarray(signs, dtype=float)
    knees, knee_note = _knee_ranges(m, path, legs, labels, jname, kq, key, given)
    hy_kn = [np.linalg.norm(bf.point(data.xanchor[leg.joints[2]]) - leg.hip) for leg in legs]
    kn_ft = [np.linalg.norm(leg.foot_point - bf.point(data.xanchor[leg.joints[2]])) for leg in legs]
    leg_length = float(np.mean(np.add(hy_kn, kn_ft)))
    if kq is not None:
        d2 = mujoco.MjData(m)
        d2.qpos[:] = data.qpos
        d2.qpos[qadr] = np.asarray(m.key_qpos[key])[qadr]
        mujoco.mj_kinematics(m, d2)
        bf2 = BaseFrame(d2, base)
        z = [bf2.point(d2.xpos[f.body] + d2.xmat[f.body].reshape(3, 3) @ f.point)[2] for f in frames]
        height = _num(radius - float(np.mean(z)), 4)
        free = [jj for jj in range(m.njnt) if m.jnt_type[jj] == mujoco.mjtJoint.mjJNT_FREE]
        kz = f"; the keyframe's own base height {m.key_qpos[key][m.jnt_qposadr[free[0]] + 2]:.4g} m" if free else ""
        height_note = f"m: keyframe {m.key(key).name!r} with its feet on the ground (radius {radius:.4g} m){kz}"
        stance_joints = [_num(x) for x in kq]
        joints_note = f"rad: keyframe {m.key(key).name!r}, in symrom's signs"
    else:
        height = _num(STAND_RATIO * leg_length, 4)
        height_note = (f"m: the Go1's standing height in proportion to leg length ({leg_length:.4g} m; "
                       f"{'a URDF has' if urdf else 'the model has'} no standing keyframe)")
        stance_joints = []
        for lo, hi in knees:  # where the leg IK starts: the knee mid-range, the foot under the hip
            kn = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else (-1.6 if hi <= 0 else 1.6)
            stance_joints += [0.0, _num(-0.5 * kn, 4), _num(kn, 4)]
        joints_note = "rad: the leg IK's standing pose at that height"

    folder = out.parent if str(out.parent) else Path(".")
    robot_name = name or m.names.split(b"\x00")[0].decode()
    if robot_name in ("MuJoCo Model", ""):
        robot_name = path.stem
    mass = float(m.body_subtreemass[base])

    def render(stance_joints: list[float]) -> str:
        doc = _Doc()

        def put(key: str, value, comment: str) -> None:
            doc.key(key.split(".")[-1], *((given[key], "given") if key in given else (value, comment)))

        doc.key("format", 2)
        put("name", robot_name, "given" if name else "the model's name")
        if urdf:
            doc.key("urdf", _rel(path, folder), "the robot model (geometry, masses, inertias)")
        else:
            doc.key("mjcf", _rel(path, folder), "the robot model; symrom derives a URDF from it once (cached)")
        doc.key("base_link", name_of(m, "body", base), "the root link" if urdf else "the body with the free joint")
        doc.table("legs", "by the hips' positions in the base frame (x fore, y left)")
        for leg, label, tok in zip(legs, labels, tokens):
            doc.key(label.lower(), tok, f"hip at x {leg.hip[0]:+.4g}, y {leg.hip[1]:+.4g} m")
        doc.table("joints", "each leg's three hinges from the base out, by their axes at zero angles")
        for r, role in enumerate(LEG_JOINTS):
            axes = sorted({_v3(_unit(bf.vector(data.xaxis[leg.joints[r]]))) for leg in legs})
            doc.key(role, templates[r], f"{_ROLE[role]}: about {' or '.join(axes)} (base frame)")
        doc.table("feet", "each leg's point farthest from its knee axis")
        if feet[0] == "body" and feet[2] is not None:
            doc.key("body", feet[1], "the body holding each foot (whose geom or site has no name)")
            doc.key("point", feet[2], "m: the foot's centre in that body's frame" +
                    (f", radius {radius:.4g} m" if radius else ""))
        else:
            doc.key(feet[0], feet[1], f"the {_KIND_TEXT[feet[0]]} at the legs' ends" +
                    (f", radius {radius:.4g} m" if radius else ""))
        doc.table("signs", "from the axes: symrom angle = sign x model angle (hx about +x, hy, kn +y)")
        for r, role in enumerate(LEG_JOINTS):
            v = _collapse([legs[k].signs[r] for k in range(N_LEGS)], per=1)
            doc.key(role, v, "" if isinstance(v, int) else "FR FL RR RL")
        doc.table("stance")
        put("stance.height", height, height_note)
        put("stance.joints", _collapse(stance_joints), joints_note)
        same = all(k == knees[0] for k in knees)
        put("stance.knee", list(knees[0]) if same else [list(k) for k in knees],
            knee_note + ("" if same else ": FR FL RR RL"))
        doc.table("limits")
        put("limits.torque", _collapse(torque), "N m: " + ", ".join(_SRC_TEXT[urdf].get(w, w) for w in sorted(sources)))
        if any(any(v) for v in effects.values()) or any(k.startswith("actuators.") for k in given):
            doc.table("actuators", "the model's joint properties")
            for k, v in effects.items():
                put(f"actuators.{k}", _collapse(v), _EFFECT_TEXT[k])
        else:
            doc.lines += [("", ""), ("", "no [actuators]: the model states no joint damping, armature or "
                                         "friction loss")]
        return doc.text([f"symrom robot description (format 2), written by `symrom robot init` from {path.name}.",
                         f"Total mass {mass:.4g} kg (the model's bodies). docs/design.md, \"Robot description file\", "
                         f"says what", "each key means; each comment says where its value came from."])

    with atomic_path(out, suffix=".toml") as tmp:
        text = render(stance_joints)
        tmp.write_text(text)
        desc = _load(tmp, path)
        kin = _kinematics(desc)
        if key is None and "stance.joints" not in given:  # the leg IK's standing pose, written back
            from symrom.robots.stance import stand

            text = render([_num(x, 4) for x in stand(desc, kin)])
            tmp.write_text(text)
            desc = _load(tmp, path)
        error = _check_kinematics(m, base, kin, jids, signs, seed, frames)
        if not error <= CHECK_TOL:
            raise _err(path, f"the description's feet are {error:.3g} m from MuJoCo's (tolerance {CHECK_TOL:g} m)")
        _check_stance(path, desc, kin)
    return RobotInit(out, text, _load(out, path), error, tuple(given))


_KIND_TEXT = {"link": "links", "geom": "sphere geoms", "site": "sites", "body": "bodies"}
_SRC_TEXT = {False: {"actuator forcerange": "the actuators' forcerange (x gear)",
                     "motor ctrlrange": "the torque motors' ctrlrange (x gain x gear)",
                     "joint actuatorfrcrange": "the joints' actuatorfrcrange"},
             True: {"joint actuatorfrcrange": "the URDF's effort"}}
_EFFECT_TEXT = {"damping": "N m s/rad: joint damping", "armature": "kg m^2: armature (reflected rotor inertia)",
                "friction_loss": "N m: joint friction loss"}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _knee_ranges(m, path: Path, legs: list[_Leg], labels: list[str], jname: list[list[str]], kq, key,
                 given: dict) -> tuple[list[tuple[float, float]], str]:
    """Per leg the knee range (symrom's signs) and where it came from: the model's range where
    it lies on one side of zero, else the side the keyframe ``kq`` (12,) bends the knee to."""
    if "stance.knee" in given:
        v = given["stance.knee"]
        rows = v if isinstance(v[0], (list, tuple)) else [v] * N_LEGS
        return [tuple(float(x) for x in r) for r in rows], "given"
    knees, note = [], ""
    for k, (leg, label) in enumerate(zip(legs, labels)):
        j, s = leg.joints[2], leg.signs[2]
        lo, hi = sorted(s * np.asarray(m.jnt_range[j], dtype=float)) if m.jnt_limited[j] else (-np.inf, np.inf)
        if hi <= 0 or lo >= 0:
            knees.append((_num(lo), _num(hi)))
            note = "rad: the knee joints' range in the model, in symrom's signs"
            continue
        side, whence = _knee_side(m, j, s, None if kq is None else kq[3 * k + 2], key)
        if side == 0:
            why = "the model has no standing keyframe" if kq is None else "the keyframe holds it straight"
            rng = f"range [{lo:.3g}, {hi:.3g}] rad" if m.jnt_limited[j] else "no range"
            raise _err(path, f"knee joint {jname[k][2]!r} of leg {label} may bend either way ({rng}), {why} "
                             f"and no servo range or reference angle says which: give key 'stance.knee' "
                             f"([lower, upper] rad, or one per leg FR FL RR RL)", "stance.knee")
        a, b = (-KNEE_SIDE[1], -KNEE_SIDE[0]) if side < 0 else KNEE_SIDE
        knees.append((_num(max(a, lo)), _num(min(b, hi))))
        note = f"rad: the built-ins' range, on the side {whence} bends the knees to (the model's range is both ways)"
    return knees, note


def _knee_side(m, joint: int, sign: int, key_angle: float | None, key: int | None) -> tuple[int, str]:
    """Which way (-1, +1, in symrom's signs; 0: cannot tell) knee hinge ``joint`` bends, and what
    says so: the keyframe's angle ``key_angle`` (symrom's signs), else a position servo's
    ``ctrlrange`` on one side of zero, else the joint's reference angle."""
    import mujoco

    if key_angle is not None and abs(key_angle) >= 0.05:
        return (1 if key_angle > 0 else -1), f"keyframe {m.key(key).name!r}"
    for a in range(m.nu):
        servo = (m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and m.actuator_trnid[a, 0] == joint
                 and m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE and m.actuator_biasprm[a, 1] < 0
                 and m.actuator_ctrllimited[a])
        if servo:
            lo, hi = sorted(sign * np.asarray(m.actuator_ctrlrange[a], dtype=float))
            if hi <= 0 or lo >= 0:
                return (1 if lo >= 0 else -1), f"the position servo's ctrlrange of {name_of(m, 'joint', joint)!r}"
    ref = sign * float(m.qpos0[m.jnt_qposadr[joint]])
    if abs(ref) >= 0.05:
        return (1 if ref > 0 else -1), "the joint's reference angle (ref)"
    return 0, ""


def _load(p: Path, model: Path) -> RobotDescription:
    try:
        return load_description(p)
    except RobotDescriptionError as e:
        raise RobotInitError(f"robot init {model}: the description written does not load ({e})") from None


def _kinematics(desc: RobotDescription) -> LegKinematics:
    return LegKinematics(desc.urdf_path, desc.base_link, list(desc.joint_names), list(desc.foot_links),
                         desc.joint_signs)


def _check_kinematics(m, base: int, kin: LegKinematics, jids: list[int], signs: list[int], seed: int,
                      frames) -> float:
    """Largest distance (m) between the description's feet (symrom angles) and MuJoCo's (model
    angles = sign x symrom angles), over random configurations within the joints' ranges."""
    import mujoco

    rng = np.random.default_rng(seed)
    d = zero_pose(m)
    qpos0 = d.qpos.copy()
    rng_lo = np.array([m.jnt_range[j][0] if m.jnt_limited[j] else -np.pi for j in jids])
    rng_hi = np.array([m.jnt_range[j][1] if m.jnt_limited[j] else np.pi for j in jids])
    qm = rng.uniform(np.maximum(rng_lo, -np.pi), np.minimum(rng_hi, np.pi), size=(CHECK_CONFIGS, len(jids)))
    ours = kin.foot_positions(qm * np.asarray(signs, dtype=float))
    qadr = [m.jnt_qposadr[j] for j in jids]
    worst = 0.0
    for i in range(CHECK_CONFIGS):
        d.qpos[:] = qpos0
        d.qpos[qadr] = qm[i]
        mujoco.mj_kinematics(m, d)
        bf = BaseFrame(d, base)
        theirs = np.array([bf.point(d.xpos[f.body] + d.xmat[f.body].reshape(3, 3) @ f.point) for f in frames])
        worst = max(worst, float(np.abs(ours[i] - theirs).max()))
    return worst


def _check_stance(path: Path, desc: RobotDescription, kin: LegKinematics) -> None:
    from symrom.robots.stance import feet_under_hips, stand

    q = stand(desc, kin)
    target = feet_under_hips(kin)
    target[:, 2] = -(desc.start_height - desc.foot_radius)
    miss = float(np.abs(kin.foot_positions(q[None])[0] - target).max())
    lo, hi = desc.knee_range
    if miss > 1e-5 or np.any(q[2::3] < lo - 1e-9) or np.any(q[2::3] > hi + 1e-9):
        raise _err(path, f"the leg IK cannot stand the robot at {desc.start_height:.4g} m with the knees in "
                         f"{desc.knee_ranges[0]} rad (the feet miss by {miss:.3g} m); give key 'stance.height' "
                         f"or 'stance.knee'", "stance.height")


__all__ = ["OVERRIDABLE", "RobotInit", "RobotInitError", "init_robot"]
