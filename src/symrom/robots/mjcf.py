"""Robot models read through MuJoCo's compiler: MJCF files (and URDFs) as kinematic trees, their
feet, and the URDF derived from an MJCF.

A robot given only as an MJCF (a MuJoCo Menagerie model, say) still needs a URDF for what
reads one: the leg kinematics (``robots.kinematics``), the controllers' body model and leg
gravity (PyBullet's parser and inverse dynamics, ``sim/dynamics.py``). ``derived_urdf``
writes that URDF once from the MJCF's compiled model and keeps it in a disk cache keyed by
the MJCF's content, so the MJCF stays the one source of the robot: every body of the base's
subtree becomes a link (its mass, centre of mass and principal inertia as compiled; the base's
on a fixed child link, ``BASE_INERTIA``, as PyBullet would otherwise turn the base's frame into
its principal axes), every hinge a revolute joint (its axis, range and torque bound), every jointless body a fixed
joint, and each foot a link of its own at the foot's point (``FOOT_LINK``) with a collision
sphere of the foot's radius. Link frames sit at the joint axes and are parallel to the base
frame at zero joint angles (no rotations in the URDF's origins), so the URDF's kinematics are
MuJoCo's to rounding; a URDF angle is the MJCF joint's ``qpos`` (whatever its ``ref``).

MuJoCo is imported only by the functions that use it. Lengths m, angles rad, masses kg.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.names import LEGS

FOOT_LINK = "symrom_foot_{leg}"  # the link (URDF) or frame body (MuJoCo world) of a foot; leg: names.LEGS
BASE_INERTIA = "symrom_base_inertia"  # the derived URDF's link holding the base body's mass and inertia
FOOT_KINDS = ("link", "body", "geom", "site")  # what a description's [feet] may name
DERIVATION = 2  # the derived URDF's version: part of its cache key
CACHE_ENV = "SYMROM_CACHE_DIR"  # shared with the generated code's cache (model/codegen.py)
_SAME_POINT = 1e-6  # m: a geom this near a foot's point is the foot's own
_NO_LIMIT = np.inf
_MASSLESS = '<inertial><mass value="0"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial>'


class RobotModelError(ValueError):
    """A robot model MuJoCo cannot read, or one that lacks what a description names; ``key``:
    the description key concerned (None: the model as a whole)."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class Feet:
    """Where a description puts the feet (its ``[feet]`` table).

    kind: ``link`` (a URDF link; in an MJCF, the body of that name), ``body``, ``geom`` or
    ``site`` (elements of an MJCF); names (4,): per leg FR FL RR RL; points: with ``body``,
    the foot's point in each body's frame (4 x (3,) m), None for the bodies' origins.
    """

    kind: str
    names: tuple[str, ...]
    points: tuple[tuple[float, float, float], ...] | None = None


@dataclass(frozen=True)
class FootFrame:
    """One foot in a compiled model: ``body`` (id) and ``body_name`` it moves with, ``point``
    (3,) m in that body's frame, ``geoms`` (ids) that touch the ground for it, ``radius`` m of
    its sphere (0 if it has none)."""

    body: int
    body_name: str
    point: np.ndarray
    geoms: tuple[int, ...]
    radius: float


def _mujoco():
    import mujoco

    return mujoco


def _one_line(e: Exception) -> str:
    return "; ".join(s.strip() for s in str(e).splitlines() if s.strip())


def missing_files(spec, root: Path) -> list[str]:
    """The files an MJCF's assets name (meshes, textures, height fields, skins) that are not
    there, as the model names them; ``root``: the model's folder."""
    out = []
    for kind, folder in (("meshes", spec.meshdir), ("textures", spec.texturedir), ("hfields", spec.meshdir),
                         ("skins", spec.meshdir)):
        for a in getattr(spec, kind):
            files = [f for f in ([a.file] if isinstance(a.file, str) else list(a.file)) if f]
            for f in files:
                if not any((base / f).is_file() for base in (root / folder, root)):
                    out.append(str(Path(folder) / f) if folder else f)
    return out


def drop_missing_meshes(spec, root: Path) -> None:
    """Delete from the ``MjSpec`` ``spec`` the meshes whose files are not found (in its mesh
    folder or beside it, relative to ``root``) and the geoms that use them: a URDF's collision
    meshes, where its primitives stand in."""
    mujoco = _mujoco()
    missing = {m.name for m in spec.meshes
               if m.file and not (root / spec.meshdir / m.file).is_file() and not (root / m.file).is_file()}
    for g in list(spec.geoms):
        if g.type == mujoco.mjtGeom.mjGEOM_MESH and g.meshname in missing:
            spec.delete(g)
    for m in list(spec.meshes):
        if m.name in missing:
            spec.delete(m)


def compile_model(path: str | os.PathLike):
    """The compiled ``MjModel`` of an MJCF or, for a ``.urdf``, of a URDF as MuJoCo reads it
    (fixed links kept as bodies, visual geoms and collision meshes whose files are missing
    dropped, impossible inertias balanced). ``RobotModelError`` if MuJoCo cannot read it (an
    MJCF whose mesh or texture files are missing: naming them)."""
    mujoco = _mujoco()
    path = Path(path)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as e:
        raise RobotModelError(f"{path}: MuJoCo cannot read it ({_one_line(e)})") from None
    if path.suffix.lower() != ".urdf":
        missing = missing_files(spec, path.parent)
        if missing:
            more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
            raise RobotModelError(f"{path}: files it names are missing ({', '.join(missing[:3])}{more}; relative "
                                  f"to {path.parent}): MuJoCo cannot read it without them; keep the model's folder "
                                  f"whole (a Menagerie model: its assets folder beside its XML)")
    try:
        if path.suffix.lower() == ".urdf":
            spec.compiler.fusestatic = False  # the foot links must stay bodies
            spec.compiler.discardvisual = True
            spec.compiler.balanceinertia = True
            drop_missing_meshes(spec, path.parent)
        return spec.compile()
    except ValueError as e:
        raise RobotModelError(f"{path}: MuJoCo cannot read it ({_one_line(e)})") from None


def zero_pose(model):
    """``MjData`` of ``model`` after MuJoCo's kinematics with every hinge at ``qpos`` 0 (the
    joints' zero, whatever their ``ref``) and free joints at the origin, unturned."""
    mujoco = _mujoco()
    d = mujoco.MjData(model)
    d.qpos[:] = 0.0
    for j in range(model.njnt):
        adr = model.jnt_qposadr[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            d.qpos[adr + 3] = 1.0
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            d.qpos[adr] = 1.0
    mujoco.mj_kinematics(model, d)
    return d


class BaseFrame:
    """Positions and directions of a posed model in its base body's frame."""

    def __init__(self, data, base: int):
        self.p = data.xpos[base].copy()
        self.R = data.xmat[base].reshape(3, 3).copy()

    def point(self, x: np.ndarray) -> np.ndarray:
        """World point(s) (..., 3) -> base frame."""
        return (np.asarray(x) - self.p) @ self.R

    def vector(self, v: np.ndarray) -> np.ndarray:
        """World direction(s) (..., 3) -> base frame."""
        return np.asarray(v) @ self.R

    def matrix(self, M: np.ndarray) -> np.ndarray:
        """World orientation (3, 3) -> base frame."""
        return self.R.T @ M


def name_of(model, kind: str, i: int) -> str:
    """The name of element ``i`` of ``kind`` ('body', 'joint', 'geom', 'site', 'actuator'), '' if none."""
    return getattr(model, kind)(i).name


def element_id(model, kind: str, name: str) -> int:
    mujoco = _mujoco()
    obj = {"body": mujoco.mjtObj.mjOBJ_BODY, "joint": mujoco.mjtObj.mjOBJ_JOINT,
           "geom": mujoco.mjtObj.mjOBJ_GEOM, "site": mujoco.mjtObj.mjOBJ_SITE}[kind]
    return mujoco.mj_name2id(model, obj, name)


def colliding(model, g: int) -> bool:
    """Whether geom ``g`` takes part in contacts (not a visual-only geom)."""
    return bool(model.geom_contype[g] or model.geom_conaffinity[g])


def _sphere(model, g: int) -> bool:
    return model.geom_type[g] == _mujoco().mjtGeom.mjGEOM_SPHERE


def _geoms_at(model, body: int, point: np.ndarray) -> tuple[list[int], float]:
    """The colliding geoms of ``body`` centred at ``point`` (body frame; all its colliding geoms
    when none is) and the foot's radius: that of the first sphere centred there, else how far
    those geoms reach beyond the point (``reach``)."""
    own = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body and colliding(model, g)]
    at = [g for g in own if np.linalg.norm(model.geom_pos[g] - point) < _SAME_POINT]
    radius = next((float(model.geom_size[g, 0]) for g in at if _sphere(model, g)), None)
    return (at or own), (reach(model, at or own, point) if radius is None else radius)


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    R = np.empty(9)
    _mujoco().mju_quat2Mat(R, np.asarray(q, dtype=float))
    return R.reshape(3, 3)


def _support(model, g: int, d: np.ndarray) -> float:
    """How far geom ``g`` extends along the unit direction d (3,), in its body's frame (m from the
    body's origin); -inf for a plane or height field."""
    mujoco = _mujoco()
    t, size, p = model.geom_type[g], model.geom_size[g], model.geom_pos[g]
    dl = _quat_matrix(model.geom_quat[g]).T @ d  # d in the geom's frame
    G = mujoco.mjtGeom
    if t == G.mjGEOM_SPHERE:
        return p @ d + size[0]
    if t == G.mjGEOM_CAPSULE:
        return p @ d + size[1] * abs(dl[2]) + size[0]
    if t == G.mjGEOM_CYLINDER:
        return p @ d + size[1] * abs(dl[2]) + size[0] * np.hypot(dl[0], dl[1])
    if t == G.mjGEOM_BOX:
        return p @ d + float(np.abs(dl) @ size)
    if t == G.mjGEOM_ELLIPSOID:
        return p @ d + float(np.linalg.norm(size * dl))
    if t == G.mjGEOM_MESH:
        m = model.geom_dataid[g]
        a, n = model.mesh_vertadr[m], model.mesh_vertnum[m]
        return p @ d + float((model.mesh_vert[a:a + n] @ dl).max())
    return -np.inf


def reach(model, geoms, point: np.ndarray) -> float:
    """A foot's radius where no sphere is centred at its point (3,) (body frame): how far the
    ``geoms`` reach beyond it, away from the body's origin (the knee, for a shank), m; 0 when they
    do not (or the point is the origin). A capsule's or a disc's rounded end around the point
    gives its radius."""
    n = float(np.linalg.norm(point))
    if n < _SAME_POINT or not len(geoms):
        return 0.0
    d = np.asarray(point, dtype=float) / n
    return max(0.0, max(_support(model, g, d) for g in geoms) - n)


def foot_frames(model, feet: Feet) -> list[FootFrame]:
    """The four feet ``feet`` names, found in the compiled ``model`` (FR FL RR RL).

    link/body: the body (at ``feet.points`` in it, else its origin), touching the ground with
    its colliding geoms centred at that point (a link: all of them, as a URDF foot link holds
    its sphere alone); geom: that geom; site: the site's body at the site, with the body's
    geoms centred there. The radius: a sphere's centred there, else how far the foot's geoms
    reach beyond the point (``reach``: a capsule's end, a mesh). ``RobotModelError`` (key
    ``feet.<kind>``) naming a missing element."""
    key = f"feet.{feet.kind}"
    out = []
    for k, name in enumerate(feet.names):
        kind = "body" if feet.kind == "link" else feet.kind
        i = element_id(model, kind, name)
        if i < 0:
            raise RobotModelError(f"the model has no {kind} {name!r}", key)
        if kind == "body":
            point = np.zeros(3) if feet.points is None else np.asarray(feet.points[k], dtype=float)
            if feet.kind == "link":
                geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == i and colliding(model, g)]
                radius = next((float(model.geom_size[g, 0]) for g in geoms if _sphere(model, g)), 0.0)
            else:
                geoms, radius = _geoms_at(model, i, point)
            out.append(FootFrame(i, name, point, tuple(geoms), radius))
        elif kind == "geom":
            body = int(model.geom_bodyid[i])
            radius = float(model.geom_size[i, 0]) if _sphere(model, i) else reach(model, [i], model.geom_pos[i])
            out.append(FootFrame(body, name_of(model, "body", body), model.geom_pos[i].copy(), (i,), radius))
        else:
            body = int(model.site_bodyid[i])
            point = model.site_pos[i].copy()
            geoms, radius = _geoms_at(model, body, point)
            out.append(FootFrame(body, name_of(model, "body", body), point, tuple(geoms), radius))
    return out


def torque_bound(model, joint: int) -> tuple[float, str]:
    """The largest torque (N m, symmetric: the smaller side of an uneven range) the model lets
    its actuators put on hinge ``joint``, and what sets it: an actuator's ``forcerange`` (times
    its gear), a torque motor's ``ctrlrange`` (times gain and gear), the joint's
    ``actuatorfrcrange`` (a URDF's ``effort``), the tightest of those that apply; (inf, '')
    when nothing bounds it. Several actuators on one joint add up."""
    mujoco = _mujoco()
    total, sources, seen = 0.0, [], False
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT or model.actuator_trnid[a, 0] != joint:
            continue
        seen = True
        gear = abs(float(model.actuator_gear[a, 0]))
        name = name_of(model, "actuator", a) or f"#{a}"
        if model.actuator_forcelimited[a]:
            lo, hi = model.actuator_forcerange[a]
            total += gear * min(-lo, hi)
            sources.append(f"actuator {name!r} forcerange")
        elif (model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
              and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE and model.actuator_ctrllimited[a]):
            lo, hi = model.actuator_ctrlrange[a]
            total += gear * abs(float(model.actuator_gainprm[a, 0])) * min(-lo, hi)
            sources.append(f"motor {name!r} ctrlrange")
        else:
            total = _NO_LIMIT
    if not seen:
        total = _NO_LIMIT
    if model.jnt_actfrclimited[joint]:
        lo, hi = model.jnt_actfrcrange[joint]
        if min(-lo, hi) < total:
            total, sources = min(-lo, hi), ["joint actuatorfrcrange"]
    if not np.isfinite(total) or total <= 0:
        return _NO_LIMIT, ""
    return float(total), ", ".join(sources)


def actuated(model, joint: int) -> bool:
    """Whether an actuator of ``model`` drives hinge ``joint``."""
    mujoco = _mujoco()
    return any(model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and model.actuator_trnid[a, 0] == joint
               for a in range(model.nu))


def subtree(model, root: int) -> list[int]:
    """Bodies of ``root``'s subtree, ``root`` first, parents before children (MuJoCo's order)."""
    inside = {root}
    for b in range(root + 1, model.nbody):
        if model.body_parentid[b] in inside:
            inside.add(b)
    return sorted(inside)


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """URDF's roll, pitch, yaw (rad) of rotation R (3, 3) = Rz(yaw) Ry(pitch) Rx(roll), well
    conditioned near pitch +-pi/2 (yaw 0 at the singularity itself)."""
    cp = np.hypot(R[0, 0], R[1, 0])
    pitch = np.arctan2(-R[2, 0], cp)
    if cp > 1e-12:
        return np.array([np.arctan2(R[2, 1], R[2, 2]), pitch, np.arctan2(R[1, 0], R[0, 0])])
    return np.array([np.arctan2(-R[1, 2], R[1, 1]), pitch, 0.0])


def _f(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def _v(v) -> str:
    return " ".join(_f(x) for x in v)


def urdf_text(model, base: str, joint_names: tuple[str, ...], feet: Feet, name: str,
              note: str = "") -> str:
    """The URDF of ``model`` (compiled MJCF) seen from body ``base``: see the module docstring.
    joint_names (12): the legs' hinges (checked to exist); feet: where the feet are.
    ``RobotModelError`` naming the description key of a missing or unfit element."""
    mujoco = _mujoco()
    b0 = element_id(model, "body", base)
    if b0 < 0:
        raise RobotModelError(f"the model has no body {base!r}", "base_link")
    for k, j in enumerate(joint_names):
        jid = element_id(model, "joint", j)
        if jid < 0:
            raise RobotModelError(f"the model has no joint {j!r}", f"joints.{('hx', 'hy', 'kn')[k % 3]}")
        if model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
            raise RobotModelError(f"joint {j!r} is not a hinge", f"joints.{('hx', 'hy', 'kn')[k % 3]}")
    frames = foot_frames(model, feet)
    data = zero_pose(model)
    bf = BaseFrame(data, b0)
    bodies = subtree(model, b0)
    names: dict[int, str] = {}
    for b in bodies:
        names[b] = name_of(model, "body", b) or f"symrom_body_{b}"
    origin: dict[int, np.ndarray] = {}  # link origin, base frame, zero pose
    lines = ['<?xml version="1.0"?>', f"<!-- {note} -->" if note else "", f'<robot name="{name}">']
    for b in bodies:
        nj, ja = model.body_jntnum[b], model.body_jntadr[b]
        kinds = [model.jnt_type[ja + i] for i in range(nj)]
        if b == b0:
            if any(t != mujoco.mjtJoint.mjJNT_FREE for t in kinds):
                raise RobotModelError(f"the base body {base!r} has joints other than a free joint", "base_link")
            origin[b] = np.zeros(3)
        elif nj == 0:
            origin[b] = bf.point(data.xpos[b])
        elif nj == 1 and kinds[0] == mujoco.mjtJoint.mjJNT_HINGE:
            origin[b] = bf.point(data.xanchor[ja])
        else:
            raise RobotModelError(f"body {names[b]!r} moves by joints a URDF cannot hold (only one hinge "
                                  f"per body)", None)
        # the body's inertia in its link frame (parallel to the base frame at zero angles)
        R = bf.matrix(data.ximat[b].reshape(3, 3))
        c = bf.point(data.xipos[b]) - origin[b]
        I = model.body_inertia[b]
        inertial = (f'<inertial><origin xyz="{_v(c)}" rpy="{_v(matrix_to_rpy(R))}"/>'
                    f'<mass value="{_f(model.body_mass[b])}"/>'
                    f'<inertia ixx="{_f(I[0])}" iyy="{_f(I[1])}" izz="{_f(I[2])}" ixy="0" ixz="0" iyz="0"/></inertial>')
        if b == b0:
            # PyBullet takes a base's principal axes for its frame (its inverse dynamics then read gravity
            # in them): the base link holds no mass; its body's inertia hangs on a fixed child.
            lines += [f'  <link name="{names[b]}">{_MASSLESS}</link>',
                      f'  <link name="{BASE_INERTIA}">{inertial}</link>',
                      f'  <joint name="{BASE_INERTIA}_joint" type="fixed"><origin xyz="0 0 0" rpy="0 0 0"/>'
                      f'<parent link="{names[b]}"/><child link="{BASE_INERTIA}"/></joint>']
            continue
        lines += [f'  <link name="{names[b]}">{inertial}</link>']
        parent = model.body_parentid[b]
        xyz = origin[b] - origin[parent]
        if nj == 0:
            lines += [f'  <joint name="symrom_fixed_{b}" type="fixed"><origin xyz="{_v(xyz)}" rpy="0 0 0"/>'
                      f'<parent link="{names[parent]}"/><child link="{names[b]}"/></joint>']
            continue
        j = ja
        jname = name_of(model, "joint", j) or f"symrom_joint_{j}"
        axis = bf.vector(data.xaxis[j])
        axis = axis / np.linalg.norm(axis)
        limited = bool(model.jnt_limited[j])
        effort, _ = torque_bound(model, j)
        limit = ""
        if limited or np.isfinite(effort):
            lo, hi = model.jnt_range[j] if limited else (0.0, 0.0)
            limit = (f'<limit lower="{_f(lo)}" upper="{_f(hi)}"' if limited else "<limit")
            limit += f' effort="{_f(effort)}"/>' if np.isfinite(effort) else ' effort="0"/>'
        lines += [f'  <joint name="{jname}" type="{"revolute" if limited else "continuous"}">'
                  f'<origin xyz="{_v(xyz)}" rpy="0 0 0"/><parent link="{names[parent]}"/>'
                  f'<child link="{names[b]}"/><axis xyz="{_v(axis)}"/>{limit}</joint>']
    for leg, f in zip(LEGS, frames):
        if f.body not in origin:
            raise RobotModelError(f"the foot of leg {leg.upper()} is outside the base body's subtree",
                                  f"feet.{feet.kind}")
        at = bf.point(data.xpos[f.body] + data.xmat[f.body].reshape(3, 3) @ f.point) - origin[f.body]
        link = FOOT_LINK.format(leg=leg)
        sphere = (f'<collision><geometry><sphere radius="{_f(f.radius)}"/></geometry></collision>'
                  if f.radius > 0 else "")
        lines += [f'  <link name="{link}">{_MASSLESS}{sphere}</link>',
                  f'  <joint name="{link}_joint" type="fixed"><origin xyz="{_v(at)}" rpy="0 0 0"/>'
                  f'<parent link="{names[f.body]}"/><child link="{link}"/></joint>']
    lines.append("</robot>")
    return "\n".join(line for line in lines if line) + "\n"


def cache_dir() -> Path:
    """The folder of derived URDFs: ``$SYMROM_CACHE_DIR/robots`` if that is set (``off`` or
    empty: a temporary folder of this process, removed at exit), else
    ``$XDG_CACHE_HOME/symrom/robots`` (default ``~/.cache/symrom/robots``)."""
    env = os.environ.get(CACHE_ENV)
    if env is not None:
        if env.strip().lower() in ("", "off"):
            return _private_dir()
        return Path(env) / "robots"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "symrom" / "robots"


_PRIVATE: list[Path] = []


def _private_dir() -> Path:
    if not _PRIVATE:
        _PRIVATE.append(Path(tempfile.mkdtemp(prefix="symrom-robots-")))
        atexit.register(shutil.rmtree, _PRIVATE[0], True)
    return _PRIVATE[0]


def model_hash(mjcf: Path) -> str:
    """sha256 of an MJCF's content as MuJoCo parses it (its includes expanded) and of the mesh
    files it names: what its compiled model depends on."""
    mujoco = _mujoco()
    try:
        spec = mujoco.MjSpec.from_file(str(mjcf))
        text = spec.to_xml()
    except ValueError as e:
        raise RobotModelError(f"{mjcf}: MuJoCo cannot read it ({_one_line(e)})") from None
    h = hashlib.sha256(text.encode())
    for m in spec.meshes:
        if m.file:
            for f in (mjcf.parent / spec.meshdir / m.file, mjcf.parent / m.file):
                if f.is_file():
                    h.update(f.read_bytes())
                    break
    return h.hexdigest()


def derived_urdf(mjcf: str | os.PathLike, base: str, joint_names: tuple[str, ...], feet: Feet,
                 name: str) -> Path:
    """The URDF derived from the MJCF ``mjcf`` (see the module docstring), written once into
    ``cache_dir()`` and found there again by the MJCF's content, MuJoCo's version and the
    roles named (base, joints, feet). ``RobotModelError`` as ``urdf_text``."""
    mujoco = _mujoco()
    mjcf = Path(mjcf)
    h = hashlib.sha256("\n".join([str(DERIVATION), mujoco.__version__, model_hash(mjcf), base, *joint_names,
                                  repr(feet), name]).encode()).hexdigest()
    path = cache_dir() / f"{mjcf.stem}-{h[:20]}.urdf"
    if path.is_file():
        return path
    text = urdf_text(compile_model(mjcf), base, joint_names, feet, name,
                     note=f"derived by symrom from {mjcf.name} (sha256 {h[:20]}); MuJoCo {mujoco.__version__}")
    write_text_atomic(path, text)
    return path


__all__ = ["BASE_INERTIA", "CACHE_ENV", "FOOT_KINDS", "FOOT_LINK", "BaseFrame", "Feet", "FootFrame",
           "RobotModelError", "actuated", "cache_dir", "colliding", "compile_model", "derived_urdf",
           "drop_missing_meshes", "element_id", "foot_frames", "matrix_to_rpy", "missing_files", "model_hash",
           "name_of", "reach", "subtree", "torque_bound", "urdf_text", "zero_pose"]
