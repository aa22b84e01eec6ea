"""The reduced-order models a jump is planned with, as CasADi expressions of one interface.

Every planner sees its model through ``PlanDynamics``: a state s (n,) whose second half is
the time derivative of its first (positions, then velocities; the closed loop's disturbance
estimate, ``plan.replan``, adds to the second half's derivative), its
stance and flight time derivatives ds/dt (the stance one driven by the planned
ground force F = (F_x, F_z), N, world, summed over the stance feet), and the
base's forward position and height (x, z, m) and velocities read from s. Three
models meet it:

- ``LearnedDynamics``: a fitted ``HybridModel``. s = [xi, dxi] (2l); its
  ``contact`` and ``flight`` phases' latent accelerations (``casadi_functions``);
  the force enters through the model's input nu = B F (``plan.inputs``); x and
  z are decoded (q = W_d xi + B_d).
- ``PointMass``: Newton's law on the description's mass, s = [x, z, vx, vz]:
  stance b'' = F / m + g, flight b'' = g.
- ``ASlipDynamics``: the fitted aSLIP (``baselines.aslip``), s = [x, z, vx, vz]:
  stance b'' = k_s |l_0 - |l|| l_hat / m + F / m + g about the stance pivot
  (the mean of the feet at the start of the push), flight b'' = g.

Units: m, s, N; x forward along the jump's heading (the world x axis here).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import casadi as ca
import numpy as np

from symrom.baselines.aslip import ASlipParams
from symrom.model.hybrid import HybridModel
from symrom.names import BASE_POS, FLIGHT_PHASE, GRAVITY, N_Q, STANCE_PHASE

_X, _Z = BASE_POS.start, BASE_POS.start + 2  # indices of base x and z in q


class PlanModelError(ValueError):
    """A model that cannot plan a jump (missing phase, latents that do not see x and z)."""


class PlanDynamics(Protocol):
    """What the planning problem needs of a model (all CasADi SX in, SX out)."""

    name: str
    n_state: int

    def stance(self, s: ca.SX, F: ca.SX, phase: str = STANCE_PHASE) -> ca.SX:
        """ds/dt (n,) in the stance phase ``phase`` (``contact``, or a froggy's ``partial``)
        under the summed ground force F (2,) N (x, z) of the feet down."""

    def flight(self, s: ca.SX) -> ca.SX:
        """ds/dt (n,) in flight."""

    def position(self, s: ca.SX) -> ca.SX:
        """(2,) base x, z (m) of state s."""

    def velocity(self, s: ca.SX) -> ca.SX:
        """(2,) base vx, vz (m/s) of state s."""

    def initial_state(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """s (n,) of the robot at configuration q (18,) and velocity dq (18,)."""


@dataclass
class PointMass:
    """Newton's law on mass ``m`` kg: s = [x, z, vx, vz]; stance b'' = F/m + g, flight b'' = g."""

    m: float
    name: str = "point-mass"
    n_state: int = 4

    def stance(self, s, F, phase=STANCE_PHASE):
        return ca.vertcat(s[2], s[3], F[0] / self.m, F[1] / self.m - GRAVITY)

    def flight(self, s):
        return ca.vertcat(s[2], s[3], 0.0, -GRAVITY)

    def position(self, s):
        return s[0:2]

    def velocity(self, s):
        return s[2:4]

    def initial_state(self, q, dq):
        return np.array([q[_X], q[_Z], dq[_X], dq[_Z]], dtype=float)


@dataclass
class ASlipDynamics(PointMass):
    """The aSLIP: the point mass plus a spring leg k_s |l_0 - |l|| l_hat from ``pivot`` (x, z) m.

    |.| is smoothed (sqrt(d^2 + 1e-8)) so that IPOPT sees a differentiable law; it
    differs from the exact one by at most 1e-4 m of leg length."""

    params: ASlipParams | None = None
    pivot: tuple[float, float] = (0.0, 0.0)
    name: str = "aslip"

    def stance(self, s, F, phase=STANCE_PHASE):
        p = self.params
        leg = s[0:2] - ca.DM(self.pivot)
        r = ca.sqrt(ca.sumsqr(leg) + 1e-12)
        spring = p.k_s * ca.sqrt((p.l_0 - r) ** 2 + 1e-8) / p.m * leg / r
        return ca.vertcat(s[2], s[3], spring[0] + F[0] / p.m, spring[1] + F[1] / p.m - GRAVITY)


class LearnedDynamics:
    """A ``HybridModel``'s latent dynamics with the planned force as its input (module docstring).

    B (l, 2): nu = B F, the model's input for a summed ground force F = (F_x, F_z) N
    (``plan.inputs.force_input_map``) in the ``contact`` phase, or a dict of such maps by
    stance phase (a froggy's ``partial`` too: the rear feet's). ``stances``: the stance
    phases the push runs through (default those of B)."""

    name = "learned"

    def __init__(self, model: HybridModel, B: np.ndarray | dict[str, np.ndarray]):
        from symrom.export import casadi_functions

        maps = dict(B) if isinstance(B, dict) else {STANCE_PHASE: B}
        for phase in (*maps, FLIGHT_PHASE):
            if phase not in model.trained_phases():
                raise PlanModelError(f"the model has no trained {phase!r} phase (its phases: "
                                     f"{', '.join(model.trained_phases())}); the jump is planned over "
                                     f"{', '.join(repr(p) for p in (*maps, FLIGHT_PHASE))}")
        self.model, self.l = model, model.latent_dim
        self.n_state = 2 * self.l
        self.B_of: dict[str, np.ndarray] = {}
        for phase, b in maps.items():
            b = np.asarray(b, dtype=float)
            if b.shape != (self.l, 2):
                raise PlanModelError(f"input map B of {phase!r}: shape {b.shape}, expected {(self.l, 2)}")
            self.B_of[phase] = b
        self.B = self.B_of[next(iter(self.B_of))]  # the first stance's (a pronk's contact)
        fns = casadi_functions(model)
        self._acc = {p: fns[f"accel_{p}"] for p in (*self.B_of, FLIGHT_PHASE)}
        ae = model.autoencoder
        rows = ae.W_d[[_X, _Z]]  # (2, l): decoded x, z per latent
        if np.linalg.matrix_rank(rows) < 2:
            raise PlanModelError("the model's decoder does not resolve the base's x and z apart "
                                 f"(decoder rows x, z: {rows.tolist()}); it cannot plan a landing point")
        self._Wd, self._Bd = ca.DM(rows), ca.DM(ae.B_d[[_X, _Z]])

    def stance(self, s, F, phase=STANCE_PHASE):
        l = self.l
        nu = ca.mtimes(ca.DM(self.B_of[phase]), F)
        return ca.vertcat(s[l:], self._acc[phase](s, nu))

    def flight(self, s):
        l = self.l
        return ca.vertcat(s[l:], self._acc[FLIGHT_PHASE](s, ca.DM.zeros(l)))

    def position(self, s):
        return ca.mtimes(self._Wd, s[:self.l]) + self._Bd

    def velocity(self, s):
        return ca.mtimes(self._Wd, s[self.l:])

    def initial_state(self, q, dq):
        ae = self.model.autoencoder
        q, dq = np.asarray(q, float).reshape(1, N_Q), np.asarray(dq, float).reshape(1, N_Q)
        return np.concatenate([ae.encode(q)[0], ae.encode_derivative(dq)[0]])
