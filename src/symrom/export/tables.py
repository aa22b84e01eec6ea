"""What an export emits of a model: its tables, read once, written out by every target.

An export is the package's runtime (``runtime/``: C and Python written once, as
source files) fed by the model's tables: the encoder and decoder, the input map
pinv(W_e^T), the divergence limit of free prediction, the guards as rows, the
leg chains of the model's robot, and each phase's latent dynamics as exact sympy
expressions (the one thing written out as code per model).

The guards are rows (source, target, dwell, bias, [(column of z, weight)]),
their terms in the order ``Guard.value`` sums them, and the dwell test is
``guards.dwell_ok``'s (``EPS_T``), so that a switch falls on the same sample in
every target; free prediction follows the model's phase sequence
(``HybridModel.phase_sequence``, phase indices; empty: none) by the stages of
``symrom.model.guards``. The input map is ``symrom.data.preprocess.input_from_torques``:
the leg chains of the model's robot (``LegKinematics.chain_arrays``: fixed
origin transforms, revolute joints by Rodrigues' formula) give the feet and the
leg Jacobians J_k (base frame); per foot in contact the ground force is
F_k = R (-(J_k^T)^-1 tau_k), R the base orientation (ZYX Euler angles); and
u = [tau, sum F_k, sum (p_k - b) x F_k] with b the base position and p_k the
foot (given, or b + R p_k(base frame) from the kinematics). A model whose
robot has no description (planted data) is exported without it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy

from symrom.model.expressions import latent_expressions
from symrom.model.guards import EPS_T
from symrom.model.hybrid import HybridModel
from symrom.model.library import symbols
from symrom.model.persistence import model_hash
from symrom.rollout.integrate import RolloutOptions

BOUND = RolloutOptions.bound  # divergence bound of the exported predict_path, x the model's yardstick


@dataclass(frozen=True)
class GuardRow:
    """One guard: source and target phase indices, dwell s, bias and its terms
    ((column of z = [xi, dxi, nu], weight), in ``Guard.value``'s order)."""

    source: int
    target: int
    dwell: float
    bias: float
    terms: tuple[tuple[int, float], ...]


@dataclass(frozen=True)
class LegChains:
    """The leg chains of a robot (``LegKinematics.chain_arrays``): n_el (4,) elements per
    chain, xyz (4, E, 3) m, rot (4, E, 3, 3), axis (4, E, 3), col (4, E) (the joint's
    column in the 12 angles, -1 for a fixed element)."""

    robot: str
    n_el: np.ndarray
    xyz: np.ndarray
    rot: np.ndarray
    axis: np.ndarray
    col: np.ndarray


@dataclass(frozen=True)
class ExportTables:
    """A model as its exports hold it.

    model_sha256: the model's hash (``model_hash``); phase_names (P); latent_dim l;
    W_e (l, 18), B_e (l,), W_d (18, l), B_d (18,), input_map (18, l): nu rows = u rows @ it;
    limit (2l,): the bound on |s| of free prediction; eps_t: s, the dwell test's rounding
    allowance; guards: the rows; sequence: the phase indices of one jump of the model's motion
    (empty: none); chains: the robot's legs, None without a description;
    state (2l), inputs (l): the symbols of ``dynamics``, per phase the l exact right-hand
    sides of ddxi."""

    model_sha256: str
    phase_names: tuple[str, ...]
    latent_dim: int
    W_e: np.ndarray
    B_e: np.ndarray
    W_d: np.ndarray
    B_d: np.ndarray
    input_map: np.ndarray
    limit: np.ndarray
    eps_t: float
    guards: tuple[GuardRow, ...]
    sequence: tuple[int, ...]
    chains: LegChains | None
    state: tuple[sympy.Symbol, ...]
    inputs: tuple[sympy.Symbol, ...]
    dynamics: tuple[tuple[sympy.Expr, ...], ...]


def robot_chains(model: HybridModel) -> LegChains | None:
    """The leg chains of the model's robot, or None if the model records no robot with a
    description."""
    from symrom.robots import RobotDescriptionError, leg_kinematics

    robot = model.provenance.data.robot
    if robot is None:
        return None
    try:
        return LegChains(str(robot), *leg_kinematics(robot).chain_arrays())
    except (RobotDescriptionError, FileNotFoundError, KeyError):
        return None


def guard_rows(model: HybridModel) -> tuple[GuardRow, ...]:
    """The model's guards as rows (none for a model without guards)."""
    l, names = model.latent_dim, model.phase_names
    return tuple(GuardRow(names.index(g.source), names.index(g.target), float(g.min_dwell_s), float(g.bias),
                          tuple(zip(g.indices(l).tolist(), g.weights.tolist()))) for g in model.guards or [])


def export_tables(model: HybridModel) -> ExportTables:
    """The tables of ``model``."""
    ae, l = model.autoencoder, model.latent_dim
    s, nu = symbols(l)
    rows = tuple(tuple(r) for r in latent_expressions(model.library, model.Xi))
    return ExportTables(model_hash(model), tuple(model.phase_names), l, ae.W_e, ae.B_e, ae.W_d, ae.B_d,
                        ae.input_map, BOUND * model.yardstick, EPS_T, guard_rows(model), model.phase_sequence(),
                        robot_chains(model),
                        tuple(s), tuple(nu), rows)
