"""Convex single-rigid-body MPC for ground-reaction forces (Di Carlo et al. 2018 style).

The robot is one rigid body of mass ``m`` (kg) and body inertia ``I_b`` (3, 3)
kg m^2, pushed by the ground-reaction forces ``f_k`` (3,) N of its four feet
(world frame, the force the ground exerts on the foot). State (13,):
``[roll, pitch, yaw, p (3) m, omega (3) rad/s world, v (3) m/s, g]``, the
constant ``g`` (m/s^2) carrying gravity so the model is linear. Linearised
about the reference yaw (small roll and pitch):

    d(rpy)/dt = Rz(yaw)^T omega,   dp/dt = v,
    d(omega)/dt = I_w^-1 sum_k r_k x f_k,   dv/dt = sum_k f_k / m - g e_z,

with ``I_w = Rz I_b Rz^T`` and ``r_k`` (3,) m the foot position relative to
the CoM, held over the horizon. The dynamics are discretised exactly
(zero-order hold, matrix exponential) and condensed: the states over the
horizon are ``X = Aqp x0 + Bqp U`` with ``U`` (12 h,) the stacked foot forces.
The quadratic program

    min_U (X - Xref)^T L (X - Xref) + alpha |U|^2
    s.t.  |f_x|, |f_y| <= mu f_z,   fz_min c_k <= f_z <= fz_max c_k

(``c_k`` in {0, 1} the planned contact of foot k at each step) is solved by one
of two solvers (``MPCConfig.solver``):

- ``osqp``: OSQP on the sparse form (states and forces as variables, the
  dynamics as equality rows). Its sparsity pattern never changes, so the solver
  is set up once and only the numbers are updated per solve (warm-started). It
  stops at its tolerances (1e-3), a few newtons from the optimum.
- ``daqp``: the dual active-set solver DAQP on the condensed form (forces only,
  ``H`` (12 h, 12 h) dense), warm-started with the last solve's active set. It
  returns the optimum to DAQP's tolerances (1e-6), in fewer and cheaper iterations
  (timed in docs/engines.md, "Speed"): with the yaw fixed, ``H = 2 (D^T W D + alpha I)`` needs only the
  moment arms per solve (``D`` block diagonal, the input map's six rows that move),
  ``W`` being kept per yaw (``CondensedForm``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import daqp
import numpy as np

from symrom.names import GRAVITY
from symrom.sim.controllers.compiled import clip_forces, condensed_qp
from symrom.sim.controllers.motion import QP_SOLVERS

if TYPE_CHECKING:
    import osqp
    import scipy.sparse as sp

N_X = 13  # state size
N_U = 12  # 4 feet x 3 force components
MOVING = np.arange(6, 12)  # the rows of Bc that hold the inputs (omega and v); the rest are 0


@dataclass
class MPCConfig:
    """Horizon, weights and limits of the MPC.

    solver: ``osqp`` or ``daqp`` (module docstring; eps_abs to check_termination are
    OSQP's); horizon: number of steps; dt: step length, s; mu: friction coefficient of
    the pyramid; fz_min / fz_max: normal-force bounds of a foot in contact, N;
    weights: per-state weights (13,) on [rpy, p, omega, v, g]; alpha: weight on
    the forces, 1/N^2; eps_abs / eps_rel / max_iter: OSQP's stopping tolerances
    (forces are tens of N, so 1e-3 changes nothing a robot would feel);
    check_termination: OSQP checks them every that many iterations (its default, 25).
    Warm-started from the previous solve, a solve meets the tolerances within 10-30
    iterations, so checking every 5 stops it sooner; but it then stops
    at another point within the tolerances, which changes the landings (the median peak
    knee torque of 24 Go1 jumps moves by -6 %), so the default keeps the data as they were.
    """

    horizon: int = 10
    dt: float = 0.025
    mu: float = 0.6
    fz_min: float = 0.0
    fz_max: float = 250.0
    weights: tuple[float, ...] = (25.0, 25.0, 10.0, 20.0, 20.0, 50.0,
                                  0.5, 0.5, 0.2, 1.0, 1.0, 2.0, 0.0)
    alpha: float = 1e-5
    eps_abs: float = 1e-3
    eps_rel: float = 1e-3
    max_iter: int = 4000
    check_termination: int = 25
    solver: str = "osqp"

    def __post_init__(self) -> None:
        if self.solver not in QP_SOLVERS:
            raise ValueError(f"MPC solver must be one of {QP_SOLVERS}, got {self.solver!r}")


def skew(v: np.ndarray) -> np.ndarray:
    """(3, 3) cross-product matrix of v (3,)."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rot_z(yaw: float) -> np.ndarray:
    """(3, 3) rotation about z by ``yaw`` rad."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def continuous_dynamics(mass: float, inertia_body: np.ndarray, yaw: float,
                        r_feet: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time SRB model ``dx/dt = Ac x + Bc u``.

    mass kg; inertia_body (3, 3) kg m^2; yaw rad; r_feet (4, 3) m, feet minus
    CoM in the world. Returns Ac (13, 13), Bc (13, 12).
    """
    Rz = rot_z(yaw)
    Ac = np.zeros((N_X, N_X))
    Ac[0:3, 6:9] = Rz.T
    Ac[3:6, 9:12] = np.eye(3)
    Ac[11, 12] = -1.0  # dvz/dt = ... - g
    Iw_inv = np.linalg.inv(Rz @ inertia_body @ Rz.T)
    Bc = np.zeros((N_X, N_U))
    for k in range(4):
        Bc[6:9, 3 * k:3 * k + 3] = Iw_inv @ skew(r_feet[k])
        Bc[9:12, 3 * k:3 * k + 3] = np.eye(3) / mass
    return Ac, Bc


def discretize(Ac: np.ndarray, Bc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation: (13, 13), (13, 12) -> A (13, 13), B (13, 12).

    The SRB ``Ac`` is nilpotent (``nilpotent_hold``): the matrix exponential is exact in
    closed form, with no ``expm`` call; any other ``Ac`` goes through ``expm``.
    """
    series = nilpotent_hold(Ac, dt)
    if series is None:
        M = np.zeros((Ac.shape[0] + Bc.shape[1],) * 2)
        M[:Ac.shape[0], :Ac.shape[0]], M[:Ac.shape[0], Ac.shape[0]:] = Ac, Bc
        import scipy.linalg  # here: the SRB model never needs it

        E = scipy.linalg.expm(M * dt)
        return E[:Ac.shape[0], :Ac.shape[0]], E[:Ac.shape[0], Ac.shape[0]:]
    A, F = series
    return A, F @ Bc


def nilpotent_hold(Ac: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray] | None:
    """A = exp(Ac dt) and F (n, n) with B = F Bc, if Ac (n, n) has Ac^3 = 0; else None.

    The SRB ``Ac`` has Ac^3 = 0 (omega -> rpy, v -> p and g -> v -> p are chains of
    length <= 2), so the series end after three terms: A = I + Ac dt + Ac^2 dt^2/2,
    F = I dt + Ac dt^2/2 + Ac^2 dt^3/6.
    """
    Ac2 = Ac @ Ac
    if np.any(Ac2 @ Ac):
        return None
    eye = np.eye(Ac.shape[0])
    return eye + Ac * dt + Ac2 * (dt * dt / 2.0), eye * dt + Ac * (dt * dt / 2.0) + Ac2 * (dt ** 3 / 6.0)


def condense(A: np.ndarray, B: np.ndarray, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Stacked prediction X = Aqp x0 + Bqp U: Aqp (13 h, 13), Bqp (13 h, m h) for B (13, m)
    (the forces' B, m = 12, or any other input map)."""
    m = B.shape[1]
    Apow = [np.eye(N_X)]
    for _ in range(horizon):
        Apow.append(A @ Apow[-1])
    Aqp = np.vstack(Apow[1:])
    AB = [B]  # A^i B, one step at a time: A (A^(i-1) B)
    for _ in range(horizon - 1):
        AB.append(A @ AB[-1])
    Bqp = np.zeros((N_X * horizon, m * horizon))
    for i in range(horizon):
        for j in range(i + 1):
            Bqp[N_X * i:N_X * (i + 1), m * j:m * (j + 1)] = AB[i - j]
    return Aqp, Bqp


def friction_matrix(mu: float, horizon: int) -> sp.csc_matrix:
    """Constraint rows per foot and step: f_z (bounded), and the 4 pyramid faces.

    Returns C (5 * 4 h, 12 h); rows per foot: [fz, fx - mu fz, -fx - mu fz,
    fy - mu fz, -fy - mu fz].
    """
    import scipy.sparse as sp  # here: only the osqp solver's sparse form needs it

    block = np.array([[0, 0, 1], [1, 0, -mu], [-1, 0, -mu], [0, 1, -mu], [0, -1, -mu]], float)
    return sp.csc_matrix(sp.block_diag([block] * (4 * horizon)))


class CondensedForm:
    """The condensed QP's parts that depend on the yaw alone, for quick ``H`` and ``g``.

    With ``G_m = A^m F`` (B = F Bc, ``nilpotent_hold``) the stacked states are
    ``X = Aqp x0 + Gqp blkdiag(Bc) U``; ``Bc`` is zero but in its rows ``MOVING``
    (``Bc'`` (6, 12)), so with ``V = Gqp[:, moving]^T L`` (6 h, 13 h):

        H = 2 (D^T W D + alpha I),  W = V Gqp[:, moving] (6 h, 6 h),
        g = 2 D^T (V Aqp x0 - V Xref),  D = blkdiag_h(Bc').

    yaw rad; A (13, 13), F (13, 13) of that yaw; L (13 h,) the state weights.
    """

    def __init__(self, A: np.ndarray, F: np.ndarray, L: np.ndarray, horizon: int):
        h = horizon
        Aqp, Gqp = condense(A, F, h)  # Gqp (13 h, 13 h): the stacked A^(i-j) F
        cols = (N_X * np.arange(h)[:, None] + MOVING).ravel()
        V = Gqp[:, cols].T * L  # (6 h, 13 h)
        self.horizon = h
        self.W4 = np.ascontiguousarray((V @ Gqp[:, cols]).reshape(h, MOVING.size, h, MOVING.size))
        self.VA = V @ Aqp  # (6 h, 13)
        self.V = V

    def qp(self, Bc_moving: np.ndarray, x0: np.ndarray, x_ref: np.ndarray, alpha: float
           ) -> tuple[np.ndarray, np.ndarray]:
        """H (12 h, 12 h), g (12 h,) for Bc' (6, 12), x0 (13,), x_ref (h, 13): one compiled call."""
        n = N_U * self.horizon
        H, g = np.empty((n, n)), np.empty(n)
        condensed_qp(self.W4, self.VA, self.V, np.ascontiguousarray(Bc_moving), x0,
                     np.ascontiguousarray(x_ref).reshape(-1), alpha, H, g)
        return H, g


@dataclass
class MPCResult:
    """One solve: forces (4, 3) N for the first step (world, ground on foot),
    the whole plan (h, 4, 3), the solver status and the wall time, s."""

    forces: np.ndarray
    plan: np.ndarray
    status: str
    solve_time: float


@dataclass
class ConvexMPC:
    """Single-rigid-body MPC solved with OSQP or DAQP (``config.solver``); see the module
    docstring.

    mass kg, inertia_body (3, 3) kg m^2 (about the CoM, base frame).
    The QP handed to OSQP is the sparse (non-condensed) form: variables
    ``z = [x_1 .. x_h, u_0 .. u_{h-1}]`` (25 h,), the dynamics as equality
    rows. Its cost is constant and only the dynamics' numbers and the bounds
    change between solves, which keeps each solve cheap (no large dense
    products). DAQP gets the condensed form, from ``condensed_form`` (per yaw) and
    the moment arms; ``condensed_qp`` builds the same by stacking ``A^i B``, the
    reference it is tested against.
    """

    mass: float
    inertia_body: np.ndarray
    config: MPCConfig = field(default_factory=MPCConfig)

    def __post_init__(self) -> None:
        cfg, h = self.config, self.config.horizon
        self.inertia_body = np.asarray(self.inertia_body, dtype=float)
        self._L = np.tile(np.asarray(cfg.weights, dtype=float), h)  # diagonal of L
        self._nx, self._nu = N_X * h, N_U * h
        self._sparse = False  # the sparse form's parts (``_sparse_form``), made at the first OSQP solve
        self._solver: osqp.OSQP | None = None
        self._yaw_model: tuple | None = None  # ``_yaw_parts`` of the last yaw
        self._daqp_cache: dict[int, tuple] = {}  # ``_daqp_parts`` by the number of foot-steps down
        # by the foot-steps down (their flags' bytes): how many, the forces kept (12 h,) bool, their
        # indices and the rows and columns of H kept (None: all)
        self._kept_cache: dict[bytes, tuple] = {}
        self._sense: np.ndarray | None = None  # DAQP's last active set, and the feet down then
        self._sense_down = b""
        self.solve_times: list[float] = []

    def _sparse_form(self) -> None:
        """The parts of OSQP's sparse form that stay from solve to solve (DAQP needs none)."""
        import scipy.sparse as sp  # here: only the osqp solver needs it

        cfg, h, nx, nu = self.config, self.config.horizon, self._nx, self._nu
        self._P = sp.diags(np.concatenate([2.0 * self._L, np.full(nu, 2.0 * cfg.alpha)]),
                           format="csc")
        # Dynamics rows x_{k+1} - A x_k - B u_k = (A x0 if k == 0 else 0); A and B get a
        # dense block pattern so that every update keeps the sparsity structure.
        rows, cols, tags = [], [], []  # tag: -1 identity, 0 A-entry, 1 B-entry
        ia, ja = np.meshgrid(np.arange(N_X), np.arange(N_X), indexing="ij")
        ib, jb = np.meshgrid(np.arange(N_X), np.arange(N_U), indexing="ij")
        def block(r, c, tag):
            rows.append(r)
            cols.append(c)
            tags.append(np.full(r.size, tag))

        for k in range(h):
            r0 = N_X * k
            block(r0 + np.arange(N_X), r0 + np.arange(N_X), -1)
            if k > 0:
                block(r0 + ia.ravel(), N_X * (k - 1) + ja.ravel(), 0)
            block(r0 + ib.ravel(), nx + N_U * k + jb.ravel(), 1)
        fric = friction_matrix(cfg.mu, h).tocoo()
        block(nx + fric.row, nx + fric.col, 2)  # tag 2: friction rows, constant
        rows, cols, tags = map(np.concatenate, (rows, cols, tags))
        values = np.zeros(rows.size)
        values[tags == 2] = fric.data
        # Build with entry ids as data to learn where each entry lands in CSC order.
        ids = np.arange(rows.size, dtype=float) + 1.0
        M = sp.coo_matrix((ids, (rows, cols)), shape=(nx + fric.shape[0], nx + nu)).tocsc()
        M.sort_indices()
        order = (M.data - 1).astype(int)
        self._M_values = values[order]
        self._tag = tags[order]
        self._row = rows[order] % N_X  # row inside A or B (dynamics entries)
        self._col = np.where(self._tag == 1, (cols[order] - nx) % N_U, cols[order] % N_X)
        self._M_template = M
        self._is_one, self._is_a, self._is_b = (self._tag == -1), (self._tag == 0), (self._tag == 1)
        # where A's and B's entries go in the data array, and where they come from in A.ravel(), B.ravel()
        self._a_pos, self._b_pos = np.flatnonzero(self._is_a), np.flatnonzero(self._is_b)
        self._a_src = self._row[self._is_a] * N_X + self._col[self._is_a]
        self._b_src = self._row[self._is_b] * N_U + self._col[self._is_b]
        self._data_a: tuple | None = None  # (A, data with A's entries) of the last A
        # bounds with their constant parts in place; per solve the dynamics' first rows and the
        # normal-force bounds (rows of f_z: every 5th friction row) are filled in
        n_fric = fric.shape[0]
        self._lo0 = np.concatenate([np.zeros(nx), np.tile([0.0, -np.inf, -np.inf, -np.inf, -np.inf], n_fric // 5)])
        self._hi0 = np.zeros(nx + n_fric)
        self._fz_rows = nx + 5 * np.arange(n_fric // 5)
        self._q_scale = -2.0 * self._L  # linear cost of the states is q_scale * x_ref
        self._sparse = True

    def _matrix_data(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """Data array (CSC order) of the constraint matrix for the discrete model A, B."""
        if self._data_a is None or self._data_a[0] is not A:  # A changes with the yaw only
            data = self._M_values.copy()
            data[self._is_one] = 1.0
            data[self._a_pos] = -A.ravel()[self._a_src]
            self._data_a = (A, data)
        data = self._data_a[1].copy()
        data[self._b_pos] = -B.ravel()[self._b_src]
        return data

    def _bounds(self, x0: np.ndarray, A: np.ndarray, contact: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of all constraint rows: dynamics, then friction."""
        cfg = self.config
        c = np.asarray(contact, dtype=float).reshape(-1)  # (4 h,)
        lo, hi = self._lo0.copy(), self._hi0.copy()
        lo[:N_X] = hi[:N_X] = A @ x0
        lo[self._fz_rows] = cfg.fz_min * c
        hi[self._fz_rows] = cfg.fz_max * c
        return lo, hi

    def _yaw_parts(self, yaw: float) -> tuple:
        """(yaw, A, F, I_w^-1, Bc, condensed form or None) of ``yaw``, kept for the last yaw."""
        if self._yaw_model is None or self._yaw_model[0] != yaw:
            Ac, Bc = continuous_dynamics(self.mass, self.inertia_body, yaw, np.zeros((4, 3)))
            A, F = nilpotent_hold(Ac, self.config.dt)  # nilpotent by its structure, whatever the yaw
            Rz = rot_z(yaw)
            self._yaw_model = (yaw, A, F, np.linalg.inv(Rz @ self.inertia_body @ Rz.T), Bc, None)
        return self._yaw_model

    def _input_map(self, r_feet: np.ndarray, yaw: float) -> np.ndarray:
        """Continuous input map Bc (13, 12) for feet r_feet (4, 3) m: only the moment arms
        (rows 6-8) change from solve to solve."""
        _, _, _, Iw_inv, Bc, _ = self._yaw_parts(yaw)
        r = np.asarray(r_feet, dtype=float)
        S = np.zeros((4, 3, 3))  # skew(r_k) per foot
        S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
        S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = r[:, 2], -r[:, 1], r[:, 0]
        Bc = Bc.copy()
        # one stacked product, the same 3 x 3 products as foot by foot
        Bc[6:9] = (Iw_inv @ S).transpose(1, 0, 2).reshape(3, 3 * 4)
        return Bc

    def model(self, r_feet: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
        """Discrete model A (13, 13), B (13, 12) for feet r_feet (4, 3) m and yaw rad.

        Only the inputs' moment arms change from solve to solve: A and the map F of
        B = F Bc (``nilpotent_hold``) depend on the yaw alone and are kept for the last yaw.
        """
        Bc = self._input_map(r_feet, yaw)
        _, A, F, _, _, _ = self._yaw_model
        return A, F @ Bc

    def condensed_form(self, yaw: float) -> CondensedForm:
        """The ``CondensedForm`` of ``yaw`` (kept for the last yaw)."""
        parts = self._yaw_parts(yaw)
        if parts[5] is None:
            self._yaw_model = parts = parts[:5] + (CondensedForm(parts[1], parts[2], self._L,
                                                                  self.config.horizon),)
        return parts[5]

    def condensed_qp(self, x0: np.ndarray, x_ref: np.ndarray, r_feet: np.ndarray, yaw: float
                     ) -> tuple[np.ndarray, np.ndarray]:
        """The same QP in the forces only: 1/2 U^T H U + g^T U, H (12 h, 12 h), g (12 h,).

        x0 (13,); x_ref (h, 13); r_feet (4, 3) m; yaw rad (linearisation point).
        """
        cfg = self.config
        A, B = self.model(r_feet, yaw)
        Aqp, Bqp = condense(A, B, cfg.horizon)
        LB = Bqp * self._L[:, None]
        H = 2.0 * (Bqp.T @ LB + cfg.alpha * np.eye(N_U * cfg.horizon))
        g = 2.0 * LB.T @ (Aqp @ x0 - np.asarray(x_ref).reshape(-1))
        return H, g

    def _solve_osqp(self, x0: np.ndarray, x_ref: np.ndarray, r_feet: np.ndarray,
                    contact: np.ndarray, yaw: float) -> tuple[np.ndarray, str]:
        """Forces U (12 h,) N and OSQP's status, from the sparse form."""
        cfg = self.config
        if not self._sparse:
            self._sparse_form()
        A, B = self.model(r_feet, yaw)
        data = self._matrix_data(A, B)
        lo, hi = self._bounds(x0, A, contact)
        q = np.zeros(self._nx + self._nu)
        np.multiply(self._q_scale, x_ref.reshape(-1), out=q[:self._nx])
        if self._solver is None:
            import osqp  # here: only the osqp solver needs it
            import scipy.sparse as sp

            self._solver = osqp.OSQP()
            M = sp.csc_matrix((data, self._M_template.indices, self._M_template.indptr),
                              shape=self._M_template.shape)
            self._solver.setup(self._P, q, M, lo, hi, eps_abs=cfg.eps_abs, eps_rel=cfg.eps_rel,
                               max_iter=cfg.max_iter, polishing=False, verbose=False,
                               warm_starting=True, check_termination=cfg.check_termination)
        else:
            self._solver.update(Ax=data, q=q, l=lo, u=hi)
        res = self._solver.solve(raise_error=False)
        z = res.x
        U = np.zeros(self._nu) if z is None or not np.all(np.isfinite(z)) else z[self._nx:]
        return U, str(res.info.status)

    def _solve_daqp(self, x0: np.ndarray, x_ref: np.ndarray, r_feet: np.ndarray,
                    contact: np.ndarray, yaw: float) -> tuple[np.ndarray, str]:
        """Forces U (12 h,) N and a status, from the condensed form by DAQP.

        The forces of a foot off the ground are 0 and left out of the problem (DAQP would
        take their zero bounds for equalities, at five times the cost); those kept have f_z
        within its limits as simple bounds and the pyramid's four faces as rows. Warm-started
        with the last active set when the same feet are down, cold if that fails.
        """
        cfg = self.config
        down = np.asarray(contact, dtype=float).reshape(-1) != 0.0  # (4 h,) foot-steps on the ground
        pattern = down.tobytes()
        U = np.zeros(self._nu)
        if pattern not in self._kept_cache:
            kept = np.repeat(down, 3)  # (12 h,) the forces in the problem
            keep = np.flatnonzero(kept)
            some = keep.size < kept.size
            self._kept_cache[pattern] = (int(down.sum()), kept, keep, np.ix_(keep, keep) if some else None)
        n_down, kept, keep, rows_cols = self._kept_cache[pattern]
        if n_down == 0:
            self._sense = None
            return U, "solved"
        H, g = self.condensed_form(yaw).qp(self._input_map(r_feet, yaw)[MOVING], x0, x_ref, cfg.alpha)
        if rows_cols is not None:
            H, g = H[rows_cols], g[keep]
        rows, hi, lo = self._daqp_parts(n_down)
        warm = self._sense if self._sense is not None and self._sense_down == pattern else None
        for sense in ((warm, None) if warm is not None else (None,)):
            x, _, flag, info = (daqp.solve(H, g, rows, hi, lo) if sense is None
                                else daqp.solve(H, g, rows, hi, lo, sense))
            if flag >= 1 and np.all(np.isfinite(x)):
                self._sense, self._sense_down = (info["lam"] != 0.0).astype(np.int32), pattern
                U[kept] = x
                return U, "solved"
        self._sense = None
        return U, f"daqp exitflag {flag}"

    def _daqp_parts(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For n feet-steps on the ground: the pyramid's faces (4 n, 3 n) (each <= 0) and the
        upper and lower bounds (7 n,) of the forces (f_z within its limits) and the faces."""
        if n not in self._daqp_cache:
            cfg = self.config
            face = np.array([[1.0, 0.0, -cfg.mu], [-1.0, 0.0, -cfg.mu], [0.0, 1.0, -cfg.mu],
                             [0.0, -1.0, -cfg.mu]])
            hi = np.concatenate([np.tile([np.inf, np.inf, cfg.fz_max], n), np.zeros(4 * n)])
            lo = np.concatenate([np.tile([-np.inf, -np.inf, cfg.fz_min], n), np.full(4 * n, -np.inf)])
            self._daqp_cache[n] = (np.kron(np.eye(n), face), hi, lo)
        return self._daqp_cache[n]

    def solve(self, x0: np.ndarray, x_ref: np.ndarray, r_feet: np.ndarray,
              contact: np.ndarray, yaw: float | None = None) -> MPCResult:
        """Optimal foot forces.

        x0 (13,) current state (last entry g, m/s^2); x_ref (h, 13) reference
        states for steps 1..h; r_feet (4, 3) m feet minus CoM (world);
        contact (h, 4) planned contact flags; yaw: linearisation yaw, rad
        (default: the first reference yaw).
        """
        cfg, h = self.config, self.config.horizon
        x_ref = np.asarray(x_ref, dtype=float)
        if x_ref.shape != (h, N_X) or np.shape(contact) != (h, 4) or np.shape(r_feet) != (4, 3):
            raise ValueError("x_ref must be (h, 13), contact (h, 4), r_feet (4, 3)")
        t0 = time.perf_counter()
        yaw = float(x_ref[0, 2] if yaw is None else yaw)
        r_feet, x0 = np.asarray(r_feet, dtype=float), np.asarray(x0, dtype=float)
        if cfg.solver == "daqp":
            U, status = self._solve_daqp(x0, x_ref, r_feet, contact, yaw)
        else:
            U, status = self._solve_osqp(x0, x_ref, r_feet, contact, yaw)
        # OSQP stops at its tolerance: clip to the exact bounds so callers can rely on them.
        U = U.reshape(h, 4, 3).copy()
        clip_forces(U, np.asarray(contact, dtype=float), cfg.fz_min, cfg.fz_max, cfg.mu)
        dt = time.perf_counter() - t0
        self.solve_times.append(dt)
        return MPCResult(forces=U[0].copy(), plan=U, status=status, solve_time=dt)


def srb_state(rpy: np.ndarray, p_com: np.ndarray, omega: np.ndarray, v_com: np.ndarray,
              gravity: float = GRAVITY) -> np.ndarray:
    """Pack the MPC state (13,) from rpy (3,) rad, CoM p (3,) m, omega (3,) rad/s, v (3,) m/s."""
    return np.concatenate([rpy, p_com, omega, v_com, [gravity]])
