"""The actuated SLIP (aSLIP) baseline: a point mass on a massless spring leg.

CoM acceleration (paper, appendix "Baseline: actuated SLIP Model"), world frame:

    flight:   b'' = g
    contact:  b'' = k_s |l_0 - |l|| l_hat / m + g + u

with b the CoM (the base position q[12:15], as everywhere in symrom),
l = b - p the leg from the stance pivot p (mean of the feet in contact) to the
CoM, l_hat = l / |l|, g = (0, 0, -9.81) m/s^2 and u the summed ground-reaction
force of the dataset (u[:, 12:15], N) divided by m, i.e. an acceleration
(``symrom.baselines.com``). ``ASlip`` is a model like any other: it is rolled
out and scored by ``symrom.rollout.integrate.rollout`` and
``symrom.evaluate.metrics.evaluate_model``.

``ASlip.fit(ds, objective=...)`` fits k_s and l_0 on the training jumps, the mass m
from the robot: ``residual`` on the acceleration residual (``fit_aslip``: fast,
closed form first), and ``rollout`` on the rollout error of the CoM, the
quantity the baseline is judged on (``fit_aslip_rollout``: multiple shooting
over growing windows, ``symrom.rollout.fitting``), started from the residual fit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from functools import partial
from typing import ClassVar

import numpy as np

from symrom.baselines.com import (
    COMPONENTS,
    GRAVITY,
    PARAMS_VERSION,
    com_system,
    flight_rows,
    input_acceleration,
    robot_mass,
    stance_pivots,
)
from symrom.data.dataset import Dataset
from symrom.names import BASE_POS
from symrom.rollout.fitting import RolloutFit, fit_to_rollouts
from symrom.rollout.system import RolloutSystem

__all__ = ["ASlip", "ASlipParams", "GRAVITY", "PAPER_PARAMS", "aslip_acceleration", "fit_aslip",
           "fit_aslip_rollout", "robot_mass", "stance_pivots"]


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


def aslip_acceleration(params: ASlipParams, b: np.ndarray, pivot: np.ndarray, u: np.ndarray,
                       contact: np.ndarray) -> np.ndarray:
    """b'' (n, 3) m/s^2 from CoM b (n, 3) m, pivot (n, 3) m, u (n, 3) m/s^2, contact (n,) bool."""
    leg = b - pivot
    r = np.linalg.norm(leg, axis=-1)
    l_hat = leg / np.maximum(r, 1e-9)[:, None]
    spring = (params.k_s / params.m) * np.abs(params.l_0 - r)[:, None] * l_hat
    return GRAVITY + np.asarray(contact, dtype=float)[:, None] * (spring + u)


OBJECTIVES = ("residual", "rollout")


@dataclass(frozen=True)
class ASlip:
    """The aSLIP as a model that can be rolled out (``Rollable``): predicts CoM x, y, z.

    ``ASlip.fit(ds)`` fits it (k_s and l_0; the mass from the robot); ``ASlip(params)`` takes
    known parameters (``ASlip.paper()``: the paper's). source: how the parameters were set,
    in words; stages: the rollout fit's record (``fit_aslip_rollout``), JSON-ready."""

    params: ASlipParams
    source: str = field(default="given", compare=False)
    stages: tuple = field(default=(), compare=False)
    components = COMPONENTS
    kind: ClassVar[str] = "aslip"

    @classmethod
    def fit(cls, ds: Dataset, rows: np.ndarray | None = None, m: float | None = None,
            objective: str = "residual") -> ASlip:
        """k_s and l_0 fitted on ``rows`` (N,) bool (default: the train split) by ``objective``:
        ``residual`` (the acceleration residual, ``fit_aslip``) or ``rollout`` (the CoM rollout
        error from the residual fit, ``fit_aslip_rollout``); mass ``m`` kg (default: the robot's)."""
        if objective not in OBJECTIVES:
            raise ValueError(f"objective={objective!r}: choose from {', '.join(OBJECTIVES)}")
        rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
        params = fit_aslip(ds, rows, m)
        mass = "" if m is not None else f"; mass from the {ds.robot} description"
        if objective == "residual":
            return cls(params, f"fitted on the train split (acceleration residual{mass})")
        params, fit = fit_aslip_rollout(ds, np.unique(ds.jump[rows]), m=params.m, start=params)
        return cls(params, f"fitted on the train split (CoM rollout error, multiple shooting{mass})",
                   tuple(fit.stages))

    @classmethod
    def paper(cls, k_s: float | None = None, l_0: float | None = None, m: float | None = None) -> ASlip:
        """The paper's Go1 values (``PAPER_PARAMS``), each overridable."""
        given = {k: float(v) for k, v in (("k_s", k_s), ("l_0", l_0), ("m", m)) if v is not None}
        return cls(replace(PAPER_PARAMS, **given), "fixed: the paper's values" + (
            f" ({', '.join(given)} given)" if given else ""))

    def to_dict(self) -> dict:
        """What its ``params.json`` holds (``symrom.baselines.from_params`` reads it back)."""
        return {"format_version": PARAMS_VERSION, "model": self.kind, **asdict(self.params),
                "units": {"k_s": "N/m", "l_0": "m", "m": "kg"}, "source": self.source,
                **({"stages": list(self.stages)} if self.stages else {})}

    def rollout_system(self, ds: Dataset, jumps: np.ndarray) -> RolloutSystem:
        p = self.params
        sysm = com_system(ds, jumps, p.m, lambda d, x, v: aslip_acceleration(
            p, x, d["pivot"], d["u"], d["contact"]))
        return replace(sysm, compiled=partial(_compiled_rk4, p))


def _compiled_rk4(p: ASlipParams, x, v, drive, lens, resets, limit, dt, substeps):
    """The aSLIP's compiled RK4 (``baselines.compiled.aslip_rk4``) in the form of a
    ``RolloutSystem.compiled`` integrator."""
    from symrom.baselines.compiled import aslip_rk4

    return aslip_rk4(p.k_s / p.m, p.l_0, np.asarray(GRAVITY, float), x, v, drive["u"], drive["pivot"],
                     np.asarray(drive["contact"], bool), np.asarray(lens, np.int64), resets, limit, dt, substeps)


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
    from scipy.optimize import least_squares  # here: scipy.optimize is slow to import

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


def fit_aslip_rollout(ds: Dataset, jumps: np.ndarray | None = None, m: float | None = None,
                      start: ASlipParams | None = None,
                      resets: tuple[float | None, ...] = (0.1, 0.3, None)) -> tuple[ASlipParams, RolloutFit]:
    """k_s (N/m) and l_0 (m) minimising the CoM rollout error over ``jumps`` (default:
    the train split), from ``start`` (default: the residual fit), mass ``m`` (kg)
    fixed; the parameters and the record of the multiple-shooting stages."""
    jumps = ds.jumps_in("train") if jumps is None else np.asarray(jumps, dtype=int)
    if jumps.size == 0:
        raise ValueError("no jumps to fit the aSLIP rollouts on (is there a 'train' split?)")
    m = robot_mass(ds.robot) if m is None else float(m)
    start = start or fit_aslip(ds, np.isin(ds.jump, jumps), m)
    x0 = np.array([max(start.k_s, 1e-3), max(start.l_0, 1e-3)])
    fit = fit_to_rollouts(lambda th: ASlip(ASlipParams(float(th[0]), float(th[1]), m)), x0, ds, jumps,
                          ([0.0, 0.0], [np.inf, np.inf]), resets,
                          x_scale=np.array([max(x0[0], 1.0), max(x0[1], 1e-2)]))
    return ASlipParams(float(fit.theta[0]), float(fit.theta[1]), m), fit
