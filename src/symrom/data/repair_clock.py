"""The repair's time base: a logged jump's clock and velocities checked against a physical clock.

Two faults make a jump's positions change ``rho`` times as fast as its velocities integrate
to in the logged time (``consistency.window_ratios``, the import's time-scale check):

- a wrong clock: the rows are truly ``s`` logged seconds apart per logged second (a loop
  slower than its nominal rate, a period estimated wrongly), the velocities right: rho = s;
- wrong velocities: the logged velocities are ``k`` times the true ones (a unit, a filter, a
  differencing step), the clock right: rho = 1 / k.

Both at once give rho = s / k. The ballistic flight tells them apart: in flight the whole
body's centre of mass (``robots.masses``, from the robot description, not the base: a Go1's
legs are 60 % of its mass and their swing moves the base against it) falls at g in true
time, so in the logged time it falls at g s^2. Fitted on the rho-corrected clock (the
positions' own clock, velocities assumed right), the flight falls at kappa^2 g with kappa = k:
kappa = 1 is a wrong clock, kappa = 1 / rho wrong velocities.

Per jump (``estimate_clock``):

1. rho window by window (50 ms, in the logged time), on the joints (the base position where
   the joints barely move), fitted robustly together with a lag of the positions behind the
   velocities (a filter, a sampling offset); its level and, where the rate changes within
   the jump, a smooth rate: a cubic spline in the logged time with 1, 2, 4 ... pieces (at
   most one per ``RepairLimits.knot`` s), taken where it predicts each window from the
   others with at most ``warp_cv`` of a constant's error and moves by more than
   ``warp_min`` (a rate changing within a jump is a clock: a velocity gain is a constant);
2. the flight: a parabola in the rho-corrected time through the centre of mass's height
   over every flight (no foot down for ``min_flight`` s, ``flight_trim`` rows cut at each end
   for the touch-down and lift-off), one acceleration shared by the flights;
3. the finding: nothing (rho within ``z`` uncertainties of 1, no change of rate); a wrong
   clock (the flight at kappa = 1); wrong velocities (kappa = 1 / rho, no change of rate); both
   (neither fits: kappa from the flight); undetermined (no flight, or both fit);
4. the clock's rows then lie at T(t) = integral of s (a uniform scale or a monotone warp),
   and each velocity group's gain is its own windows' ratio to s (``velocity_gains``): the
   joints, the base position and the base angles (a group whose windows do not determine
   its gain, the base of a noisy estimator, takes the gain the others agree on where its
   windows do not contradict it, and stays as logged otherwise).

Refused (``RepairError`` naming the file, jump and figures): the windows scattering about the
smooth rate by more than ``RepairLimits.scatter`` (and 3 times their own noise: a rate that
changes faster than the windows resolve), a rate that is not positive. Undetermined faults
are refused by the repair's caller unless the jump passes the consistency check as logged.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from symrom.data.consistency import window_ratios
from symrom.data.rawlog import LogError
from symrom.names import BASE_POS, BASE_RPY, JOINTS
from symrom.names import GRAVITY as G

if TYPE_CHECKING:  # scipy.interpolate is slow to import: loaded where a clock's rate is fitted
    from scipy.interpolate import BSpline

# Velocity groups, each with its own gain: (name, q columns).
VELOCITY_GROUPS = (("joints", JOINTS), ("base position", BASE_POS), ("base angles", BASE_RPY))


class RepairError(LogError):
    """A fault of a log that the data cannot determine; one line naming the file and jump."""


@dataclass(frozen=True)
class RepairLimits:
    """How the repair estimates and decides (``data.repair``).

    z: an estimate is applied when it departs from "nothing to repair" by more than z of
    its uncertainties (each uncertainty includes its floor below);
    window: s, the time-scale windows; knot: s, the spacing of a time warp's knots;
    warp_min: a rate changing by less than this (relative) within a jump is uniform;
    warp_cv: a warp is fitted where it predicts each window from the others with at most
    this fraction of a uniform scale's error (median over the windows), and torque gains per
    joint kind where they predict the momentum windows so against one gain;
    scatter: the windows' largest robust scatter about the fitted rate (relative) before the
    rate is taken to change faster than the windows resolve; ratio_floor: relative floor of
    the position/velocity ratio's uncertainty; determined: a velocity group whose gain is
    less certain than this (relative) takes the others' gain where it fits it; min_flight: s, the shortest
    flight fitted; flight_trim: rows cut at each end of a flight; flight_floor: relative
    floor of the flight's acceleration's uncertainty (a state estimator's height in flight);
    gain_window: s, the windows of the vertical momentum balance; static: the largest mean
    vertical acceleration of a quasi-static window, in g; static_floor, dynamic_floor:
    relative floors of the torque gain's uncertainty from quasi-static and from dynamic
    windows (the legs' own inertia is left out of the balance: 2 % on simulated Go1 jumps);
    min_static: the fewest quasi-static windows that give the gain on their own;
    gain_spread: the largest factor between the dynamic and the quasi-static windows' gains
    for one gain to describe the torques; kind_min: the least relative difference between
    the hips' and the knees' gains for a gain per joint kind;
    height_floor: m, floor of the height offset's uncertainty (the feet's contact model);
    lag_max: rows, the largest contact lag looked for; foot_clearance: m, a foot higher
    than this above its stance level, or foot_speed m/s, moving faster vertically, is in
    the air (the evidence the contact flags are checked against).
    """

    z: float = 3.0
    window: float = 0.05
    knot: float = 0.25
    warp_min: float = 0.01
    warp_cv: float = 0.5
    scatter: float = 0.02
    ratio_floor: float = 0.002
    determined: float = 0.02
    min_flight: float = 0.04
    flight_trim: int = 3
    flight_floor: float = 0.02
    gain_window: float = 0.1
    static: float = 0.05
    static_floor: float = 0.01
    dynamic_floor: float = 0.03
    min_static: int = 2
    gain_spread: float = 1.3
    kind_min: float = 0.05
    height_floor: float = 0.001
    lag_max: int = 3
    foot_clearance: float = 0.004
    foot_speed: float = 0.1

    def __post_init__(self) -> None:
        for name in ("z", "window", "knot", "warp_min", "warp_cv", "scatter", "ratio_floor", "determined",
                     "min_flight", "flight_floor", "gain_window", "static", "static_floor", "dynamic_floor",
                     "gain_spread", "kind_min", "height_floor", "foot_clearance", "foot_speed"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"repair limit {name} = {v}: must be a positive number")

    def to_dict(self) -> dict:
        return asdict(self)


# ----------------------------------------------------------------- robust fitting

def robust_fit(X: np.ndarray, y: np.ndarray, c: float = 2.0, iters: int = 50
               ) -> tuple[np.ndarray, np.ndarray, float]:
    """Huber regression of y (n,) on X (n, p) by iteratively reweighted least squares.
    Returns the coefficients (p,), their covariance (p, p) and the residuals' robust scale
    (1.4826 MAD, never below 1e-12 of the data's)."""
    X, y = np.asarray(X, float), np.asarray(y, float)
    w = np.ones(y.size)
    beta = np.zeros(X.shape[1])
    floor = 1e-12 * max(float(np.abs(y).max(initial=0.0)), 1e-300)
    for _ in range(iters):
        sw = np.sqrt(w)
        beta_new = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)[0]
        r = y - X @ beta_new
        scale = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), floor)
        w = np.minimum(1.0, c * scale / np.maximum(np.abs(r), 1e-300))
        done = np.allclose(beta_new, beta, rtol=1e-10, atol=1e-14)
        beta = beta_new
        if done:
            break
    r = y - X @ beta
    scale = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), floor)
    n, p = X.shape
    xtwx = (X * w[:, None]).T @ X
    # Huber's sandwich with the efficiency factor of the weights (Huber 1981, 7.6)
    eff = float(np.mean(w >= 1.0)) or 1.0 / n
    cov = np.linalg.pinv(xtwx) * scale ** 2 * (n / max(n - p, 1)) / eff
    return beta, cov, scale


# ----------------------------------------------------------------- records

@dataclass(frozen=True)
class ClockEstimate:
    """The time base of one jump (module docstring).

    finding: ``none``, ``clock``, ``velocities``, ``clock and velocities`` or
    ``undetermined``; ratio, ratio_sd: the positions change ``ratio`` times as fast as the
    logged velocities integrate to (the primary group's level over ``windows`` windows);
    group: that group; lag: s, the positions' lag behind the velocities fitted with it;
    warp: the rate changes within the jump (a time warp); scale, scale_sd: the true
    duration over the logged one (1.0: the clock as logged); rate_low,
    rate_high: the lowest and highest rate (true s per logged s); knots, rates: the warp's
    rate at its knots (logged s; empty for a uniform scale); scatter: the windows' robust
    scatter about the fitted rate; flight_g, flight_g_sd: the centre of mass's acceleration
    in flight on the repaired clock, in g (None: no flight), over flight_rows rows;
    applied: the rows' times were changed; note: what was decided and why, one line.
    """

    finding: str
    ratio: float
    ratio_sd: float
    windows: int
    group: str
    lag: float
    warp: bool
    scale: float
    scale_sd: float
    rate_low: float
    rate_high: float
    knots: tuple[float, ...]
    rates: tuple[float, ...]
    scatter: float
    flight_g: float | None
    flight_g_sd: float | None
    flight_rows: int
    applied: bool
    note: str

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class VelocityGain:
    """One velocity group's gain: the logged velocities are ``gain`` times the true ones
    (``sd`` its uncertainty, over ``windows`` windows); applied: the group's velocities were
    divided by it; how: ``estimated`` (its own windows), ``as the other velocities`` (its
    windows do not determine it, and fit the determined groups' common gain) or
    ``undetermined`` (left as logged)."""

    group: str
    gain: float
    sd: float
    windows: int
    applied: bool
    how: str

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Rate:
    """True seconds per logged second as a function of the logged time t: a constant
    (``spline`` None) or a cubic spline on [lo, hi], held constant outside."""

    level: float
    spline: BSpline | None = None
    lo: float = 0.0
    hi: float = 0.0
    sd: float = 0.0  # the uncertainty of its mean over [lo, hi]

    def __call__(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)
        if self.spline is None:
            return np.full(t.shape, self.level)
        return self.spline(np.clip(t, self.lo, self.hi))

    def times(self, t: np.ndarray) -> np.ndarray:
        """The true time since the jump's first row (n,) s of logged times t (n,) s from 0."""
        t = np.asarray(t, float)
        if self.spline is None:
            return self.level * t
        F = self.spline.antiderivative()
        f_lo, f_hi = float(self.spline(self.lo)), float(self.spline(self.hi))
        inner = np.clip(t, self.lo, self.hi)
        return (f_lo * np.minimum(t, self.lo) + (F(inner) - F(self.lo))
                + f_hi * np.maximum(t - self.hi, 0.0))

    def scaled(self, k: float) -> Rate:
        from scipy.interpolate import BSpline

        return Rate(self.level * k, None if self.spline is None else
                    BSpline(self.spline.t, self.spline.c * k, self.spline.k), self.lo, self.hi, self.sd * k)


# ----------------------------------------------------------------- windows and the rate

@dataclass(frozen=True)
class _Windows:
    """One group's windows: centres (k,) logged s, ratios (k,), rows (k, 2), noise (k,): the
    ratio's spread across the group's columns within the window; lead (k,) 1/s: the change
    of velocity over the window projected like its ratio, which a lag between positions and
    velocities multiplies into the ratio (a lag of d s moves it by about -d lead)."""
    centre: np.ndarray
    ratio: np.ndarray
    rows: np.ndarray
    noise: np.ndarray
    lead: np.ndarray


def _windows(t: np.ndarray, q: np.ndarray, dq: np.ndarray, cols: slice, limits: RepairLimits,
             min_motion: float) -> _Windows:
    x = np.unwrap(q[:, cols], axis=0) if cols == BASE_RPY else q[:, cols]
    v = dq[:, cols]
    rows, ratio, power = window_ratios(t, x, v, limits.window, min_motion)
    noise, lead = np.empty(ratio.size), np.empty(ratio.size)
    for i, (a, b) in enumerate(rows):
        change = x[b] - x[a]
        integral = np.trapezoid(v[a:b + 1], t[a:b + 1], axis=0)
        e = change - ratio[i] * integral
        noise[i] = np.sqrt(e @ e / max(e.size - 1, 1) / power[i])
        lead[i] = (v[b] - v[a]) @ integral / power[i]
    centre = 0.5 * (t[rows[:, 0]] + t[rows[:, 1]]) if rows.size else np.zeros(0)
    return _Windows(centre, ratio, rows, noise, lead)


def _level(w: _Windows, floor: float) -> tuple[float, float, float, float]:
    """The robust level of a group's window ratios, its uncertainty (with the floor), the
    windows' robust scatter about it and the lag of the positions behind the velocities (s)
    fitted with it (a filter or a sampling offset between them: 0.5 ms in symrom's
    simulator, whose windows scatter 0.7 % without it and 0.01 % with it)."""
    beta, cov, scale = robust_fit(np.c_[np.ones(w.ratio.size), w.lead], w.ratio)
    level = float(beta[0])
    return level, float(np.hypot(np.sqrt(cov[0, 0]), floor * abs(level))), scale, -float(beta[1]) / level


def loo_error(X: np.ndarray, y: np.ndarray) -> float:
    """The median absolute error of predicting each row of y from the others, by the robust
    fit's final weights (the weighted least squares' leave-one-out residuals r / (1 - h))."""
    beta, _, scale = robust_fit(X, y)
    r = y - X @ beta
    w = np.minimum(1.0, 2.0 * scale / np.maximum(np.abs(r), 1e-300))
    h = np.einsum("ij,jk,ik->i", X, np.linalg.pinv((X * w[:, None]).T @ X), X) * w
    return float(np.median(np.abs(r / np.maximum(1.0 - h, 1e-3))))


def _spline_rate(w: _Windows, limits: RepairLimits) -> tuple[Rate, np.ndarray, float, float]:
    """The smooth rate that best predicts the windows it is not fitted to: a cubic spline in
    time through the windows' ratios (robust, with the lag of ``_level``), with 1, 2, 4 ...
    pieces up to one per ``knot`` s, chosen by leave-one-out prediction. Returns the rate,
    its value at the windows, the windows' scatter about it and its leave-one-out error as a
    fraction of a constant's."""
    from scipy.interpolate import BSpline

    # held constant over the first and last windows: a jump's ends (a start from rest, a log
    # cut anywhere) are where the windows fit worst, and an end coefficient would follow them
    lo, hi = float(w.centre[1]), float(w.centre[-2])
    most = max(1, min(int(round((hi - lo) / limits.knot)), (w.ratio.size - 5) // 3))
    base = loo_error(np.c_[np.ones(w.ratio.size), w.lead], w.ratio)
    best = None
    pieces = 1
    while True:
        knots = np.r_[[lo] * 4, np.linspace(lo, hi, pieces + 1)[1:-1], [hi] * 4]
        B = BSpline.design_matrix(np.clip(w.centre, lo, hi), knots, 3).toarray()
        X = np.c_[B, w.lead]
        err = loo_error(X, w.ratio)
        if best is None or err < best[0]:
            best = (err, knots, B, X)
        if pieces >= most:
            break
        pieces = min(2 * pieces, most)
    err, knots, B, X = best
    beta, cov, scale = robust_fit(X, w.ratio)
    fit = B @ beta[:-1]
    mean = BSpline.design_matrix(np.linspace(lo, hi, 101), knots, 3).toarray().mean(axis=0)
    mean_sd = float(np.sqrt(mean @ cov[:-1, :-1] @ mean))
    return (Rate(float(np.mean(fit)), BSpline(knots, beta[:-1], 3), lo, hi, mean_sd), fit, scale,
            err / max(base, 1e-300))


# ----------------------------------------------------------------- the flight

def flight_runs(contact: np.ndarray, t: np.ndarray, limits: RepairLimits) -> list[tuple[int, int]]:
    """[start, stop) rows of the flights (no foot down for at least ``min_flight`` logged s),
    ``flight_trim`` rows cut at each end."""
    air = np.r_[0, (np.asarray(contact).sum(axis=1) == 0).astype(int), 0]
    starts, stops = np.flatnonzero(np.diff(air) == 1), np.flatnonzero(np.diff(air) == -1)
    out = []
    for a, b in zip(starts, stops):
        a, b = int(a) + limits.flight_trim, int(b) - limits.flight_trim
        if b - a >= 5 and t[b - 1] - t[a] >= limits.min_flight:
            out.append((a, b))
    return out


def flight_fall(T: np.ndarray, z: np.ndarray, runs: list[tuple[int, int]], floor: float
                ) -> tuple[float | None, float | None, int]:
    """The acceleration of a fall, in g, and its uncertainty (relative floor included), from
    heights z (n,) m at times T (n,) s over the runs: one parabola per run sharing its
    second derivative. (None, None, 0) without a run."""
    if not runs:
        return None, None, 0
    n = sum(b - a for a, b in runs)
    X = np.zeros((n, 2 * len(runs) + 1))
    y = np.empty(n)
    row = 0
    for i, (a, b) in enumerate(runs):
        tau = T[a:b] - T[a:b].mean()
        X[row:row + b - a, 2 * i] = 1.0
        X[row:row + b - a, 2 * i + 1] = tau
        X[row:row + b - a, -1] = -0.5 * tau ** 2
        y[row:row + b - a] = z[a:b]
        row += b - a
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ beta
    dof = max(n - X.shape[1], 1)
    # residuals of an estimator are correlated: count the independent ones
    phi = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.95)) if n > 3 and r.std() > 0 else 0.0
    var = r @ r / dof * (1 + phi) / (1 - phi)
    sd = float(np.sqrt(var * np.linalg.pinv(X.T @ X)[-1, -1]))
    a = float(beta[-1]) / G
    return a, float(np.hypot(sd / G, floor * abs(a))), n


# ----------------------------------------------------------------- the estimate

@dataclass(frozen=True)
class ClockFit:
    """What ``estimate_clock`` found: the record, the velocity gains and the true times of
    the rows (None: as logged)."""

    clock: ClockEstimate
    velocities: tuple[VelocityGain, ...]
    times: np.ndarray | None
    undetermined: str | None  # the one-line reason, when a fault is found but not determined
    evidence: tuple[float, float] | None = None  # the flight's z against a wrong clock and against wrong velocities


# chi-square bound of n standardised flights that fit a hypothesis at ``RepairLimits.z`` (3: 99.73 %)
def _fits(z2: float, n: int, z: float) -> bool:
    from scipy.stats import chi2, norm

    return z2 <= chi2.ppf(2 * norm.cdf(z) - 1, n)


def file_kind(fits: list[ClockFit], limits: RepairLimits) -> tuple[str | None, str]:
    """What the flights of one file's jumps say together about its time base, where one jump's
    flight fits a wrong clock and wrong velocities alike (``estimate_clock``'s ``undetermined``):
    ``clock`` or ``velocities`` when all the flights of the jumps with a fault (``evidence``)
    fit that one at ``limits.z`` (a chi-square over them) and not the other, else None; and
    the figures in words. One logger writes a file: a loop slower than its rate, or velocities
    off, is its fault in every jump (how much may differ between jumps)."""
    ev = [f.evidence for f in fits if f.evidence is not None]
    if len(ev) < 2:
        return None, ""
    zc, zv = (float(sum(e[i] ** 2 for e in ev)) for i in (0, 1))
    clock, vel = _fits(zc, len(ev), limits.z), _fits(zv, len(ev), limits.z)
    words = (f"the file's {len(ev)} flights together: chi-square {zc:.3g} for a wrong clock, "
             f"{zv:.3g} for wrong velocities")
    if clock and not vel:
        return "clock", words
    if vel and not clock:
        return "velocities", words
    return None, words


def estimate_clock(where: str, t: np.ndarray, q: np.ndarray, dq: np.ndarray, contact: np.ndarray,
                   com_z: np.ndarray, limits: RepairLimits, min_motion: float,
                   grounded: np.ndarray | None = None, kind: tuple[str, str] | None = None) -> ClockFit:
    """The time base of one jump (module docstring): t (n,) logged s since its first row, q,
    dq (n, 18), contact (n, 4), com_z (n,) m the centre of mass's height; min_motion: the
    time-scale check's least RMS change per window; grounded (n, 4): the feet the heights and
    speeds put on the ground, whose flights stand in where the flags show none (a contact
    sensor that never lets go). ``where``: 'FILE, jump J'. kind: (``clock`` or ``velocities``,
    why) the file's flights together say (``file_kind``), taken where this jump's flight fits
    both alike."""
    groups = {name: _windows(t, q, dq, cols, limits, min_motion) for name, cols in VELOCITY_GROUPS}
    primary = next((g for g in ("joints", "base position") if groups[g].ratio.size >= 3), None)
    runs = flight_runs(contact, t, limits)
    from_feet = not runs and grounded is not None
    if from_feet:
        runs = flight_runs(grounded, t, limits)
    if primary is None:  # nothing moves enough to say
        fg, fsd, frows = flight_fall(t, com_z, runs, limits.flight_floor)
        clock = ClockEstimate("none", 1.0, float("nan"), 0, "", 0.0, False, 1.0, 0.0, 1.0, 1.0, (), (), 0.0,
                              fg, fsd, frows, False, "too little motion for the time scale")
        gains = tuple(VelocityGain(g, 1.0, float("nan"), 0, False, "undetermined") for g, _ in VELOCITY_GROUPS)
        return ClockFit(clock, gains, None, None)
    w = groups[primary]
    level, level_sd, scatter, lag = _level(w, limits.ratio_floor)
    rate = Rate(level)
    warp = False
    if w.ratio.size >= 8:
        # a warp must predict the windows it is not fitted to better than a uniform scale does
        spline, fit, spline_scatter, cv = _spline_rate(w, limits)
        if cv < limits.warp_cv and np.max(np.abs(fit - level)) > limits.warp_min:
            rate, warp, scatter = spline, True, spline_scatter
            level, level_sd = spline.level, float(np.hypot(spline.sd, limits.ratio_floor * spline.level))
    noise = float(np.median(w.noise))
    if scatter > limits.scatter and scatter > 3 * noise:
        raise RepairError(f"{where}: the rate of the clock changes faster than the {1e3 * limits.window:g} ms "
                          f"windows resolve: the {primary}' position/velocity ratio scatters by "
                          f"{100 * scatter:.3g} % about the smoothest rate that fits (the limit is "
                          f"{100 * limits.scatter:g} %; within a window the columns agree to {100 * noise:.2g} %)")
    grid = np.linspace(0.0, float(t[-1]), 200)
    if np.min(rate(grid)) <= 0:
        raise RepairError(f"{where}: the position/velocity ratio of the {primary} falls to "
                          f"{np.min(rate(grid)):.3g}: no clock runs backwards")
    off = abs(level - 1.0) > limits.z * level_sd
    T_rho = rate.times(t)
    fg, fsd, frows = flight_fall(T_rho, com_z, runs, limits.flight_floor)  # kappa^2 on the rho clock
    undetermined = evidence = None
    note_kind = ""
    kappa = 1.0
    kappa_sd = 0.0
    if not warp and not off:
        finding, scale = "none", Rate(1.0)
        note = f"positions and velocities agree ({level:.4g} +- {level_sd:.2g})"
    elif fg is None:
        finding, scale = "undetermined", Rate(1.0)
        undetermined = (f"{where}: the {primary} change {level:.4g} times as fast as the velocities integrate to"
                        f"{' (the rate changes within the jump)' if warp else ''}, and without a flight "
                        f"(no foot down for {1e3 * limits.min_flight:g} ms) a wrong clock cannot be told from "
                        f"wrong velocities")
        note = "no flight to tell a wrong clock from wrong velocities"
    else:
        z_clock = abs(fg - 1.0) / fsd
        z_vel = abs(fg - 1.0 / level ** 2) / fsd
        evidence = (z_clock, float("inf") if warp else z_vel)  # a rate that changes within a jump: no velocity gain
        if warp:
            if z_clock <= limits.z:
                finding = "clock"
            else:
                finding, kappa = "clock and velocities", float(np.sqrt(fg))
        elif z_clock <= limits.z < z_vel:
            finding = "clock"
        elif z_vel <= limits.z < z_clock:
            finding, kappa = "velocities", 1.0 / level
        elif z_vel <= limits.z and z_clock <= limits.z and kind is not None:
            finding, kappa = kind[0], (1.0 if kind[0] == "clock" else 1.0 / level)
            note_kind = f"; the flight fits both alike, {kind[1]}: the {kind[0]}"
        elif z_vel <= limits.z and z_clock <= limits.z:
            finding = "undetermined"
            undetermined = (f"{where}: the {primary} change {level:.4g} times as fast as the velocities integrate "
                            f"to; the flight falls at {fg * level ** 2:.4g} +- {fsd * level ** 2:.2g} g on the logged "
                            f"clock, which fits both a clock off by {level:.4g} ({level ** 2:.4g} g) and velocities "
                            f"off by {1 / level:.4g} (1 g)")
        else:
            finding, kappa = "clock and velocities", float(np.sqrt(fg))
        if finding == "undetermined":
            scale = Rate(1.0)
            note = "the flight fits a wrong clock and wrong velocities alike"
        elif finding == "velocities":
            scale = Rate(1.0)
            note = (f"the flight falls at {fg * level ** 2:.4g} +- {fsd * level ** 2:.2g} g on the logged clock: the "
                    f"clock is right, the velocities are off")
        else:
            if finding == "clock and velocities":
                kappa_sd = 0.5 * fsd / max(kappa, 1e-9)
            scale = rate.scaled(kappa)
            note = (f"the flight falls at {fg / kappa ** 2:.4g} +- {fsd / kappa ** 2:.2g} g on the repaired clock"
                    + (f" (velocities off by {kappa:.4g})" if finding != "clock" else ""))
    note += note_kind
    if from_feet and runs:
        note += " (the flights from the feet's heights: the flags show none)"
    applied = finding not in ("none", "undetermined", "velocities")
    T = scale.times(t) if applied else None
    duration = float(t[-1]) if t[-1] > 0 else 1.0
    mean_rate = float(scale.times(np.array([duration]))[0] / duration)
    scale_sd = float(np.hypot(level_sd * mean_rate / max(level, 1e-9), kappa_sd * mean_rate / max(kappa, 1e-9))) \
        if applied else 0.0
    if applied and warp:
        knots = tuple(float(x) for x in np.unique(scale.spline.t))
        low, high = float(np.min(scale(grid))), float(np.max(scale(grid)))
    else:
        knots = ()
        low = high = mean_rate
    # the flight's acceleration on the clock the rows end up on, in g
    flight = flight_sd = None
    if fg is not None:
        flight = fg / kappa ** 2 if applied else fg * level ** 2
        flight_sd = fsd * flight / fg
    clock = ClockEstimate(
        finding=finding, ratio=level, ratio_sd=level_sd, windows=int(w.ratio.size), group=primary, lag=lag,
        warp=warp and applied, scale=mean_rate, scale_sd=scale_sd, rate_low=low, rate_high=high, knots=knots,
        rates=tuple(float(x) for x in scale(np.array(knots))) if knots else (), scatter=scatter,
        flight_g=flight, flight_g_sd=flight_sd, flight_rows=frows, applied=applied, note=note)
    gains = velocity_gains(t, groups, scale, limits, finding)
    return ClockFit(clock, gains, T, undetermined, evidence)


def velocity_gains(t: np.ndarray, groups: dict[str, _Windows], rate: Rate, limits: RepairLimits,
                   finding: str) -> tuple[VelocityGain, ...]:
    """Each group's velocity gain against the clock ``rate``: its windows' ratio of the
    clock's rate over the window to the positions' ratio (with the positions' lag). A group
    whose windows do not determine it (fewer than 3, or less certain than ``determined``:
    an estimator's noisy base) takes the gain the determined groups agree on, where its own
    windows do not contradict it (one fault of a log's velocities, its differencing or its
    filter), and is left as logged otherwise."""
    T = rate.times(t)
    est: dict[str, tuple[float, float, int]] = {}
    for name, w in groups.items():
        if w.ratio.size < 3:
            est[name] = (1.0, float("inf"), int(w.ratio.size))
            continue
        a, b = w.rows[:, 0], w.rows[:, 1]
        y = w.ratio * (t[b] - t[a]) / (T[b] - T[a])  # positions against velocities on the clock: 1 / gain
        beta, cov, _ = robust_fit(np.c_[np.ones(y.size), w.lead], y)
        k = 1.0 / float(beta[0])
        est[name] = (k, float(np.hypot(np.sqrt(cov[0, 0]) * k ** 2, limits.ratio_floor * abs(k))), int(y.size))
    if finding == "undetermined":  # leave every group as logged
        return tuple(VelocityGain(n, est[n][0], est[n][1], est[n][2], False, "undetermined") for n in groups)
    out: dict[str, VelocityGain] = {}
    for name, (k, sd, n) in est.items():
        if sd / max(abs(k), 1e-9) <= limits.determined:
            out[name] = VelocityGain(name, k, sd, n, abs(k - 1.0) > limits.z * sd, "estimated")
    applied = [g for g in out.values() if g.applied]
    common = None
    if applied:  # one factor for the velocities where the groups that show one agree on it
        ks = np.array([g.gain for g in applied])
        ws = 1.0 / np.array([g.sd for g in applied]) ** 2
        mean = float(ks @ ws / ws.sum())
        if all(abs(g.gain - mean) <= limits.z * g.sd for g in applied):
            common = (mean, float(1.0 / np.sqrt(ws.sum())))
    for name in groups:
        if name in out:
            continue
        k, sd, n = est[name]
        if common is not None and (not np.isfinite(sd) or abs(k - common[0]) <= limits.z * sd):
            out[name] = VelocityGain(name, common[0], common[1], n, True, "as the other velocities")
        else:
            out[name] = VelocityGain(name, k, sd, n, False, "undetermined")
    return tuple(out[name] for name in groups)
