"""The jump planning problem: a stance force profile that lands the base on a target.

Decision variables: the summed ground force F = (F_x, F_z) N, piecewise constant
on ``knots`` equal intervals of the stance; the stance duration T_s and the
durations of the rise (lift-off to apex) and of the fall (apex to touchdown),
s; the model's state at every shooting node. Dynamics: the chosen model
(``plan.dynamics``), integrated by classical Runge-Kutta (``substeps`` per
shooting interval) over the stance (``knots`` intervals), the rise and the fall
(``flight_intervals`` each); the phase switches are the guards' constraints
(``plan.guards``). Bounds: F_z in [0, fz_max], the friction pyramid |F_x| <=
mu F_z, T_s, T_rise, T_fall in [t_min, t_max]. Objective:

    w_x (x_td - x_0 - target_x)^2 + w_apex (z_apex - H)^2
      + w_effort mean_k |(F_k - m g e_z) / (m g)|^2 + w_smooth sum_k |(F_k+1 - F_k) / (m g)|^2

with x_0 the base's x at the start of the push. Without a target apex H, the
apex is held at or above ``min_apex`` instead (the motion's nominal apex) and
w_apex is 0. The NLP is built once per model (CasADi SX, IPOPT) with the start
state, targets and heights as parameters; each solve starts from the previous
solution (or, the first time, from a constant-force ballistic guess).
Units: m, s, N.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from symrom.plan.dynamics import GRAVITY, PlanDynamics
from symrom.plan.guards import Guards, HeightGuards


class PlanError(RuntimeError):
    """A plan that could not be made (the solver failed or returned non-finite numbers)."""


@dataclass(frozen=True)
class PlanConfig:
    """knots: force intervals over the stance; substeps: RK4 steps per shooting interval;
    flight_intervals: shooting intervals of the rise and of the fall each; mu: friction
    coefficient; fz_max: largest summed normal force, N; stance_min / stance_max: bounds of the
    stance duration, s (the pronk's pushes last 0.15-0.2 s); t_min / t_max: bounds of the rise's
    and the fall's durations, s; w_x (1/m^2), w_apex (1/m^2), w_effort, w_smooth: objective weights; tol:
    IPOPT's tolerance; max_iter: IPOPT's iteration limit."""

    knots: int = 5
    substeps: int = 2
    flight_intervals: int = 2
    mu: float = 0.6
    fz_max: float = 1000.0
    stance_min: float = 0.12
    stance_max: float = 0.30
    t_min: float = 0.03
    t_max: float = 0.6
    w_x: float = 1e4
    w_apex: float = 1e4
    w_effort: float = 1e-2
    w_smooth: float = 1e-2
    tol: float = 1e-8
    max_iter: int = 200


@dataclass
class Plan:
    """A solved jump plan.

    forces (knots, 2) N: F_x, F_z on equal intervals of the stance; t_stance, t_rise, t_fall s;
    x0 m: base x at the start of the push; landing_x m: planned touchdown x relative to x0;
    apex_z m: planned apex height; liftoff (2,) m/s: planned base velocity at lift-off;
    nodes (n, 2) m: base x, z at the shooting nodes (start, stance, rise, fall); solve_time_s:
    wall time of the solve; solve_cpu_s: the process's CPU time during it (about the wall time:
    one core); status: IPOPT's return status; success; iterations."""

    forces: np.ndarray
    t_stance: float
    t_rise: float
    t_fall: float
    x0: float
    landing_x: float
    apex_z: float
    liftoff: np.ndarray
    nodes: np.ndarray
    solve_time_s: float
    status: str
    success: bool
    iterations: int
    solve_cpu_s: float = float("nan")

    def force_at(self, tau: float) -> np.ndarray:
        """F (2,) N at tau s after the start of the push (zero after the stance)."""
        if tau < 0 or tau >= self.t_stance:
            return np.zeros(2)
        k = min(int(tau / self.t_stance * len(self.forces)), len(self.forces) - 1)
        return self.forces[k]

    def to_dict(self) -> dict:
        return {"forces_N": self.forces.tolist(), "t_stance_s": self.t_stance, "t_rise_s": self.t_rise,
                "t_fall_s": self.t_fall, "x0_m": self.x0, "landing_x_m": self.landing_x,
                "apex_z_m": self.apex_z, "liftoff_velocity_m_s": self.liftoff.tolist(),
                "nodes_xz_m": self.nodes.tolist(), "solve_time_s": self.solve_time_s,
                "solve_cpu_s": self.solve_cpu_s, "status": self.status,
                "success": self.success, "iterations": self.iterations}


def _rk4(f, s, h, n):
    """n classical Runge-Kutta steps of length h of ds/dt = f(s)."""
    for _ in range(n):
        k1 = f(s)
        k2 = f(s + h / 2 * k1)
        k3 = f(s + h / 2 * k2)
        k4 = f(s + h * k3)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s


class JumpPlanner:
    """The NLP of one model, built once (module docstring); ``solve`` plans one jump.

    dyn: the model (``PlanDynamics``); mass kg: the robot's, for the scale of the force terms
    and the first guess; guards: the phase-switch rule; torque_map: (A (m, 2), limits (m,)) with
    A F the joint torques (N m) a summed force F asks of the legs, bounded by the limits."""

    def __init__(self, dyn: PlanDynamics, mass: float, config: PlanConfig | None = None,
                 guards: Guards | None = None, torque_map: tuple[np.ndarray, np.ndarray] | None = None):
        self.dyn, self.mass = dyn, float(mass)
        self.config = cfg = config or PlanConfig()
        self.guards = guards or HeightGuards()
        n, N, K, M = dyn.n_state, cfg.knots, cfg.flight_intervals, cfg.substeps
        w = self.mass * GRAVITY
        # parameters: start state, target x, target apex, its weight, least apex, lift-off height
        s0 = ca.SX.sym("s0", n)
        target_x, apex_ref, w_apex, min_apex, z_lo = (ca.SX.sym(k) for k in
                                                      ("target_x", "apex", "w_apex", "min_apex", "z_lo"))
        P = ca.vertcat(s0, target_x, apex_ref, w_apex, min_apex, z_lo)
        T = ca.SX.sym("T", 3)  # stance, rise, fall durations
        F = ca.SX.sym("F", 2, N)
        S = ca.SX.sym("S", n, N + 2 * K)  # shooting nodes after the start
        g, lbg, ubg = [], [], []

        def eq(e):
            g.append(e)
            lbg.extend([0.0] * e.numel())
            ubg.extend([0.0] * e.numel())

        def add(constraints):
            for e, lo, hi in constraints:
                g.append(e)
                lbg.append(lo)
                ubg.append(hi)

        prev = s0
        h_st = T[0] / (N * M)
        for k in range(N):  # stance, F_k held
            Fk = F[:, k]
            eq(_rk4(lambda s, Fk=Fk: self.dyn.stance(s, Fk), prev, h_st, M) - S[:, k])
            prev = S[:, k]
            add([(dyn.velocity(prev)[1], 0.0, ca.inf)])  # the base rises all through the push
            add([(Fk[0] - cfg.mu * Fk[1], -ca.inf, 0.0), (Fk[0] + cfg.mu * Fk[1], 0.0, ca.inf)])
            if torque_map is not None:  # joint torques the force asks of the legs, within the limits
                A, lim = torque_map
                tau = ca.mtimes(ca.DM(A), Fk)
                add([(tau[i], -float(lim[i]), float(lim[i])) for i in range(A.shape[0])])
        add(self.guards.liftoff(dyn, prev, z_lo, F[:, N - 1]))
        for phase, dur in ((0, T[1]), (1, T[2])):  # rise, then fall
            h = dur / (K * M)
            for k in range(K):
                col = N + phase * K + k
                eq(_rk4(self.dyn.flight, prev, h, M) - S[:, col])
                prev = S[:, col]
            if phase == 0:
                apex_state = prev
                add(self.guards.apex(dyn, prev))
                add([(dyn.position(prev)[1] - min_apex, 0.0, ca.inf)])
        add(self.guards.touchdown(dyn, prev, z_lo))
        x_td = dyn.position(prev)[0] - dyn.position(s0)[0]
        z_apex = dyn.position(apex_state)[1]
        Fn = (F - ca.repmat(ca.DM([0.0, w]), 1, N)) / w
        J = (cfg.w_x * (x_td - target_x) ** 2 + w_apex * (z_apex - apex_ref) ** 2
             + cfg.w_effort * ca.sumsqr(Fn) / N + cfg.w_smooth * ca.sumsqr(ca.diff(F, 1, 1) / w))
        X = ca.vertcat(T, ca.vec(F), ca.vec(S))
        self._lbx = np.concatenate([[cfg.stance_min, cfg.t_min, cfg.t_min], np.tile([-cfg.mu * cfg.fz_max, 0.0], N),
                                    np.full(S.numel(), -np.inf)])
        self._ubx = np.concatenate([[cfg.stance_max, cfg.t_max, cfg.t_max], np.tile([cfg.mu * cfg.fz_max, cfg.fz_max], N),
                                    np.full(S.numel(), np.inf)])
        self._lbg, self._ubg = np.array(lbg), np.array(ubg)
        opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": cfg.tol,
                "ipopt.max_iter": cfg.max_iter, "ipopt.linear_solver": "mumps"}
        self._solver = ca.nlpsol("jump", "ipopt", {"x": X, "p": P, "f": J, "g": ca.vertcat(*g)}, opts)
        self._readout = ca.Function("readout", [X, P], [x_td, z_apex, dyn.velocity(S[:, N - 1]),
                                    ca.horzcat(dyn.position(s0), *[dyn.position(S[:, c]) for c in range(S.shape[1])]).T])
        Fc, hh = ca.SX.sym("Fc", 2), ca.SX.sym("h")
        self._stance_step = ca.Function("stance_step", [s0, Fc, hh], [_rk4(lambda s: dyn.stance(s, Fc), s0, hh, 1)])
        self._flight_step = ca.Function("flight_step", [s0, hh], [_rk4(dyn.flight, s0, hh, 1)])
        self._warm: np.ndarray | None = None

    # ------------------------------------------------------------------ guesses
    def _first_guess(self, s0: np.ndarray, target_x: float, apex: float, z_lo: float) -> np.ndarray:
        """A constant-force ballistic jump of the point mass, its states rolled out with the model."""
        cfg, dyn = self.config, self.dyn
        z0 = float(np.asarray(ca.DM(dyn.position(ca.DM(s0)))).ravel()[1])
        vz = np.sqrt(2 * GRAVITY * max(apex - z_lo, 0.02))
        t_st = float(np.clip(2 * max(z_lo - z0, 0.02) / vz, cfg.stance_min, cfg.stance_max))
        t_up = float(np.clip(vz / GRAVITY, cfg.t_min, cfg.t_max))
        vx = target_x / (0.5 * t_st + 2 * t_up)
        Fc = np.array([self.mass * vx / t_st, self.mass * (vz / t_st + GRAVITY)])
        Fc[0] = np.clip(Fc[0], -cfg.mu * Fc[1], cfg.mu * Fc[1])
        N, K, M = cfg.knots, cfg.flight_intervals, cfg.substeps
        nodes, s = [], ca.DM(s0)
        for _ in range(N):
            for _ in range(M):
                s = self._stance_step(s, Fc, t_st / (N * M))
            nodes.append(np.asarray(s).ravel())
        for _ in range(2 * K):
            for _ in range(M):
                s = self._flight_step(s, t_up / (K * M))
            nodes.append(np.asarray(s).ravel())
        return np.concatenate([[t_st, t_up, t_up], np.tile(Fc, N), np.concatenate(nodes)])

    # ------------------------------------------------------------------ solve
    def solve(self, s0: np.ndarray, target_x: float, z_liftoff: float, apex: float | None = None,
              min_apex: float | None = None, warm: bool = True) -> Plan:
        """Plan a jump from the model state s0 (n,) landing ``target_x`` m ahead of the start,
        lifting off at base height ``z_liftoff`` m; with ``apex`` (m) aimed at that apex height,
        else held at or above ``min_apex`` m. ``warm``: start from the previous solution."""
        cfg = self.config
        s0 = np.asarray(s0, dtype=float)
        if s0.shape != (self.dyn.n_state,) or not np.isfinite(s0).all():
            raise PlanError(f"start state: expected {self.dyn.n_state} finite numbers, got {s0.tolist()}")
        if apex is None and min_apex is None:
            raise PlanError("give a target apex height or a least apex height")
        w_apex = cfg.w_apex if apex is not None else 0.0
        ref = apex if apex is not None else min_apex
        lo = min_apex if apex is None else z_liftoff
        p = np.concatenate([s0, [target_x, ref, w_apex, lo, z_liftoff]])
        x_init = self._warm if (warm and self._warm is not None) else self._first_guess(s0, target_x, ref, z_liftoff)
        t, c = time.perf_counter(), time.process_time()
        sol = self._solver(x0=x_init, p=p, lbx=self._lbx, ubx=self._ubx, lbg=self._lbg, ubg=self._ubg)
        elapsed, cpu = time.perf_counter() - t, time.process_time() - c
        stats = self._solver.stats()
        x = np.asarray(sol["x"]).ravel()
        if not np.isfinite(x).all():
            raise PlanError(f"the {self.dyn.name} plan has non-finite numbers (IPOPT: {stats['return_status']})")
        success = bool(stats["success"])
        if success:
            self._warm = x
        x_td, z_apex, v_lo, nodes = (np.asarray(v) for v in self._readout(x, p))
        N = cfg.knots
        return Plan(forces=x[3:3 + 2 * N].reshape(N, 2), t_stance=float(x[0]), t_rise=float(x[1]),
                    t_fall=float(x[2]), x0=float(nodes[0, 0]), landing_x=float(x_td.item()), apex_z=float(z_apex.item()),
                    liftoff=v_lo.ravel(), nodes=nodes, solve_time_s=elapsed, status=str(stats["return_status"]),
                    success=success, iterations=int(stats["iter_count"]), solve_cpu_s=cpu)
