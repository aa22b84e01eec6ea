"""The repair's body estimates: the torque gain, the base-height offset and the contact flags
of a logged jump, from physics and the robot description.

What they share (``body_state``; ``body_pose``: what the positions alone give): the whole
body's centre of mass (``robots.masses``: every link of the URDF, not the base) and its
vertical velocity; the feet's height above the ground and vertical speed (leg kinematics, the
foot's radius); per joint, the vertical ground force a unit torque gives its foot
(``preprocess.ground_reaction_forces``, through the leg Jacobian), and the torques that hold
the legs' own weight. A foot in contact then pushes up with F_z = C tau_true - C h, and the
feet together carry m (g + a_z) of the centre of mass.

- **Torque gain** (``estimate_gain``): logged torques are ``gain`` times the true ones (a
  current sensor's calibration, a gear ratio). Over windows of ``gain_window`` s (their edges
  kept off contact changes) the vertical momentum balance, integral of the feet's force =
  m g T + m dv_z, holds with the logged torques divided by the gain. Quasi-static windows
  (mean vertical acceleration within ``static`` g, no contact change inside: the feet carry
  the weight) give it on their own; the dynamic ones (push-off, landing) give it too, less
  surely (the legs' own inertia, friction and damping are left out: 1 % on simulated Go1
  jumps, 5-10 % on the hardware-like proxy). The gain is the quasi-static windows' where
  there are ``min_static`` of them, else all windows'; where both exist, dynamic windows
  off by more than the factor ``gain_spread`` mean no one gain describes the torques (a
  torque offset, a load the legs do not carry) and the gain is not determined. The
  flight rows are the check that the gain is not absorbing the time base: the repaired
  clock puts the flight's centre of mass at g (``repair_clock``); what the torques push in
  flight (every foot as if down, in units of the weight) is recorded beside it.
- **Height offset** (``estimate_height``): the feet in contact touch the ground (centres one
  foot radius above it): the offset is the median over the rows with a foot down (two rows
  off each contact change) of the mean height of their feet, negated; this is what
  ``importers.restore_height`` does for logs rebased to z = 0, for an offset of any size.
- **Contacts** (``contact_lag``, ``derive_contacts``): a foot is *grounded* where it sits
  within ``foot_clearance`` of its stance level (its median height while flagged down) and
  moves vertically slower than ``foot_speed``. Each isolated change of a logged flag is moved
  by the number of rows (within ``lag_max``) that makes the flag fit the grounded evidence
  best around it; a logger's lag moves every touch-down and every lift-off alike, so a lag is
  taken where the touch-downs' most common move and the lift-offs' are the same, nonzero,
  with at least two votes each (a flag defined otherwise, a force threshold on a soft foot,
  moves them differently and is left as logged). Flags a log did not hold (a bag without a
  contact topic: ``bags.derived_contact``) are derived again from the repaired torques and
  heights.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict, dataclass

import numpy as np

from symrom.data.repair_clock import RepairLimits, loo_error, robust_fit
from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_LEGS, leg_slice
from symrom.names import GRAVITY as G
from symrom.robots import get_robot, leg_kinematics, mass_model
from symrom.robots.kinematics import rpy_to_matrix

_Z = BASE_POS.start + 2  # q column of the base height


@dataclass(frozen=True)
class BodyState:
    """One jump's bodies, per row (n rows): com_z, com_vz (n,) the centre of mass's height m
    and vertical velocity m/s; feet_z (n, 4) m the feet's centres above one foot radius over
    the ground (0: touching), feet_vz (n, 4) m/s their vertical velocity; force (n, 12) N per
    N m, the vertical ground force on its foot per unit torque of each joint; hold (n, 12)
    N m the torques that hold the legs' own weight; mass kg."""

    com_z: np.ndarray
    com_vz: np.ndarray
    feet_z: np.ndarray
    feet_vz: np.ndarray
    force: np.ndarray
    hold: np.ndarray
    mass: float


def angular_velocity(rpy: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """World-frame angular velocity (n, 3) rad/s of ZYX angles rpy (n, 3) and their rates."""
    p, y = rpy[:, 1], rpy[:, 2]
    dr, dp, dy = rates.T
    return np.stack([np.cos(y) * np.cos(p) * dr - np.sin(y) * dp,
                     np.sin(y) * np.cos(p) * dr + np.cos(y) * dp,
                     -np.sin(p) * dr + dy], axis=1)


@dataclass(frozen=True)
class BodyPose:
    """What of a jump's bodies its positions alone give, per row (n rows), for ``body_state``
    at any velocities: R (n, 3, 3) base to world; com_w (n, 3) m the centre of mass from the
    base and feet_w (n, 4, 3) m the feet's centres, world axes; J (n, 4, 3, 3) the legs'
    Jacobians (base frame, m/rad); com_z, feet_z, force, hold, mass as ``BodyState``'s."""

    R: np.ndarray
    com_w: np.ndarray
    feet_w: np.ndarray
    J: np.ndarray
    com_z: np.ndarray
    feet_z: np.ndarray
    force: np.ndarray
    hold: np.ndarray
    mass: float


def body_pose(robot: str, q: np.ndarray) -> BodyPose:
    """The position-only quantities of ``body_state`` for q (n, 18) of one jump."""
    desc, mm = get_robot(robot), mass_model(robot)
    qj = q[:, JOINTS]
    R = rpy_to_matrix(q[:, BASE_RPY])
    com_b, hold = mm.com_and_hold(qj, q[:, BASE_RPY], G)  # one placement of the links for both
    com_w = np.einsum("nij,nj->ni", R, com_b)
    feet, J = leg_kinematics(robot).foot_positions_and_jacobians(qj)  # (n, 4, 3), (n, 4, 3, 3)
    feet_w = np.einsum("nij,nkj->nki", R, feet)
    feet_z = q[:, None, _Z] + feet_w[:, :, 2] - desc.foot_radius
    up = R[:, 2, :]  # the world's z in the base frame
    force = np.empty((q.shape[0], 12))
    for k in range(N_LEGS):
        try:
            c = -np.linalg.solve(J[:, k], up[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a stretched leg: least squares, as the wrench does
            c = -np.einsum("nij,nj->ni", np.linalg.pinv(J[:, k]), up)
        force[:, leg_slice(k)] = c
    return BodyPose(R, com_w, feet_w, J, q[:, _Z] + com_w[:, 2], feet_z, force, hold, mm.mass)


def body_state(robot: str, q: np.ndarray, dq: np.ndarray, pose: BodyPose | None = None) -> BodyState:
    """The quantities of the module docstring for q, dq (n, 18) of one jump; pose:
    ``body_pose(robot, q)`` where it is at hand (None: computed here), as for the same
    positions with repaired velocities."""
    mm = mass_model(robot)
    pose = body_pose(robot, q) if pose is None else pose
    dq = np.ascontiguousarray(dq)  # einsum's order of summing follows the layout: the same bits from a log's columns
    omega = angular_velocity(q[:, BASE_RPY], dq[:, BASE_RPY])
    com_v = np.einsum("nij,nj->ni", pose.R, mm.com_base_rate(q[:, JOINTS], dq[:, JOINTS]))
    com_vz = dq[:, _Z] + np.cross(omega, pose.com_w)[:, 2] + com_v[:, 2]
    leg_v = np.einsum("nkij,nkj->nki", pose.J, dq[:, JOINTS].reshape(-1, N_LEGS, 3))
    feet_vz = (dq[:, None, _Z] + np.cross(omega[:, None, :], pose.feet_w)[:, :, 2]
               + np.einsum("nij,nkj->nki", pose.R, leg_v)[:, :, 2])
    return BodyState(pose.com_z, com_vz, pose.feet_z, feet_vz, pose.force, pose.hold, pose.mass)


def vertical_forces(state: BodyState, tau: np.ndarray, contact: np.ndarray | None = None) -> np.ndarray:
    """Each foot's vertical ground force (n, 4) N from torques tau (n, 12) N m (the legs'
    weight held), zero where ``contact`` (n, 4) says the foot is up (None: every foot)."""
    per_joint = state.force * (tau - state.hold)
    f = per_joint.reshape(-1, N_LEGS, 3).sum(axis=2)
    return f if contact is None else f * (np.asarray(contact) > 0)


# ----------------------------------------------------------------- the torque gain

@dataclass(frozen=True)
class GainEstimate:
    """The torque gain of one jump (module docstring): the logged torques are ``gain`` times
    the true ones by the data (sd its uncertainty; applied or not); static, static_sd,
    static_windows and dynamic, dynamic_sd, dynamic_windows: the quasi-static and the
    dynamic windows' own estimates
    (nan without such windows); flight_force: the flight rows' mean vertical push of the
    torques (divided by the gain, every foot as if down) in units of the weight (nan without
    a flight); applied: the torques were divided by the gain; note: one line."""

    gain: float
    sd: float
    static: float
    static_sd: float
    static_windows: int
    dynamic: float
    dynamic_sd: float
    dynamic_windows: int
    flight_force: float
    applied: bool
    note: str
    kinds: tuple[float, float, float] | None = None
    kinds_sd: tuple[float, float, float] | None = None

    def per_joint(self) -> np.ndarray:
        """The gain of each of the 12 joints (12,): per joint kind where found, else the one."""
        return np.tile(self.kinds, 4) if self.kinds is not None else np.full(12, self.gain)

    def to_dict(self) -> dict:
        return asdict(self)


def _near_changes(contact: np.ndarray, rows: int) -> np.ndarray:
    """(n,) True within ``rows`` rows of a change of any foot's flag."""
    change = np.r_[False, np.any(np.diff(np.asarray(contact).astype(int), axis=0) != 0, axis=1)]
    return np.convolve(change.astype(float), np.ones(2 * rows + 1), "same") > 0


def _ratio_fit(x: np.ndarray, y: np.ndarray, floor: float) -> tuple[float, float]:
    """y = x / gain by a robust fit: the gain and its uncertainty (relative floor included)."""
    if x.size == 0:
        return float("nan"), float("nan")
    if x.size == 1:
        g = float(x[0] / y[0])
        return g, abs(g) * floor * 3
    beta, cov, _ = robust_fit(x[:, None], y)
    inv = float(beta[0])
    g = 1.0 / inv
    return g, float(np.hypot(np.sqrt(cov[0, 0]) * g ** 2, floor * abs(g)))


def estimate_gain(t: np.ndarray, state: BodyState, tau: np.ndarray, contact: np.ndarray,
                  limits: RepairLimits) -> tuple[GainEstimate, str | None]:
    """The torque gain of one jump: t (n,) s (on the repaired clock), tau (n, 12) N m as
    logged, contact (n, 4). Returns the estimate and, where the data do not determine it,
    the reason (the estimate is then not applied)."""
    n = t.size
    down = np.asarray(contact).astype(bool)
    weight = state.mass * G
    near = _near_changes(contact, 2)
    pushed = (state.force * tau).reshape(n, N_LEGS, 3).sum(axis=2) * down  # (n, 4) N, logged torques
    held = (state.force * state.hold).reshape(n, N_LEGS, 3).sum(axis=2) * down  # (n, 4) N of the legs' weight
    x_rows, h_rows = pushed.sum(axis=1), held.sum(axis=1)
    knee_rows = ((state.force * tau)[:, 2::3] * down).sum(axis=1)  # the knees' share of x_rows
    vz = np.convolve(np.pad(state.com_vz, 2, mode="edge"), np.ones(5) / 5, "valid")  # 5-row mean at each row
    edges = np.searchsorted(t, np.arange(t[0], t[-1] + limits.gain_window, limits.gain_window))
    edges = np.unique(np.r_[edges, n - 1].clip(0, n - 1))
    xs, ys, static, knees = [], [], [], []
    for a, b in zip(edges[:-1], edges[1:]):
        while a < b and near[a]:
            a += 1
        while b > a and near[b]:
            b -= 1
        if b - a < 5 or not down[a:b + 1].any():
            continue
        span = float(t[b] - t[a])
        x = float(np.trapezoid(x_rows[a:b + 1], t[a:b + 1]))
        if abs(x) < 0.1 * weight * span:  # the feet carry almost nothing here: no information
            continue
        dv = float(vz[b] - vz[a])
        xs.append(x)
        knees.append(float(np.trapezoid(knee_rows[a:b + 1], t[a:b + 1])))
        ys.append(weight * span + state.mass * dv + float(np.trapezoid(h_rows[a:b + 1], t[a:b + 1])))
        inside = np.any(np.diff(down[a:b + 1].astype(int), axis=0) != 0)
        static.append(abs(dv) <= limits.static * G * span and not inside)
    xs, ys, static, knees = np.array(xs), np.array(ys), np.array(static, bool), np.array(knees)
    gs, gs_sd = _ratio_fit(xs[static], ys[static], limits.static_floor)
    gd, gd_sd = _ratio_fit(xs[~static], ys[~static], limits.dynamic_floor)
    air = np.flatnonzero((~down.any(axis=1)) & ~_near_changes(contact, limits.flight_trim))
    undetermined = None
    if xs.size == 0:
        gain, sd, note = 1.0, float("nan"), "no window with a foot carrying load: the gain is not determined"
        undetermined = "no rows with a foot down to weigh the robot with"
    elif static.sum() >= limits.min_static:
        gain, sd = gs, gs_sd
        note = f"from the weight over {int(static.sum())} quasi-static windows"
        if (~static).sum() >= 2 and abs(gs - gd) > limits.z * np.hypot(gs_sd, gd_sd):
            # the dynamic windows leave out the legs' inertia, friction and damping: noted
            note += f"; the dynamic windows give {gd:.3g} +- {gd_sd:.2g}"
            if not 1 / limits.gain_spread <= gd / gs <= limits.gain_spread:
                undetermined = (f"the quasi-static rows give a torque gain of {gs:.3g} +- {gs_sd:.2g}, the dynamic "
                                f"ones {gd:.3g} +- {gd_sd:.2g}: not one gain (a torque offset, or a load the legs do "
                                f"not carry)")
    else:
        gain, sd = _ratio_fit(xs, ys, limits.dynamic_floor)
        note = f"from the vertical momentum over {xs.size} windows ({int(static.sum())} quasi-static)"
    flight = float("nan")
    if air.size and np.isfinite(gain) and gain != 0:
        flight = float((state.force[air] * tau[air]).sum(axis=1).mean() / gain / weight)
    kinds = kinds_sd = None
    if undetermined is None and xs.size >= 6:
        # the hips' (hx, hy) and the knees' gains apart, over every window: where the windows
        # tell them apart (each within ``determined``, apart by more than z uncertainties and
        # ``kind_min``, and predicting the windows better); hx moves no foot vertically and goes
        # with hy (the hip's motors alike)
        X2 = np.c_[xs - knees, knees]
        beta, cov, _ = robust_fit(X2, ys)
        if np.all(beta > 0):
            g2 = 1.0 / beta
            sd2 = np.sqrt(np.diag(cov)) * g2 ** 2
            # and it predicts each window from the others with at most warp_cv of one gain's error
            if (np.all(sd2 <= limits.determined * g2) and abs(g2[0] - g2[1]) > limits.z * np.hypot(*sd2)
                    and abs(g2[0] / g2[1] - 1) > limits.kind_min
                    and loo_error(X2, ys) < limits.warp_cv * loo_error(xs[:, None], ys)):
                kinds = (float(g2[0]), float(g2[0]), float(g2[1]))
                kinds_sd = (float(sd2[0]), float(sd2[0]), float(sd2[1]))
                note = f"per joint kind, the hips' and the knees' apart over {xs.size} windows"
    applied = undetermined is None and bool(np.isfinite(sd)) and (kinds is not None or abs(gain - 1.0) > limits.z * sd)
    est = GainEstimate(gain=gain, sd=sd, static=gs, static_sd=gs_sd, static_windows=int(static.sum()), dynamic=gd,
                       dynamic_sd=gd_sd, dynamic_windows=int((~static).sum()), flight_force=flight,
                       applied=applied, note=note, kinds=kinds, kinds_sd=kinds_sd)
    return est, undetermined


# ----------------------------------------------------------------- the height

@dataclass(frozen=True)
class HeightEstimate:
    """The base-height offset of one jump: ``offset`` m is added to z (the feet in contact
    sat -offset above the ground), sd its uncertainty, over ``rows`` rows with a foot down;
    applied: z was changed."""

    offset: float
    sd: float
    rows: int
    applied: bool

    def to_dict(self) -> dict:
        return asdict(self)


def stance_offset(feet_z: np.ndarray, down: np.ndarray) -> tuple[float, np.ndarray]:
    """The offset that puts the feet in contact on the ground: the median over rows with a
    foot down of minus their feet's mean height; feet_z (n, 4) m, down (n, 4) bool. Returns
    it and the per-row values (nan: no foot down)."""
    count = down.sum(axis=1)
    per_row = np.full(down.shape[0], np.nan)
    rows = count > 0
    per_row[rows] = -(np.where(down, feet_z, 0.0).sum(axis=1)[rows] / count[rows])
    return (float(np.median(per_row[rows])) if rows.any() else float("nan")), per_row


def estimate_height(state: BodyState, contact: np.ndarray, limits: RepairLimits) -> HeightEstimate:
    """The height offset of one jump (module docstring); nan without a foot down."""
    down = np.asarray(contact).astype(bool)
    for k in range(N_LEGS):  # two rows off each change of the foot's flag: impact, lift-off
        down[:, k] &= ~_near_changes(contact[:, [k]], 2)
    offset, per_row = stance_offset(state.feet_z, down)
    values = per_row[np.isfinite(per_row)]
    if values.size == 0:
        return HeightEstimate(float("nan"), float("nan"), 0, False)
    mad = 1.4826 * float(np.median(np.abs(values - offset)))
    independent = max(values.size / 25.0, 1.0)  # rows 50 ms apart at 500 Hz count as independent
    sd = float(np.hypot(1.25 * mad / np.sqrt(independent), limits.height_floor))
    return HeightEstimate(offset, sd, int(values.size), abs(offset) > limits.z * sd)


# ----------------------------------------------------------------- contacts

@dataclass(frozen=True)
class ContactEstimate:
    """The contact flags of one jump: source ``logged`` or ``derived`` (the log held none);
    lag: rows the logged flags trailed the evidence by (moved back by it); votes: the moves
    of the isolated touch-downs and lift-offs that fit the evidence best ({move: count});
    changed: foot-rows changed; applied: the flags were changed; note: one line."""

    source: str
    lag: int
    touchdowns: dict
    liftoffs: dict
    changed: int
    applied: bool
    note: str

    def to_dict(self) -> dict:
        return asdict(self)


def grounded(state: BodyState, contact: np.ndarray, limits: RepairLimits) -> np.ndarray:
    """(n, 4) bool: each foot within ``foot_clearance`` of its stance level (its median
    height while flagged down) and slower vertically than ``foot_speed``."""
    down = np.asarray(contact).astype(bool)
    level = np.array([np.median(state.feet_z[down[:, k], k]) if down[:, k].any() else 0.0 for k in range(N_LEGS)])
    return (state.feet_z - level < limits.foot_clearance) & (np.abs(state.feet_vz) < limits.foot_speed)


def transition_moves(contact: np.ndarray, ground: np.ndarray, lag_max: int, half: int = 4
                     ) -> tuple[Counter, Counter]:
    """For each isolated change of a flag (no other change of that foot within
    2 half + lag_max rows), the move (rows, in -lag_max..lag_max) of the change that makes
    the flag agree best with ``ground`` (n, 4) over half + lag_max rows each side; ties are
    left out. Returns the touch-downs' and the lift-offs' moves counted."""
    n = contact.shape[0]
    td, lo = Counter(), Counter()
    reach = half + lag_max
    for k in range(contact.shape[1]):
        flag = np.asarray(contact[:, k]).astype(int)
        changes = np.flatnonzero(np.diff(flag) != 0) + 1
        for m, i in enumerate(changes):
            if i - reach < 0 or i + reach > n:
                continue
            if (m > 0 and changes[m - 1] > i - 2 * reach) or (m + 1 < changes.size and changes[m + 1] < i + 2 * reach):
                continue
            before, after = flag[i - 1], flag[i]
            evidence = ground[i - reach:i + reach, k].astype(int)
            cost = [int(np.sum(np.r_[np.full(reach + d, before), np.full(reach - d, after)] != evidence))
                    for d in range(-lag_max, lag_max + 1)]
            best = np.flatnonzero(np.array(cost) == min(cost))
            if best.size == 1:
                (td if after else lo)[int(best[0]) - lag_max] += 1
    return td, lo


def contact_lag(state: BodyState, contact: np.ndarray, limits: RepairLimits) -> tuple[int, Counter, Counter]:
    """The rows the logged flags trail the evidence by (module docstring): 0 where the
    touch-downs and the lift-offs do not agree on one move."""
    td, lo = transition_moves(contact, grounded(state, contact, limits), limits.lag_max)

    def mode(c: Counter) -> int | None:
        top = c.most_common(2)
        if not top or top[0][1] < 2 or (len(top) > 1 and top[1][1] == top[0][1]):
            return None
        return top[0][0]

    a, b = mode(td), mode(lo)
    return (-a if a is not None and a == b and a != 0 else 0), td, lo


def shift_flags(contact: np.ndarray, lag: int) -> np.ndarray:
    """Flags (n, 4) moved ``lag`` rows earlier (a logger's lag undone); the last rows hold the
    last flag."""
    if lag == 0:
        return np.asarray(contact).copy()
    out = np.empty_like(contact)
    if lag > 0:
        out[:-lag] = contact[lag:]
        out[-lag:] = contact[-1]
    else:
        out[-lag:] = contact[:lag]
        out[:-lag] = contact[0]
    return out
