"""Plausibility checks of logged samples against the robot's description.

Every imported log is checked, column by column, against what the robot can
do (``PlausibilityLimits``, the defaults stated there):

- joint angles within the URDF's joint range plus ``angle_margin``;
- joint speeds within ``velocity_factor`` times the URDF's velocity limit;
- joint torques within the motor limit (the description's ``limits.torque``,
  where the actuator saturates): ``commanded`` torques within it exactly (a
  command beyond saturation is not the torque the joint got), ``measured``
  ones within ``torque_factor`` (1.25) times it (a torque estimated from the
  motor current reads the saturation plus its calibration error and the
  current loop's overshoot; the simulated and proxy Go1 logs reach 0.96 x);
- a base height between ``height[0]`` and ``height[1]`` times the robot's
  standing height, |roll|, |pitch| below ``tilt``, |yaw| below ``yaw``,
  |x|, |y| below ``position``, base speeds below ``linear_speed`` and
  ``angular_speed``.

(Finite values and contact flags in {0, 1} are checked while the file is
read.) A column that fails is looked at as a whole: if most of its values are
outside and one conversion brings every one of them within the limit, the
likely mistake is named (degrees for radians, mm for m, a value 1000 times
too large, a joint turned the other way). ``check_samples`` returns one ``ColumnProblem`` per failing
column; the importer turns the first into one error naming the file, the jump,
the row, the column, the value and the limit, or, lenient, lists them all.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from symrom.names import BASE_NAMES, JOINT_NAMES
from symrom.robots import get_robot


@dataclass(frozen=True)
class PlausibilityLimits:
    """How far a log may go beyond the robot's description before it is refused.

    angle_margin: rad beyond the URDF joint range; velocity_factor: multiple of the
    URDF's velocity limit; torques: ``measured`` or ``commanded`` (what the log's
    torque columns hold); torque_factor: multiple of the motor limit (the
    description's ``limits.torque``) allowed for measured torques (commanded ones:
    1, the limit itself); height: (low, high) base
    height as multiples of the standing height; tilt: largest |roll|, |pitch|
    (rad); yaw: largest |yaw| (rad); position: largest |x|, |y| (m);
    linear_speed (m/s), angular_speed (rad/s): largest base speeds.
    """

    angle_margin: float = 0.2
    velocity_factor: float = 2.0
    torques: str = "measured"
    torque_factor: float = 1.25
    height: tuple[float, float] = (0.2, 4.0)
    tilt: float = math.pi / 2
    yaw: float = 2 * math.pi
    position: float = 50.0
    linear_speed: float = 10.0
    angular_speed: float = 20.0

    def __post_init__(self) -> None:
        if self.torques not in TORQUES:
            raise ValueError(f"torques={self.torques!r}: choose from {', '.join(TORQUES)}")

    def to_dict(self) -> dict:
        return asdict(self)


TORQUES = ("measured", "commanded")

# Likely unit mistakes: (what to call it, the factor that undoes it), tried in this order.
_ANGLE_FIXES = (("degrees for radians", math.pi / 180), ("the opposite sign (a joint turned the other "
                                                         "way: its sign in the robot description)", -1.0))
_RATE_FIXES = (("degrees/s for rad/s", math.pi / 180), ("the opposite sign (a joint turned the other "
                                                        "way: its sign in the robot description)", -1.0))
_LENGTH_FIXES = (("mm for m", 1e-3),)
_SPEED_FIXES = (("mm/s for m/s", 1e-3),)
_TORQUE_FIXES = (("values 1000 times too large (mN m for N m?)", 1e-3),
                 ("the opposite sign (a joint turned the other way: its sign in the robot description)", -1.0))


@dataclass(frozen=True)
class ColumnProblem:
    """One column whose values leave their plausible range.

    field: ``q``, ``dq`` or ``tau``; index: the column within it (symrom order);
    name: the component (``fr_kn``); what: the quantity in words; unit; low,
    high: the plausible range; limit: how the range was set; rows: how many
    rows are outside; first: the first such row of the log (0-based);
    value: its value; worst: the value farthest outside; hint: the likely unit
    mistake (None if no single conversion explains the column).
    """

    field: str
    index: int
    name: str
    what: str
    unit: str
    low: float
    high: float
    limit: str
    rows: int
    first: int
    value: float
    worst: float
    hint: str | None

    def range_text(self) -> str:
        lo = "-inf" if not np.isfinite(self.low) else f"{self.low:.4g}"
        hi = "inf" if not np.isfinite(self.high) else f"{self.high:.4g}"
        return f"[{lo}, {hi}] {self.unit}"

    def hint_text(self) -> str:
        return f"; it looks like {self.hint}" if self.hint else ""

    def to_dict(self) -> dict:
        d = asdict(self)
        d["low"], d["high"] = (None if not np.isfinite(v) else v for v in (self.low, self.high))
        return d


def _ranges(robot: str, limits: PlausibilityLimits) -> list[tuple]:
    """(field, index, name, what, unit, low (n,), high (n,), limit text, fixes) for every
    checked column."""
    desc = get_robot(robot)
    jl = desc.joint_limits
    motor = np.asarray(desc.torque_limit, dtype=float)
    factor = 1.0 if limits.torques == "commanded" else limits.torque_factor
    m, h = limits.angle_margin, desc.start_height
    out = []
    for i, name in enumerate(JOINT_NAMES):
        out.append(("q", i, name, "joint angle", "rad", jl.lower[i] - m, jl.upper[i] + m,
                    f"URDF range {jl.lower[i]:.4g}..{jl.upper[i]:.4g} rad + {m:g} rad margin", _ANGLE_FIXES))
        v = limits.velocity_factor * jl.velocity[i]
        out.append(("dq", i, name, "joint speed", "rad/s", -v, v,
                    f"{limits.velocity_factor:g} x URDF velocity limit {jl.velocity[i]:.4g} rad/s", _RATE_FIXES))
        e = factor * motor[i]
        text = (f"commanded: the motor limit {motor[i]:.4g} N m" if limits.torques == "commanded"
                else f"measured: {factor:g} x motor limit {motor[i]:.4g} N m")
        out.append(("tau", i, name, f"{limits.torques} joint torque", "N m", -e, e, text, _TORQUE_FIXES))
    lo_z, hi_z = limits.height[0] * h, limits.height[1] * h
    base = {"x": (-limits.position, limits.position, f"|x| <= {limits.position:g} m", "m", _LENGTH_FIXES),
            "y": (-limits.position, limits.position, f"|y| <= {limits.position:g} m", "m", _LENGTH_FIXES),
            "z": (lo_z, hi_z, f"{limits.height[0]:g}..{limits.height[1]:g} x standing height {h:g} m", "m",
                  _LENGTH_FIXES),
            "roll": (-limits.tilt, limits.tilt, f"|roll| <= {limits.tilt:.4g} rad", "rad", _ANGLE_FIXES[:1]),
            "pitch": (-limits.tilt, limits.tilt, f"|pitch| <= {limits.tilt:.4g} rad", "rad", _ANGLE_FIXES[:1]),
            "yaw": (-limits.yaw, limits.yaw, f"|yaw| <= {limits.yaw:.4g} rad", "rad", _ANGLE_FIXES[:1])}
    for k, name in enumerate(BASE_NAMES):
        lo, hi, text, unit, fixes = base[name]
        what = "base height" if name == "z" else f"base {name}"
        out.append(("q", 12 + k, name, what, unit, lo, hi, text, fixes))
        linear = k < 3
        s = limits.linear_speed if linear else limits.angular_speed
        out.append(("dq", 12 + k, name, f"base {name} rate", "m/s" if linear else "rad/s", -s, s,
                    f"|d{name}| <= {s:g} {'m/s' if linear else 'rad/s'}",
                    _SPEED_FIXES if linear else _RATE_FIXES[:1]))
    return out


def motion_ratio(x: np.ndarray, v: np.ndarray, t: np.ndarray) -> float:
    """How far a column ``x`` (n,) moves against the trapezoidal integral of its logged rate
    ``v`` (n,) over times ``t`` (n,) s (steps where t does not increase, a new jump, left out):
    1 when both are in the same unit, 180/pi when x is in degrees and v in rad/s; NaN when the
    rate never moves."""
    dt = np.diff(t)
    ok = dt > 0
    moved = float(np.abs(np.diff(x))[ok].sum())
    integral = float((0.5 * np.abs(v[1:] + v[:-1]) * dt)[ok].sum())
    return moved / integral if integral > 0 else float("nan")


# A column is in degrees (or its rate in degrees/s) when it moves this close to 180/pi times its
# rate's integral (or 1/(180/pi) times), whatever share of it leaves the range.
DEGREES_RATIO = (0.8, 1.25)


def _in_degrees(ratio: float, factor: float) -> bool:
    return bool(np.isfinite(ratio) and DEGREES_RATIO[0] <= ratio * factor <= DEGREES_RATIO[1])


def check_samples(robot: str, q: np.ndarray, dq: np.ndarray, tau: np.ndarray,
                  limits: PlausibilityLimits = PlausibilityLimits(),
                  t: np.ndarray | None = None) -> list[ColumnProblem]:
    """Every column of a log outside its plausible range for ``robot``, in field order
    (q, dq, tau) then column order. q, dq (n, 18), tau (n, 12) in symrom's order and SI
    units; an empty list if the log is plausible. With the times ``t`` (n,) s, an angle (or
    angular rate) column that moves 180/pi times what its rate says (or 1/(180/pi)) is named
    as in degrees even when only a few of its rows leave the range (a hip abduction logged
    in degrees stays mostly within its range)."""
    arrays = {"q": np.asarray(q, float), "dq": np.asarray(dq, float), "tau": np.asarray(tau, float)}
    order = {"q": 0, "dq": 1, "tau": 2}
    problems = []
    for field, i, name, what, unit, lo, hi, text, fixes in _ranges(robot, limits):
        x = arrays[field][:, i]
        bad = (x < lo) | (x > hi)
        if not bad.any():
            continue
        rows = np.flatnonzero(bad)
        outside = np.maximum(lo - x, x - hi)
        worst = float(x[int(np.argmax(outside))])
        # A unit mistake puts most of a column outside (a few rows outside are a glitch or a
        # fall), and one conversion brings all of it back.
        hint = None if bad.mean() <= 0.5 else next(
            (label for label, f in fixes if np.all((x * f >= lo) & (x * f <= hi))), None)
        if hint is None and t is not None and field in ("q", "dq") and fixes and fixes[0][0].startswith("degrees"):
            # the column against its own rate (or its rate against the column): the unit says itself
            deg = np.pi / 180
            fits = bool(np.all((x * deg >= lo) & (x * deg <= hi)))
            ratio = (motion_ratio(x, arrays["dq"][:, i], t) if field == "q"
                     else motion_ratio(arrays["q"][:, i], x, t))
            if fits and _in_degrees(ratio, deg if field == "q" else 1 / deg):
                hint = fixes[0][0]
        problems.append(ColumnProblem(field, i, name, what, unit, float(lo), float(hi), text, int(rows.size),
                                      int(rows[0]), float(x[rows[0]]), worst, hint))
    problems.sort(key=lambda p: (order[p.field], p.index))
    return problems
