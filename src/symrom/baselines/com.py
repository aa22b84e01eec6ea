"""What the centre-of-mass baselines share: the logged drive and the rollout set-up.

A CoM baseline predicts the base position b = q[12:15] (m, world; symrom's
stand-in for the CoM, as in the learned model's data) from b'' = a(b, b',
drive), integrated by ``symrom.rollout`` like any other model. The drive is
logged per sample: u, the summed ground-reaction force (``ds.u[:, 12:15]``,
N) divided by the mass m, an acceleration; the stance pivot, the mean of the
feet in contact; and whether the sample is in contact (any phase but
``flight``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from symrom import names
from symrom.data.dataset import Dataset
from symrom.names import BASE_POS, FLIGHT_PHASE, WRENCH
from symrom.rollout.system import RolloutSystem

GRAVITY = np.array([0.0, 0.0, -names.GRAVITY])  # m/s^2, the gravity vector in the world frame
COMPONENTS: tuple[str, ...] = ("x", "y", "z")
# A baseline's params.json (``to_dict``): 2 adds format_version, model, units and source to
# every baseline; files without format_version (1) hold the aSLIP's k_s, l_0, m or a model's record.
PARAMS_VERSION = 2


def robot_mass(robot: str) -> float:
    """Total mass of ``robot`` (a name or description file) from its URDF, kg; a clear error
    for robots without a description."""
    from symrom.robots import RobotDescriptionError, get_robot

    try:
        return get_robot(robot).mass
    except RobotDescriptionError as e:
        raise ValueError(f"{e}; give the mass explicitly (m= in kg)") from None


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


def com_system(ds: Dataset, jumps: np.ndarray, m: float,
               acceleration: Callable[[dict[str, np.ndarray], np.ndarray, np.ndarray], np.ndarray]
               ) -> RolloutSystem:
    """The rollout set-up of a CoM baseline of mass ``m`` (kg) on ``jumps`` of ``ds``.

    Drive: ``u`` (n, 3) m/s^2, ``pivot`` (n, 3) m, ``contact`` (n,) bool. The
    divergence yardstick is the jump's own largest |b| (at least 0.1 m) and
    |b'| (at least 0.1 m/s): one scale for all positions and one for all
    velocities, so that a coordinate barely moving in the data (y of a planar
    jump) does not make a small drift absurd.
    """
    bounds = ds.jump_bounds()
    u, pivot, contact = input_acceleration(ds, m), stance_pivots(ds), ~flight_rows(ds)
    x, v, drive, scale = [], [], {"u": [], "pivot": [], "contact": []}, []
    for j in jumps:
        s = slice(*bounds[j])
        b, db = ds.q[s][:, BASE_POS], ds.dq[s][:, BASE_POS]
        x.append(b)
        v.append(db)
        drive["u"].append(u[s])
        drive["pivot"].append(pivot[s])
        drive["contact"].append(contact[s])
        scale.append(np.repeat([max(np.abs(b).max(), 0.1), max(np.abs(db).max(), 0.1)], 3))
    return RolloutSystem(x, v, drive, np.array(scale), acceleration, lambda i, X: X)
