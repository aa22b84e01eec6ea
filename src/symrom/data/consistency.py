"""Physical consistency of a log, checked at import: what plausible ranges cannot catch.

A value can be within every range (``checks``) and the log still be wrong as a
whole. Per jump of a log:

- **time scale** (``time_scale``): the positions must change as fast as the
  logged velocities say. Over windows of ``ConsistencyLimits.window`` s, the
  change of each position is compared with the trapezoidal integral of its
  velocity in the logged time; the ratio of the two (least squares over the
  windows together, ``pooled_ratio``: windows far off the others, an impact, stale
  rows or a seam in a continuous recording, left out) is 1 on a consistent log. A time column scaled by the
  wrong period (loop iterations 1.16 ms apart logged as 1 ms) gives the period
  ratio; velocities in other units give their factor. Checked per group:
  the 12 joint angles and the base position (the base angles change too
  little over a jump against an estimator's noise: 1.11 on a noisy proxy
  jump whose time base is right).
- **stale rows** (``stale_rows``): a row whose joint group (angles, rates,
  torques) or base group (pose, rates) repeats the previous row exactly is a
  stale sensor read; the sensor then catches up several steps at once.
  Reported per jump and group; ``retime_stale`` replaces the repeats by the
  modified Akima interpolation between the fresh rows, each fresh row kept at
  its own time (the instant its value arrived).
- **vertical momentum** (``vertical_impulse``): over a jump, the vertical
  ground force (from the torques through the legs' Jacobians, feet in contact)
  integrated over time must equal m g T plus the change of vertical momentum.
  Their ratio is about 0.9 on simulated Go1 jumps (the legs' own dynamics are
  left out) and 1.0-1.09 on them read as an A1; a sign-flipped torque column
  gives a negative ratio, a robot twice as heavy about 0.3.
- **foot height** (``foot_height``): the feet in contact, placed by the
  robot's URDF from the logged base pose and joint angles, must touch the
  ground (their centres one foot radius above z = 0). A log of a robot with
  other leg lengths puts them above or below it: a Go1 log read as an A1
  puts its stance feet 15 mm up (the A1's thigh and calf are 13 mm shorter
  each), where the Go1's own URDF puts them within 3 mm. Jumps whose height
  was restored from the feet (``importers.restore_height``) are not checked:
  their feet touch the ground by construction.

Each check returns problems as dicts with a one-line ``message`` naming the
file, jump, rows, the figure and the limit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from symrom.names import BASE_POS, GRAVITY, JOINTS

# Groups of the time-scale check: (name, q columns, unit).
SCALE_GROUPS = (("joint angles", JOINTS, "rad"), ("base position", BASE_POS, "m"))


@dataclass(frozen=True)
class ConsistencyLimits:
    """How far a log may depart from physics before it is refused.

    window: s, the windows of the time-scale check; scale: largest relative
    departure of the position/velocity ratio from 1 (0.05: a 16 % time-scale
    error is caught; the simulated Go1 jumps stay within 0.4 %, the noisy and
    proxy jumps within 1.5 %);
    min_motion: the least RMS change per window (in the group's unit) for a
    window to count (standing still says nothing about the time scale);
    impulse: (low, high) allowed ratio of the vertical ground impulse to m g T +
    m dv_z; foot_height: m, largest |median height| of the feet in contact
    above the ground (the simulated and proxy Go1 logs: within 0.1 mm median,
    3 mm at the 10th/90th percentile).
    """

    window: float = 0.05
    scale: float = 0.05
    min_motion: float = 1e-3
    impulse: tuple[float, float] = (0.6, 1.5)
    foot_height: float = 0.008

    def to_dict(self) -> dict:
        return asdict(self)


def _rows(a: int, b: int) -> str:
    return f"rows {a}-{b - 1}"


def window_ratios(t: np.ndarray, x: np.ndarray, v: np.ndarray, window: float,
                  min_motion: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions against their integrated velocities, window by window: t (n,) s, x, v (n, d)
    one group's positions and velocities. Windows of ``window`` s of t share their edge
    samples; a window whose velocities integrate to an RMS change below ``min_motion`` is
    left out. Returns per window kept its first and last row (k, 2), its ratio (k,) (the
    least-squares factor of the change of x over the trapezoidal integral of v) and its
    integral's sum of squares (k,)."""
    n = t.size
    rows, ratios, power = [], [], []
    if n < 3:
        return np.zeros((0, 2), int), np.zeros(0), np.zeros(0)
    edges = np.searchsorted(t, np.arange(t[0], t[-1] + window, window))
    edges = np.unique(np.r_[edges, n])
    for a, b in zip(edges[:-1], edges[1:]):
        b = min(b + 1, n)  # windows share their edge sample
        if b - a < 3:
            continue
        change = x[b - 1] - x[a]
        integral = np.trapezoid(v[a:b], t[a:b], axis=0)
        if np.sqrt(np.mean(integral ** 2)) < min_motion:
            continue
        rows.append((a, b - 1))
        ratios.append(float(change @ integral / (integral @ integral)))
        power.append(float(integral @ integral))
    return np.array(rows, int).reshape(-1, 2), np.array(ratios), np.array(power)


def pooled_ratio(ratios: np.ndarray, power: np.ndarray) -> float:
    """The least-squares ratio of windows together: ratios (k,) and power (k,) as
    ``window_ratios`` returns them, each window weighted by its motion, windows beyond Tukey's
    far-out fences (3 interquartile ranges outside the quartiles: an impact, a seam, stale
    reads caught up) left out. A median over windows is as noisy as the windows with the
    least motion: the base position's on a noisy proxy log scatter 0.4-1.9 on a right clock."""
    q1, q3 = np.percentile(ratios, [25, 75])
    keep = (ratios >= q1 - 3 * (q3 - q1)) & (ratios <= q3 + 3 * (q3 - q1))
    return float(np.sum(ratios[keep] * power[keep]) / np.sum(power[keep]))


def time_scale(where: str, t: np.ndarray, q: np.ndarray, dq: np.ndarray,
               limits: ConsistencyLimits) -> list[dict]:
    """Problems of one jump's time scale: t (n,) s, q, dq (n, 18). ``where``: 'FILE, jump J'."""
    out = []
    n = t.size
    if n < 3:
        return out
    for name, cols, _unit in SCALE_GROUPS:
        x = np.unwrap(q[:, cols], axis=0) if name == "base angles" else q[:, cols]
        _, ratios, power = window_ratios(t, x, dq[:, cols], limits.window, limits.min_motion)
        if len(ratios) < 3:
            continue
        r = pooled_ratio(ratios, power)
        if abs(r - 1.0) <= limits.scale:
            continue
        step = float(np.median(np.diff(t)))
        if 40 < r < 80 or 1 / 80 < r < 1 / 40:
            hint = "the velocities look like degrees/s against positions in rad (or the reverse)"
        elif 500 < r < 2000 or 1 / 2000 < r < 1 / 500:
            hint = "the time column looks like ms read as s (or the reverse)"
        elif r < 0:
            hint = "the velocities have the opposite sign of the positions' change"
        else:
            hint = (f"the time column is likely scaled: rows {1e3 * step * r:.3g} ms apart logged as "
                    f"{1e3 * step:.4g} ms (log the true times; a given dt does not fix it), or the velocities "
                    f"are in other units")
        out.append({"check": "time scale", "group": name, "value": r, "low": 1 - limits.scale,
                    "high": 1 + limits.scale, "windows": len(ratios),
                    "message": (f"{where}, {_rows(0, n)}: the {name} change {r:.3g} times as fast as the "
                                f"logged velocities integrate to (least squares over {len(ratios)} windows of "
                                f"{1e3 * limits.window:g} ms); the limit is "
                                f"{1 - limits.scale:g}..{1 + limits.scale:g}: {hint}")})
    return out


# ----------------------------------------------------------------- stale rows

STALE_GROUPS = ("joints", "base")


def _group_arrays(q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> dict[str, list[tuple[np.ndarray, slice]]]:
    """The arrays of each stale-row group and their columns."""
    return {"joints": [(q, JOINTS), (dq, JOINTS), (tau, slice(None))],
            "base": [(q, slice(12, 18)), (dq, slice(12, 18))]}


def stale_mask(q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> dict[str, np.ndarray]:
    """Per group, (n,) True where the row repeats the previous row exactly (row 0: False).
    q, dq (n, 18), tau (n, 12) of one jump."""
    out = {}
    for g, parts in _group_arrays(q, dq, tau).items():
        same = np.ones(q.shape[0] - 1, bool)
        for x, cols in parts:
            same &= np.all(x[1:, cols] == x[:-1, cols], axis=1)
        out[g] = np.r_[False, same]
    return out


def stale_rows(where: str, jump: int, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> list[dict]:
    """A report per group holding stale rows in one jump: count, fraction, longest run."""
    out = []
    n = q.shape[0]
    for g, m in stale_mask(q, dq, tau).items():
        if not m.any():
            continue
        edges = np.diff(np.r_[0, m.astype(int), 0])
        runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
        out.append({"jump": jump, "group": g, "rows": int(m.sum()), "of": n,
                    "fraction": round(float(m.mean()), 4), "longest_run": int(runs.max()),
                    "first_row": int(np.flatnonzero(m)[0]),
                    "message": (f"{where}: {int(m.sum())} of {n} rows ({100 * m.mean():.3g} %) repeat the "
                                f"previous row's {g} exactly (stale reads; longest run {int(runs.max())}, first "
                                f"at row {int(np.flatnonzero(m)[0])})")})
    return out


def retime_stale(t: np.ndarray, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> dict[str, int]:
    """Replace the stale rows of one jump (in place) by the modified Akima interpolation
    between its fresh rows, per group; rows after the last fresh one keep its value.
    Returns the rows replaced per group."""
    from scipy.interpolate import Akima1DInterpolator

    done = {}
    for g, m in stale_mask(q, dq, tau).items():
        fresh = np.flatnonzero(~m)
        inner = np.flatnonzero(m & (np.arange(m.size) < fresh[-1]))
        if inner.size == 0 or fresh.size < 2:
            continue
        for x, cols in _group_arrays(q, dq, tau)[g]:
            y = x[:, cols]
            if fresh.size >= 3:
                y[inner] = Akima1DInterpolator(t[fresh], y[fresh], axis=0, method="makima")(t[inner])
            else:
                y[inner] = np.stack([np.interp(t[inner], t[fresh], c) for c in y[fresh].T], axis=1)
            x[:, cols] = y
        done[g] = int(inner.size)
    return done


# ----------------------------------------------------------------- forces

def vertical_impulse(where: str, robot: str, t: np.ndarray, q: np.ndarray, dq: np.ndarray,
                     tau: np.ndarray, contact: np.ndarray, limits: ConsistencyLimits) -> list[dict]:
    """The vertical momentum balance of one jump (module docstring); none without a contact row."""
    from symrom.data.preprocess import ground_reaction_forces
    from symrom.robots import get_robot

    if t.size < 2 or not np.asarray(contact).any():
        return []
    m = get_robot(robot).mass
    fz = ground_reaction_forces(robot, q, tau, contact)[:, :, 2].sum(axis=1)  # (n,) N
    span = float(t[-1] - t[0])
    need = m * GRAVITY * span + m * float(dq[-1, 14] - dq[0, 14])
    got = float(np.trapezoid(fz, t))
    if need <= 0:
        return []
    r = got / need
    lo, hi = limits.impulse
    if lo <= r <= hi:
        return []
    stance = np.asarray(contact).any(axis=1)
    if r < 0:
        hint = "the torques have the opposite sign (the joints' convention is not the robot description's)"
    elif r < lo:
        hint = ("a torque column with its sign flipped (the knees carry the weight), the wrong robot (a "
                "heavier one) or torques in other units")
    else:
        hint = "the wrong robot (a lighter one) or torques in other units"
    return [{"check": "vertical impulse", "value": r, "low": lo, "high": hi,
             "message": (f"{where}, {_rows(0, t.size)}: the feet push up with {got / span:.4g} N on average "
                         f"(mean over the jump; {float(fz[stance].mean()):.4g} N over its {int(stance.sum())} rows "
                         f"with a foot down), the robot's weight {m * GRAVITY:.4g} N and its change of vertical "
                         f"momentum need {need / span:.4g} N: ratio {r:.3g}, the limit is {lo:g}..{hi:g}; {hint}")}]


def foot_height(where: str, robot: str, q: np.ndarray, contact: np.ndarray,
                limits: ConsistencyLimits) -> list[dict]:
    """Whether the feet in contact touch the ground by the robot's URDF (module docstring)."""
    from symrom.data.preprocess import foot_positions_world
    from symrom.robots import get_robot

    down = np.asarray(contact).astype(bool)
    if not down.any():
        return []
    desc = get_robot(robot)
    z = foot_positions_world(robot, q)[:, :, 2] - desc.foot_radius  # (n, 4) m above the ground
    h = float(np.median(z[down]))
    if abs(h) <= limits.foot_height:
        return []
    rows = np.flatnonzero(down.any(axis=1))
    return [{"check": "foot height", "value": h, "low": -limits.foot_height, "high": limits.foot_height,
             "message": (f"{where}, {_rows(int(rows[0]), int(rows[-1]) + 1)}: by the {desc.name} URDF the feet in "
                         f"contact sit {1e3 * h:.3g} mm {'above' if h > 0 else 'below'} the ground (median over "
                         f"{int(down.sum())} foot-rows); the limit is {1e3 * limits.foot_height:g} mm: the log "
                         f"is likely of another robot (legs of another length) or its base height is offset "
                         f"(positions='rebased' restores it from the feet)")}]
