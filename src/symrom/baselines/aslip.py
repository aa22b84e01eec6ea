"""The actuated SLIP (aSLIP) baseline: a point mass on a massless spring leg.

CoM acceleration (paper, appendix "Baseline: actuated SLIP Model"), world frame:

    flight:   b'' = g
    contact:  b'' = k_s |l_0 - |l|| l_hat / m + g + u

with b the CoM (the base position q[12:15], as everywhere in symrom),
l = b - p the leg from the stance pivot p (mean of the feet in contact) to the
CoM, l_hat = l / |l|, g = (0, 0, -9.81) m/s^2 and u the summed ground-reaction
force of the dataset (u[:, 12:15], N) divided by m, i.e. an acceleration.

Rollouts follow the learned model's semantics (``symrom.rollout.integrate``):
the state (b, b') of each jump is integrated along the logged phase sequence
(phase ``flight`` is flight, every other phase is contact), with the logged u
and pivot held over each 2 ms sample; ``lsoda`` (odeint per sample interval
with a step budget) or ``rk4`` (fixed step, all jumps at once); full horizon or
periodic resets to the true (b, b'); non-finite or absurd states are flagged as
diverged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from symrom.data.dataset import Dataset
from symrom.evaluate.metrics import component_stats, horizon_key, prediction_errors
from symrom.names import BASE_POS, WRENCH
from symrom.rollout.integrate import RolloutOptions, integrate_lsoda, integrate_rk4, pad_edge, reset_mask

GRAVITY = np.array([0.0, 0.0, -9.81])  # m/s^2, world frame
COMPONENTS: tuple[str, ...] = ("x", "y", "z")
FLIGHT_PHASE = "flight"


@dataclass(frozen=True)
class ASlipParams:
    """k_s: spring constant, N/m; l_0: rest length, m; m: body mass, kg."""

    k_s: float
    l_0: float
    m: float

    def __post_init__(self) -> None:
        for name in ("k_s", "l_0", "m"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0 or (name == "m" and v == 0):
                raise ValueError(f"aSLIP parameter {name} must be a finite "
                                 f"{'positive' if name == 'm' else 'non-negative'} number, got {v}")


# The authors' values for the Go1 (paper, aSLIP baseline).
PAPER_PARAMS = ASlipParams(k_s=250.0, l_0=0.32, m=12.01)


def robot_mass(robot: str) -> float:
    """Total mass of ``robot`` (a name or description file) from its URDF, kg; a clear error
    for robots without a description."""
    from symrom.robots import RobotDescriptionError, get_robot

    try:
        return get_robot(robot).mass
    except RobotDescriptionError as e:
        raise ValueError(f"{e}; give the mass explicitly (--mass)") from None


# ------------------------------------------------------------------ per-row inputs
def flight_rows(ds: Dataset) -> np.ndarray:
    """(N,) bool: rows in the phase named ``flight`` (none if the dataset has no such phase)."""
    if FLIGHT_PHASE not in ds.phase_names:
        return np.zeros(ds.n_samples, dtype=bool)
    return ds.phase == ds.phase_names.index(FLIGHT_PHASE)


def stance_pivots(ds: Dataset) -> np.ndarray:
    """(N, 3) m, world: mean of the feet in contact per row.

    Feet from ``ds.foot_pos`` if logged, else from the kinematics of the
    robot's URDF. A row without any foot flagged in contact (flight, or a
    contact-phase row whose flags disagree with its label) takes the mean of
    all four feet, so the pivot is always defined and finite.
    """
    if ds.foot_pos is not None:
        feet = ds.foot_pos
    else:
        from symrom.data.preprocess import foot_positions_world

        feet = foot_positions_world(ds.robot, ds.q)
    w = (np.asarray(ds.contact) > 0).astype(float)  # (N, 4)
    none = w.sum(axis=1) == 0
    w[none] = 1.0
    return np.einsum("nk,nkd->nd", w, feet) / w.sum(axis=1)[:, None]


def input_acceleration(ds: Dataset, m: float) -> np.ndarray:
    """(N, 3) m/s^2: u = summed ground-reaction force (ds.u[:, 12:15], N) / m (kg)."""
    return ds.u[:, WRENCH][:, :3] / m


def aslip_acceleration(params: ASlipParams, b: np.ndarray, pivot: np.ndarray, u: np.ndarray,
                       contact: np.ndarray) -> np.ndarray:
    """b'' (n, 3) m/s^2 from CoM b (n, 3) m, pivot (n, 3) m, u (n, 3) m/s^2, contact (n,) bool."""
    leg = b - pivot
    r = np.linalg.norm(leg, axis=-1)
    l_hat = leg / np.maximum(r, 1e-9)[:, None]
    spring = (params.k_s / params.m) * np.abs(params.l_0 - r)[:, None] * l_hat
    return GRAVITY + np.asarray(contact, dtype=float)[:, None] * (spring + u)


# ----------------------------------------------------------------------- fitting
def fit_aslip(ds: Dataset, rows: np.ndarray | None = None, m: float | None = None) -> ASlipParams:
    """Least-squares k_s (N/m) and l_0 (m) on the contact rows among ``rows`` (N,) bool
    (default: the train split); mass ``m`` (kg, default: the robot's URDF total).

    Residual acceleration a = b'' - g - u (b'' = ddq[:, 12:15]) must equal
    k_s |l_0 - |l|| l_hat / m. For a compressed leg (|l| < l_0) that is
    (k_s l_0) l_hat / m - k_s l / m, linear in (k_s l_0, k_s): solved first,
    then refined on the exact |.| form by ``scipy.optimize.least_squares``
    with k_s, l_0 >= 0. Where the measured force u already explains b'' (no
    spring-like residual), k_s goes to 0 and l_0 is then not identifiable.
    """
    m = robot_mass(ds.robot) if m is None else float(m)
    rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
    sel = rows & ~flight_rows(ds)
    if not sel.any():
        raise ValueError("no contact rows to fit the aSLIP model on (is there a 'train' split "
                         "with contact phases?)")
    b = ds.q[sel][:, BASE_POS]
    leg = b - stance_pivots(ds)[sel]
    r = np.linalg.norm(leg, axis=1)
    l_hat = leg / np.maximum(r, 1e-9)[:, None]
    a = ds.ddq[sel][:, BASE_POS] - GRAVITY - input_acceleration(ds, m)[sel]  # (n, 3)

    # Linear stage: m a = (k_s l_0) l_hat - k_s l, three equations per row.
    A = np.stack([l_hat.ravel(), -leg.ravel()], axis=1)
    (c0, k0), *_ = np.linalg.lstsq(A, m * a.ravel(), rcond=None)
    if k0 > 0 and np.isfinite(c0 / k0) and c0 / k0 > 0:
        x0 = np.array([k0, c0 / k0])
    else:  # no compressed-spring reading of the data: start from a soft spring at the longest leg
        x0 = np.array([1.0, float(r.max())])

    def residual(x):
        return ((x[0] / m) * np.abs(x[1] - r)[:, None] * l_hat - a).ravel()

    scale = np.array([max(abs(x0[0]), 1.0), max(abs(x0[1]), 1e-2)])
    sol = least_squares(residual, x0, bounds=([0.0, 0.0], [np.inf, np.inf]), x_scale=scale,
                        xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return ASlipParams(k_s=float(sol.x[0]), l_0=float(sol.x[1]), m=m)


# ---------------------------------------------------------------------- rollouts
@dataclass
class ASlipRolloutOptions(RolloutOptions):
    """As ``RolloutOptions``, except that ``bound`` scales the jump's own largest true
    |b| component (at least 0.1 m), and likewise for b' (at least 0.1 m/s)."""


@dataclass
class ASlipRollout:
    """Per jump (lists of J): predicted CoM b (n_j, 3) m and b' (n_j, 3) m/s
    (NaN from the first diverged sample on); diverged (J,) bool; diverged_at
    (J,) first bad sample or -1."""

    jumps: np.ndarray
    b_pred: list[np.ndarray]
    db_pred: list[np.ndarray]
    diverged: np.ndarray
    diverged_at: np.ndarray


@dataclass
class _Jump:
    b: np.ndarray  # (n, 3) true CoM, m
    db: np.ndarray  # (n, 3) m/s
    u: np.ndarray  # (n, 3) m/s^2
    pivot: np.ndarray  # (n, 3) m
    contact: np.ndarray  # (n,) bool
    limit: np.ndarray  # (6,) divergence limit on |[b, b']|


def _jumps(ds: Dataset, jumps: np.ndarray, m: float, bound: float) -> list[_Jump]:
    bounds = ds.jump_bounds()
    u, pivot, contact = input_acceleration(ds, m), stance_pivots(ds), ~flight_rows(ds)
    out = []
    for j in jumps:
        s = slice(*bounds[j])
        b, db = ds.q[s][:, BASE_POS], ds.dq[s][:, BASE_POS]
        # One scale for all positions and one for all velocities: a coordinate that barely
        # moves in the data (y of a planar jump) must not make a small drift "absurd".
        scale = np.repeat([max(np.abs(b).max(), 0.1), max(np.abs(db).max(), 0.1)], 3)
        out.append(_Jump(b, db, u[s], pivot[s], contact[s], bound * scale))
    return out


def _aslip_accel(params: ASlipParams, pivot: np.ndarray, u: np.ndarray, contact: np.ndarray):
    """CoM acceleration with pivot (J, n, 3), u (J, n, 3), contact (J, n) of sample k held."""
    return lambda k, x, v: aslip_acceleration(params, x, pivot[:, k], u[:, k], contact[:, k])


def rollout_aslip(params: ASlipParams, ds: Dataset, jumps: np.ndarray | list[int] | None = None,
                  options: ASlipRolloutOptions = ASlipRolloutOptions(),
                  progress: Callable[[int, int], None] | None = None) -> ASlipRollout:
    """Roll the aSLIP model out along the logged ``jumps`` of ``ds`` (default: all).

    Returns the predicted CoM x, y, z (m) per jump.
    """
    jumps = np.arange(ds.n_jumps) if jumps is None else np.asarray(jumps, dtype=int)
    jps = _jumps(ds, jumps, params.m, options.bound)
    if not jps:
        return ASlipRollout(jumps, [], [], np.zeros(0, bool), np.zeros(0, int))
    if options.method == "lsoda":
        Bs, Vs, div = [], [], []
        for i, jp in enumerate(jps):
            B, V, d = integrate_lsoda(_aslip_accel(params, jp.pivot[None], jp.u[None], jp.contact[None]),
                                      jp.b, jp.db, reset_mask(len(jp.b), options.reset, ds.dt), jp.limit,
                                      ds.dt, options.max_steps)
            Bs.append(B)
            Vs.append(V)
            div.append(d)
            if progress:
                progress(i + 1, len(jps))
        div_at = np.array(div, dtype=int)
    else:
        lens = np.array([len(jp.b) for jp in jps])
        acc = _aslip_accel(params, pad_edge([jp.pivot for jp in jps]), pad_edge([jp.u for jp in jps]),
                           pad_edge([jp.contact for jp in jps]))
        Bs, Vs, div_at = integrate_rk4(acc, pad_edge([jp.b for jp in jps]), pad_edge([jp.db for jp in jps]),
                                       lens, reset_mask(int(lens.max()), options.reset, ds.dt),
                                       np.stack([jp.limit for jp in jps]), ds.dt, options.substeps)
        if progress:
            progress(len(jps), len(jps))
    return ASlipRollout(jumps, Bs, Vs, div_at >= 0, div_at)


def rollout_errors(ds: Dataset, ro: ASlipRollout) -> np.ndarray:
    """Signed CoM errors predicted - true (n, 3) m over the non-diverged jumps of ``ro``."""
    return prediction_errors(ds, ro.jumps, ro.b_pred, ro.diverged, BASE_POS)


def evaluate_aslip(params: ASlipParams, ds: Dataset, split: str = "test",
                   resets: tuple[float | None, ...] = (None, 0.1), method: str = "lsoda",
                   options: ASlipRolloutOptions | None = None, model_name: str = "aslip",
                   data_name: str = "", progress: Callable[[int, int], None] | None = None) -> dict:
    """Metrics of the aSLIP rollouts on ``split`` at each horizon, in the layout of
    ``metrics.json`` (DESIGN.md) with components ``x``, ``y``, ``z`` (m)."""
    jumps = ds.jumps_in(split)
    if jumps.size == 0:
        raise ValueError(f"the dataset has no {split!r} jumps")
    base = replace(options or ASlipRolloutOptions(), method=method)
    horizons = {}
    for reset in resets:
        ro = rollout_aslip(params, ds, jumps, replace(base, reset=reset), progress)
        horizons[horizon_key(reset)] = {"diverged_jumps": int(ro.diverged.sum()),
                                        "components": component_stats(rollout_errors(ds, ro), COMPONENTS)}
    return {"model": model_name, "data": data_name, "split": split, "n_jumps": int(jumps.size),
            "integrator": method, "horizons": horizons}
