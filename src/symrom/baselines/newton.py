"""Newton's law on the measured ground force: the baseline a CoM model has to beat.

    b'' = g + F / m

with b the base position (symrom's stand-in for the CoM), F the summed
ground-reaction force of the feet in contact logged in the data
(``u[:, 12:15]``, N; zero in flight) and m the robot's total mass. Nothing is
fitted: whatever the data's force explains, this model explains. Where it
errs, the gap comes from what the CoM model leaves out: legs that move the
CoM against the base, and ground forces estimated from joint torques
through massless-leg Jacobians.

``AffineForce`` is the same law with its numbers fitted on the training rows,
the strongest CoM baseline of a few parameters:

    contact:  b'' = c + A F / m        flight:  b'' = c_f

A (3, 3) corrects the force estimate's gain and cross-talk, c and c_f the
gravity and a constant bias; least squares on the base accelerations of the
training rows, per phase (15 numbers).
"""

from __future__ import annotations

from dataclasses import dataclass, field
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
)
from symrom.data.dataset import Dataset
from symrom.names import BASE_POS
from symrom.rollout.system import RolloutSystem


@dataclass(frozen=True)
class Newton:
    """b'' = g + F/m as a model that can be rolled out (``Rollable``); m in kg; source: where
    the mass came from, in words."""

    m: float
    source: str = field(default="the given mass; nothing fitted", compare=False)
    components = COMPONENTS
    kind: ClassVar[str] = "newton"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.m) and self.m > 0):
            raise ValueError(f"mass={self.m}: the Newton baseline's mass must be a positive number")

    @classmethod
    def fit(cls, ds: Dataset, rows: np.ndarray | None = None, m: float | None = None) -> Newton:
        """The baseline for the robot of ``ds``: nothing is fitted (``rows`` are not read, the
        same call as every baseline's); its mass is the description's unless ``m`` is given."""
        if m is not None:
            return cls(float(m))
        return cls(robot_mass(ds.robot), "the robot's total mass; nothing fitted")

    def to_dict(self) -> dict:
        """What its ``params.json`` holds (``symrom.baselines.from_params`` reads it back)."""
        return {"format_version": PARAMS_VERSION, "model": self.kind, "m": self.m, "units": {"m": "kg"},
                "source": self.source}

    def rollout_system(self, ds: Dataset, jumps: np.ndarray) -> RolloutSystem:
        return com_system(ds, jumps, self.m, lambda d, x, v: GRAVITY + d["u"])


@dataclass(frozen=True)
class AffineForce:
    """Contact b'' = c + A F/m, flight b'' = c_f (``Rollable``); A (3, 3), c and c_f (3,) m/s^2,
    m kg (module docstring)."""

    m: float
    A: np.ndarray
    c: np.ndarray
    c_f: np.ndarray
    source: str = field(default="given", compare=False)
    components = COMPONENTS
    kind: ClassVar[str] = "affine_force"

    def __post_init__(self) -> None:
        Newton(self.m)  # the same check of the mass
        for name, shape in (("A", (3, 3)), ("c", (3,)), ("c_f", (3,))):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != shape or not np.isfinite(v).all():
                raise ValueError(f"AffineForce: {name} must be a finite array of shape {shape}, got {v.shape}")
            object.__setattr__(self, name, v)

    @classmethod
    def fit(cls, ds: Dataset, rows: np.ndarray | None = None, m: float | None = None) -> AffineForce:
        """Least squares on the base accelerations of ``rows`` (N,) (default: the train split),
        contact and flight rows apart; a clear error if either has too few rows."""
        rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
        m = robot_mass(ds.robot) if m is None else float(m)
        flight, acc, u = flight_rows(ds), ds.ddq[:, BASE_POS], input_acceleration(ds, m)
        contact_rows, flight_only = rows & ~flight, rows & flight
        if contact_rows.sum() < 4 or flight_only.sum() < 1:
            raise ValueError(f"AffineForce.fit: needs at least 4 contact and 1 flight training rows, got "
                             f"{int(contact_rows.sum())} and {int(flight_only.sum())}")
        X = np.column_stack([np.ones(contact_rows.sum()), u[contact_rows]])
        coef, *_ = np.linalg.lstsq(X, acc[contact_rows], rcond=None)
        return cls(m, coef[1:].T, coef[0], acc[flight_only].mean(axis=0),
                   "fitted on the train split (least squares on the base accelerations)")

    def to_dict(self) -> dict:
        """What its ``params.json`` holds (``symrom.baselines.from_params`` reads it back)."""
        return {"format_version": PARAMS_VERSION, "model": self.kind, "m": self.m, "A": self.A.tolist(),
                "c": self.c.tolist(), "c_f": self.c_f.tolist(),
                "units": {"m": "kg", "A": "1", "c": "m/s^2", "c_f": "m/s^2"}, "source": self.source}

    def rollout_system(self, ds: Dataset, jumps: np.ndarray) -> RolloutSystem:
        A, c, c_f = self.A, self.c, self.c_f

        def acceleration(d, x, v):
            return np.where(np.asarray(d["contact"], dtype=bool)[:, None], c + d["u"] @ A.T, c_f)

        return com_system(ds, jumps, self.m, acceleration)
