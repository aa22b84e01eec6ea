"""The robot description file: a robot model (URDF or MJCF) plus the few facts symrom needs beyond it.

A description (TOML, ``format = 1`` or ``2``) names which joints and links of the
model play symrom's roles (legs FR FL RR RL x joints hx hy kn, four feet), the sign
that turns each model joint angle into symrom's convention (hx about +x, hy and kn
about +y of the base), a standing pose and the actuator torque limits. Geometry,
masses and inertias stay in the model, the one source of them: a URDF, or an MJCF
alone (format 2), from which a URDF is derived once and cached (``robots.mjcf``).

Every problem is reported as one ``RobotDescriptionError`` naming the file and
the key. docs/design.md, "Robot description file", is the reference.
"""

from __future__ import annotations

import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from symrom.names import LEG_JOINTS, LEGS
from symrom.robots.mjcf import FOOT_KINDS, FOOT_LINK, Feet, RobotModelError

FORMAT = 2  # the newest format this symrom reads and writes
FORMATS = (1, 2)  # the formats it reads
PYBULLET_DATA = "pybullet_data:"  # urdf prefix: a path inside the pybullet_data package
FRICTION_SPEED = 0.1  # rad/s: a joint's friction loss takes its full torque from this speed on

_KEYS: dict[str, tuple[str, ...] | None] = {  # top-level key -> allowed sub-keys (None: a value)
    "format": None, "name": None, "urdf": None, "base_link": None,
    "legs": LEGS, "joints": LEG_JOINTS, "feet": (*FOOT_KINDS, "point"), "signs": LEG_JOINTS,
    "stance": ("height", "joints", "knee"), "limits": ("torque",),
    "mjcf": None, "actuators": ("damping", "armature", "friction_loss"),
}
_OPTIONAL = ("urdf", "mjcf", "actuators")  # keys a file may leave out (urdf: given an mjcf, format 2)
_FREE_TABLES = ("feet", "actuators")  # tables whose sub-keys are each optional (feet: one kind)



class RobotDescriptionError(ValueError):
    """A robot description file is unreadable or wrong; the message names the file and key."""


def pybullet_data_path(rel: str) -> Path:
    """Absolute path of ``rel`` inside the installed ``pybullet_data`` package."""
    import pybullet_data

    return Path(pybullet_data.getDataPath()) / rel


@dataclass(frozen=True)
class ActuatorEffects:
    """What sits between a motor's torque and its joint, per joint (12,), symrom order.

    damping N m s/rad: viscous joint damping (typical 0-2 for 10-30 kg quadrupeds);
    armature kg m^2: reflected rotor inertia, rotor inertia x gear ratio^2 (typical
    0-0.05); friction_loss N m: Coulomb joint friction (typical 0-1). All zero (the
    default) is the ideal motor both engines simulate otherwise. ``symrom.sim`` applies
    them in every engine that can (``symrom.sim.engines``); a description states them in
    its optional ``[actuators]`` table, per joint kind (3) or per joint (12).
    """

    damping: tuple[float, ...] = (0.0,) * 12
    armature: tuple[float, ...] = (0.0,) * 12
    friction_loss: tuple[float, ...] = (0.0,) * 12

    def __post_init__(self) -> None:
        for name in ("damping", "armature", "friction_loss"):
            v = getattr(self, name)
            if len(v) == 3:
                object.__setattr__(self, name, tuple(float(x) for x in v) * 4)
            elif len(v) != 12:
                raise ValueError(f"actuator effect {name}: expected 3 or 12 values, got {len(v)}")
            if min(getattr(self, name)) < 0 or not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"actuator effect {name}: values must be finite and >= 0, got {v}")

    @property
    def ideal(self) -> bool:
        """Whether every effect is zero (an ideal motor)."""
        return not any(self.damping) and not any(self.armature) and not any(self.friction_loss)

    def __add__(self, other: ActuatorEffects) -> ActuatorEffects:
        """Both effects at once, joint by joint (a robot's stated ones and hardware's on top)."""
        return ActuatorEffects(*(tuple(a + b for a, b in zip(getattr(self, n), getattr(other, n)))
                                 for n in ("damping", "armature", "friction_loss")))

    def losses(self, dq: np.ndarray, ddq: np.ndarray | None = None) -> np.ndarray:
        """The torques (..., 12) N m the effects take from the motors at joint speeds dq (..., 12)
        rad/s and, if given, accelerations ddq (..., 12) rad/s^2 (in symrom's signs or the
        model's alike: a loss turns with its joint): damping x dq + friction_loss x s(dq) + armature x ddq, where the
        friction's sign s ramps linearly through zero over +-``FRICTION_SPEED`` (the engines'
        friction loss is a regularised constraint, not a jump at rest). A motor's torque less
        these is what reaches the joint."""
        dq = np.asarray(dq, dtype=float)
        out = np.asarray(self.damping) * dq
        out = out + np.asarray(self.friction_loss) * np.clip(dq / FRICTION_SPEED, -1.0, 1.0)
        if ddq is not None:
            out = out + np.asarray(self.armature) * np.asarray(ddq, dtype=float)
        return out


@dataclass(frozen=True)
class RobotDescription:
    """One robot, as read from its description file (arrays in symrom's joint order).

    key: what names the robot in a dataset's ``robot`` attribute (a built-in
    name, else the description file's absolute path); urdf_path: the URDF (the
    description's, or the one derived from its MJCF: ``urdf_derived``);
    joint_names (12) and foot_links (4): URDF names, FR FL RR RL x hx hy kn (joint
    names are the MJCF's too; a derived URDF's foot links are ``mjcf.FOOT_LINK``);
    joint_signs (12): +1 or -1, symrom angle = sign x model angle (and the same
    for rates and torques); stance_joints (12) rad: a standing leg posture
    where the leg IK starts; knee_ranges (4 x (lower, upper)) rad: per leg, the
    range the leg IK keeps the knee in; start_height m: base height standing;
    torque_limit (12) N m; actuators: joint damping, armature and friction loss
    (``ActuatorEffects``; all zero without an ``[actuators]`` table); mjcf_path: an
    MJCF model of the robot for the MuJoCo engine (key ``mjcf``; None: MuJoCo
    compiles the URDF); feet: the ``[feet]`` table as read (``mjcf.Feet``: what the
    MuJoCo engine finds the feet by); format: the file's format.
    """

    key: str
    name: str
    urdf_path: Path
    base_link: str
    joint_names: tuple[str, ...]
    foot_links: tuple[str, ...]
    joint_signs: tuple[float, ...]
    stance_joints: tuple[float, ...]
    knee_ranges: tuple[tuple[float, float], ...]
    start_height: float
    torque_limit: tuple[float, ...]
    source: Path = field(compare=False)
    actuators: ActuatorEffects = field(default_factory=ActuatorEffects)
    mjcf_path: Path | None = None
    feet: Feet | None = None
    urdf_derived: bool = False
    format: int = 1

    @property
    def knee_range(self) -> np.ndarray:
        """(2, 4) rad: the knee's lower and upper bound per leg (FR FL RR RL)."""
        return np.asarray(self.knee_ranges, dtype=float).T

    @cached_property
    def mass(self) -> float:
        """Total mass, kg: the sum of every link's ``<inertial><mass>`` in the URDF (a derived
        URDF's are the MJCF's bodies')."""
        root = ET.parse(self.urdf_path).getroot()
        masses = [float(m.get("value")) for m in root.findall("link/inertial/mass") if m.get("value") is not None]
        if not masses:
            raise RobotDescriptionError(f"{self.source}: the URDF {self.urdf_path} declares no link masses")
        return float(sum(masses))

    @cached_property
    def foot_radius(self) -> float:
        """Radius (m) of the first foot link's collision sphere in the URDF (0 if not a sphere)."""
        root = ET.parse(self.urdf_path).getroot()
        for link in root.findall("link"):
            if link.get("name") == self.foot_links[0]:
                sphere = link.find("collision/geometry/sphere")
                if sphere is not None:
                    return float(sphere.get("radius"))
        return 0.0

    @property
    def signs(self) -> np.ndarray:
        """(12,) joint signs as an array."""
        return np.asarray(self.joint_signs, dtype=float)

    @cached_property
    def joint_limits(self) -> JointLimits:
        """The URDF's ``<limit>`` of each of the 12 joints, in symrom's signs (a joint turned
        the other way has its range mirrored): angles (rad; -inf/inf for a continuous
        joint or a missing bound), speed (rad/s) and effort (N m; inf where the URDF gives
        none or 0)."""
        root = ET.parse(self.urdf_path).getroot()
        joints = {j.get("name"): j for j in root.findall("joint")}
        lo, hi, vel, eff = (np.full(len(self.joint_names), v) for v in (-np.inf, np.inf, np.inf, np.inf))
        for i, name in enumerate(self.joint_names):
            lim = joints[name].find("limit")
            if lim is None:
                continue
            if joints[name].get("type") == "revolute":
                lo[i] = float(lim.get("lower", "-inf"))
                hi[i] = float(lim.get("upper", "inf"))
            for arr, key in ((vel, "velocity"), (eff, "effort")):
                v = float(lim.get(key, "inf"))
                arr[i] = v if v > 0 else np.inf
        flip = self.signs < 0
        lo[flip], hi[flip] = -hi[flip], -lo[flip]
        return JointLimits(lo, hi, vel, eff)


@dataclass(frozen=True)
class JointLimits:
    """Per joint (12,), symrom order and signs: ``lower``, ``upper`` (rad), ``velocity``
    (rad/s) and ``effort`` (N m), as the URDF states them (infinite where it does not)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


def _fail(path: Path, key: str, what: str) -> RobotDescriptionError:
    return RobotDescriptionError(f"robot description {path}: key {key!r}: {what}")


def _number(path: Path, key: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise _fail(path, key, f"expected a number, got {v!r}")
    return float(v)


def _numbers(path: Path, key: str, v, sizes: tuple[int, ...]) -> list[float]:
    """A list of numbers of one of ``sizes``; a lone number counts as size 1."""
    items = v if isinstance(v, list) else [v]
    if len(items) not in sizes:
        raise _fail(path, key, f"expected {' or '.join(map(str, sizes))} numbers, got {v!r}")
    return [_number(path, key, x) for x in items]


def _per_joint(values: list[float]) -> list[float]:
    """Values given per joint kind (3: hx hy kn) or per joint (12) -> 12 values, symrom order."""
    return values * len(LEGS) if len(values) == len(LEG_JOINTS) else values


def _text(path: Path, key: str, v) -> str:
    if not isinstance(v, str) or not v.strip():
        raise _fail(path, key, f"expected a non-empty string, got {v!r}")
    return v


def _template(path: Path, key: str, v, leg: str) -> str:
    try:
        return _text(path, key, v).format(leg=leg)
    except (KeyError, IndexError, ValueError):
        raise _fail(path, key, f"{v!r} may hold only the placeholder {{leg}}") from None


def _urdf(path: Path, v) -> Path:
    return _path(path, "urdf", v)


def _path(path: Path, key: str, v) -> Path:
    """A file named by key ``key``: ``pybullet_data:REL`` or a path relative to the description."""
    v = _text(path, key, v)
    f = pybullet_data_path(v[len(PYBULLET_DATA):]) if v.startswith(PYBULLET_DATA) else path.parent / v
    if not f.is_file():
        raise _fail(path, key, f"no such file {f}")
    return f.resolve()


def _actuators(path: Path, table: dict | None) -> ActuatorEffects:
    if table is None:
        return ActuatorEffects()
    vals = {}
    for k in ("damping", "armature", "friction_loss"):
        v = _numbers(path, f"actuators.{k}", table.get(k, 0.0), (1, 3, 12))
        if min(v) < 0:
            raise _fail(path, f"actuators.{k}", f"must be >= 0, got {v}")
        vals[k] = tuple(_per_joint(v * 3 if len(v) == 1 else v))
    return ActuatorEffects(**vals)


def _check_keys(path: Path, doc: dict) -> None:
    for k in doc:
        if k not in _KEYS:
            raise _fail(path, k, f"unknown key; known: {', '.join(_KEYS)}")
    for k, subs in _KEYS.items():
        if k not in doc:
            if k in _OPTIONAL:
                continue
            raise _fail(path, k, "missing")
        if subs is None:
            continue
        if not isinstance(doc[k], dict):
            raise _fail(path, k, "expected a table")
        for s in doc[k]:
            if s not in subs:
                raise _fail(path, f"{k}.{s}", f"unknown key; known: {', '.join(subs)}")
        for s in subs:
            if s not in doc[k] and k not in _OPTIONAL and k not in _FREE_TABLES:
                raise _fail(path, f"{k}.{s}", "missing")


def _check_format(path: Path, doc: dict) -> int:
    """The file's format; a format-2 feature in a format-1 file is refused by its key."""
    fmt = doc["format"]
    if isinstance(fmt, bool) or fmt not in FORMATS:
        raise _fail(path, "format", f"{fmt!r} is not supported (this symrom reads {', '.join(map(str, FORMATS))})")
    if fmt == 1:
        if "urdf" not in doc and "mjcf" in doc:
            raise _fail(path, "urdf", "missing (format 1 needs a URDF; a description of an MJCF alone "
                                      "is format = 2)")
        used = [f"feet.{k}" for k in doc["feet"] if k != "link"]
        used += ["stance.knee"] if isinstance(doc["stance"].get("knee"), list) and any(
            isinstance(x, list) for x in doc["stance"]["knee"]) else []
        if used:
            raise _fail(path, used[0], "needs format = 2 (feet by body, geom or site; knee ranges per leg)")
    return fmt


def _check_urdf(path: Path, urdf: Path, base_link: str, joints: list[str], feet: list[str]) -> None:
    """Every named joint and link exists in the URDF (a wrong name is caught here, by key)."""
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as e:
        raise _fail(path, "urdf", f"{urdf} is not valid XML ({e})") from None
    links = {link.get("name") for link in root.findall("link")}
    kinds = {j.get("name"): j.get("type") for j in root.findall("joint")}
    if base_link not in links:
        raise _fail(path, "base_link", f"no link {base_link!r} in {urdf.name}")
    for i, name in enumerate(joints):
        key = f"joints.{LEG_JOINTS[i % 3]}"
        if name not in kinds:
            raise _fail(path, key, f"no joint {name!r} in {urdf.name}")
        if kinds[name] not in ("revolute", "continuous"):
            raise _fail(path, key, f"joint {name!r} is {kinds[name]}, not revolute")
    for name in feet:
        if name not in links:
            raise _fail(path, "feet.link", f"no link {name!r} in {urdf.name}")


def _feet(path: Path, table: dict, prefixes: list[str], has_urdf: bool) -> Feet:
    kinds = [k for k in FOOT_KINDS if k in table]
    if len(kinds) != 1:
        raise _fail(path, "feet", f"name the feet by exactly one of {', '.join(FOOT_KINDS)}, got "
                                  f"{', '.join(kinds) or 'none'}")
    kind = kinds[0]
    if has_urdf and kind != "link":
        raise _fail(path, f"feet.{kind}", "a description with a URDF names its feet by their links (feet.link)")
    if not has_urdf and kind == "link":
        raise _fail(path, "feet.link", "this description has no URDF: name the feet in its MJCF by "
                                       "feet.body, feet.geom or feet.site")
    names = tuple(_template(path, f"feet.{kind}", table[kind], p) for p in prefixes)
    points = None
    if "point" in table:
        if kind != "body":
            raise _fail(path, "feet.point", "a point is given in a body's frame: only with feet.body")
        v = table["point"]
        rows = v if isinstance(v, list) and v and all(isinstance(r, list) for r in v) else [v]
        if len(rows) not in (1, 4):
            raise _fail(path, "feet.point", f"expected [x, y, z] or 4 of them (FR FL RR RL), got {v!r}")
        rows = [_numbers(path, "feet.point", r, (3,)) for r in rows]
        points = tuple(tuple(r) for r in (rows * 4 if len(rows) == 1 else rows))
    return Feet(kind, names, points)


def _knees(path: Path, v) -> tuple[tuple[float, float], ...]:
    """[lower, upper] for every leg, or 4 of them (FR FL RR RL)."""
    rows = v if isinstance(v, list) and v and all(isinstance(r, list) for r in v) else [v]
    if len(rows) not in (1, 4):
        raise _fail(path, "stance.knee", f"expected [lower, upper] or 4 of them (FR FL RR RL), got {v!r}")
    out = []
    for r in rows:
        knee = _numbers(path, "stance.knee", r, (2,))
        if knee[0] >= knee[1]:
            raise _fail(path, "stance.knee", f"expected [lower, upper] with lower < upper, got {knee}")
        out.append((knee[0], knee[1]))
    return tuple(out * 4 if len(out) == 1 else out)


def load_description(path: str | Path, key: str | None = None) -> RobotDescription:
    """Read and check the description file ``path``; ``key`` names the robot in datasets
    (default: the file's absolute path). A description naming an MJCF and no URDF gets the URDF
    derived from it (``robots.mjcf.derived_urdf``, cached on disk)."""
    path = Path(path).resolve()
    try:
        doc = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise RobotDescriptionError(f"robot description {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise RobotDescriptionError(f"robot description {path}: unreadable ({e.__class__.__name__})") from None
    except tomllib.TOMLDecodeError as e:
        raise RobotDescriptionError(f"robot description {path}: not valid TOML ({e})") from None
    _check_keys(path, doc)
    fmt = _check_format(path, doc)
    if "urdf" not in doc and "mjcf" not in doc:
        raise _fail(path, "urdf", "missing (or, format 2, an mjcf alone)")
    mjcf = _path(path, "mjcf", doc["mjcf"]) if "mjcf" in doc else None
    prefixes = [_text(path, f"legs.{leg}", doc["legs"][leg]) for leg in LEGS]
    joints = [_template(path, f"joints.{j}", doc["joints"][j], p) for p in prefixes for j in LEG_JOINTS]
    feet = _feet(path, doc["feet"], prefixes, "urdf" in doc)
    base_link = _text(path, "base_link", doc["base_link"])
    name = _text(path, "name", doc["name"])
    if "urdf" in doc:
        urdf, foot_links = _urdf(path, doc["urdf"]), list(feet.names)
        _check_urdf(path, urdf, base_link, joints, foot_links)
    else:
        from symrom.robots.mjcf import derived_urdf

        try:
            urdf = derived_urdf(mjcf, base_link, tuple(joints), feet, name)
        except RobotModelError as e:
            raise _fail(path, e.key or "mjcf", str(e)) from None
        foot_links = [FOOT_LINK.format(leg=leg) for leg in LEGS]
    signs = []
    for j in LEG_JOINTS:
        s = _numbers(path, f"signs.{j}", doc["signs"][j], (1, 4))
        if any(x not in (1.0, -1.0) for x in s):
            raise _fail(path, f"signs.{j}", f"each sign must be 1 or -1, got {doc['signs'][j]!r}")
        signs.append(s * 4 if len(s) == 1 else s)
    stance = doc["stance"]
    height = _number(path, "stance.height", stance["height"])
    if height <= 0:
        raise _fail(path, "stance.height", f"must be positive, got {height}")
    knees = _knees(path, stance["knee"])
    torque = _numbers(path, "limits.torque", doc["limits"]["torque"], (3, 12))
    if min(torque) <= 0:
        raise _fail(path, "limits.torque", f"limits must be positive, got {torque}")
    return RobotDescription(
        key=str(path) if key is None else key, name=name, urdf_path=urdf,
        base_link=base_link, joint_names=tuple(joints), foot_links=tuple(foot_links),
        joint_signs=tuple(signs[k][leg] for leg in range(4) for k in range(3)),
        stance_joints=tuple(_per_joint(_numbers(path, "stance.joints", stance["joints"], (3, 12)))),
        knee_ranges=knees, start_height=height,
        torque_limit=tuple(_per_joint(torque)), source=path, actuators=_actuators(path, doc.get("actuators")),
        mjcf_path=mjcf, feet=feet, urdf_derived="urdf" not in doc, format=fmt)
