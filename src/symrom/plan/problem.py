"""The jump planning problem: a push force profile that lands the base on a target.

The push is one stance phase (a pronk: ``contact``) or several in a row (a froggy jump:
``contact`` on four feet, then ``partial`` on the rear feet alone), each a ``Stance``.
Decision variables: the summed ground force F = (F_x, F_z) N of the feet down, piecewise
constant on ``knots`` equal intervals of each stance; each stance's duration, and the
durations of the rise (lift-off to apex) and of the fall (apex to touchdown), s; the model's
state at every shooting node. Dynamics: the chosen model (``plan.dynamics``), integrated
by classical Runge-Kutta (``substeps`` per shooting interval) over the stances (``knots``
intervals each, in the model's phase of that stance), the rise and the fall
(``flight_intervals`` each); the phase switches are the guards' constraints
(``plan.guards``): lift-off at the end of the last stance at height z_lo, touchdown at
height z_td. With a ``release`` (``Release``: the data's, ``data.envelope``), the last stance
goes on for the release's length under its fixed force after the planned push ends, and the
lift-off guard holds at its end: the push ends where the release must begin. With a flight
bias (``FlightBias``: fitted on the training jumps, ``plan.bias``), the landing x_td is the
flight's plus the bias at the lift-off velocity: what the flight misses of the base's travel
while the legs swing under it. Bounds: F_z in
[0, fz_max], the friction pyramid |F_x| <= mu F_z, each
stance's duration within its bounds, T_rise, T_fall in [t_min, t_max]. Objective:

    w_x (x_td - x_0 - target_x)^2 + w_apex (z_apex - H)^2
      + w_effort mean_k |(F_k - m g e_z) / (m g)|^2 + w_smooth sum_k |(F_k+1 - F_k) / (m g)|^2

with x_0 the base's x at the start of the push (the smoothness term within each stance).
Without a target apex H, the apex is held at or above ``min_apex`` instead (the motion's
nominal apex) and w_apex is 0. The NLP is built once per model (CasADi SX, IPOPT) with the
start state, targets and heights as parameters; each solve starts from the previous
solution (or, the first time, from a constant-force ballistic guess).

Reach (``JumpPlanner.reach``): the same constraints with a linear objective, the farthest
and nearest landing, the highest and lowest apex, from a start state (a second NLP, built
on first use).
Units: m, s, N.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from symrom.names import GRAVITY, STANCE_PHASE
from symrom.plan.config import PlanConfig
from symrom.plan.dynamics import PlanDynamics
from symrom.plan.guards import Guards, HeightGuards


class PlanError(RuntimeError):
    """A plan that could not be made (the solver failed or returned non-finite numbers)."""


@dataclass(frozen=True)
class Stance:
    """One stance phase of the push: the model's phase it runs in, its force intervals
    (knots) and the bounds of its duration t_min, t_max s."""

    phase: str
    knots: int
    t_min: float
    t_max: float


@dataclass
class Plan:
    """A solved jump plan.

    forces (N, 2) N: F_x, F_z on the knots of the stances in turn (each stance's on equal
    intervals of it); t_stance s: the whole push; t_rise, t_fall s; x0 m: base x at the start
    of the push; landing_x m: planned touchdown x relative to x0; apex_z m: planned apex
    height; liftoff (2,) m/s: planned base velocity at the push's end (lift-off, or where a
    ``Release`` begins); nodes (n, 2) m: base x, z at the shooting nodes (start, stances, rise,
    fall); solve_time_s: wall time of the solve;
    solve_cpu_s: the process's CPU time during it (about the wall time: one core); status:
    IPOPT's return status; success; iterations; stances: the ``Stance`` of each part of the
    push and durations (s) their lengths (one of each for a one-stance push); states (n, s):
    the model's state at the nodes."""

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
    stances: tuple[Stance, ...] = ()
    durations: tuple[float, ...] = ()
    states: np.ndarray | None = field(default=None, repr=False)

    def _parts(self) -> list[tuple[float, int]]:
        """(duration s, knots) of each stance."""
        if not self.durations:
            return [(self.t_stance, len(self.forces))]
        return [(d, st.knots) for d, st in zip(self.durations, self.stances)]

    def force_at(self, tau: float) -> np.ndarray:
        """F (2,) N at tau s after the start of the push (zero after the stance)."""
        if tau < 0 or tau >= self.t_stance:
            return np.zeros(2)
        start, first = 0.0, 0
        parts = self._parts()
        for i, (d, n) in enumerate(parts):
            if tau < start + d or i == len(parts) - 1:
                k = min(int((tau - start) / d * n), n - 1) if d > 0 else n - 1
                return self.forces[first + max(k, 0)]
            start, first = start + d, first + n
        return self.forces[-1]  # not reached

    def phase_at(self, tau: float) -> int:
        """Index of the stance (into ``stances``) at tau s after the start of the push; the last
        one from its end on."""
        start = 0.0
        parts = self._parts()
        for i, (d, _) in enumerate(parts):
            if tau < start + d:
                return i
            start += d
        return len(parts) - 1

    def to_dict(self) -> dict:
        d = {"forces_N": self.forces.tolist(), "t_stance_s": self.t_stance, "t_rise_s": self.t_rise,
             "t_fall_s": self.t_fall, "x0_m": self.x0, "landing_x_m": self.landing_x,
             "apex_z_m": self.apex_z, "liftoff_velocity_m_s": self.liftoff.tolist(),
             "nodes_xz_m": self.nodes.tolist(), "solve_time_s": self.solve_time_s,
             "solve_cpu_s": self.solve_cpu_s, "status": self.status,
             "success": self.success, "iterations": self.iterations}
        if self.stances:
            d["stances"] = [{"phase": st.phase, "knots": st.knots, "duration_s": dur}
                            for st, dur in zip(self.stances, self.durations)]
        return d


@dataclass(frozen=True)
class Release:
    """What follows the planned push in the last stance before the feet leave: ``duration`` s
    under the summed force ``force`` (F_x, F_z) N, in the model's input as the data derive it
    (``data.envelope``'s ``release``: the held legs' pull on the trunk)."""

    duration: float
    force: tuple[float, float]

    def __post_init__(self):
        if not (np.isfinite(self.duration) and self.duration > 0 and np.all(np.isfinite(self.force))):
            raise ValueError(f"a release needs a positive length and a finite force, got {self}")


@dataclass(frozen=True)
class FlightBias:
    """What a planner's flight misses of the base's forward travel from lift-off to touchdown:
    the base travels ``offset`` m + ``per_velocity`` (s) · (vx, vz) further than the flight
    predicts from a lift-off at velocity (vx, vz) m/s as the planner's state reads it; fitted on
    ``jumps`` training jumps, whose travel it predicts to ``rms_m`` (without it, with it) m
    (``plan.bias``)."""

    offset: float
    per_velocity: tuple[float, float]
    jumps: int = 0
    rms_m: tuple[float, float] = (float("nan"), float("nan"))

    def __post_init__(self):
        if not (np.isfinite(self.offset) and np.all(np.isfinite(self.per_velocity))
                and len(self.per_velocity) == 2):
            raise ValueError(f"a flight bias needs a finite offset and two finite slopes, got {self}")

    def at(self, v):
        """The bias (m) at lift-off velocity v (2,) m/s (numbers or CasADi)."""
        return self.offset + self.per_velocity[0] * v[0] + self.per_velocity[1] * v[1]

    def to_dict(self) -> dict:
        return {"offset_m": self.offset, "per_velocity_s": list(self.per_velocity), "jumps": self.jumps,
                "rms_m": list(self.rms_m)}


def _biased(dyn, s_liftoff, bias: FlightBias | None):
    """The flight bias (m) at lift-off state ``s_liftoff`` (0 without one)."""
    return 0.0 if bias is None else bias.at(dyn.velocity(s_liftoff))


def _released(dyn, s, release: Release | None, phase: str, substeps: int, offset=None):
    """The state s after ``release`` in stance ``phase`` (s itself without one); ``offset``: an
    acceleration (the state's velocity part) added to the stance's (``replan``'s estimate)."""
    if release is None:
        return s
    F = ca.DM(list(release.force))

    def stance(v):
        ds = dyn.stance(v, F, phase)
        return ds if offset is None else ds + offset

    return _rk4(stance, s, release.duration / substeps, substeps)


@dataclass(frozen=True)
class Reach:
    """What a model can do from one start state under the problem's bounds (m): the landing's
    forward distance x_min..x_max (with the apex as asked) and the apex's height
    z_min..z_max."""

    x_min: float
    x_max: float
    z_min: float
    z_max: float


def _rk4(f, s, h, n):
    """n classical Runge-Kutta steps of length h of ds/dt = f(s)."""
    for _ in range(n):
        k1 = f(s)
        k2 = f(s + h / 2 * k1)
        k3 = f(s + h / 2 * k2)
        k4 = f(s + h * k3)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s


# A (m, 2), limits (m,): -limits <= A F <= limits; or A, lower (m,), upper (m,)
TorqueMap = tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]


def linear_bounds(tmap: TorqueMap) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, lower, upper) of a ``TorqueMap``: lower <= A F <= upper."""
    if len(tmap) == 2:
        A, lim = tmap
        return np.asarray(A, float), -np.asarray(lim, float), np.asarray(lim, float)
    A, lo, hi = tmap
    return np.asarray(A, float), np.asarray(lo, float), np.asarray(hi, float)


def force_rows(Fk, mu: float, tmap: TorqueMap | None) -> list[tuple]:
    """The rows (expression, lower, upper) one interval's summed force Fk (2,) N (CasADi) must
    meet: the friction pyramid |F_x| <= mu F_z and, with a ``TorqueMap``, lower <= A Fk <= upper
    (the joint torques the force asks of the legs, and a rear pair's pitching moment)."""
    rows = [(Fk[0] - mu * Fk[1], -ca.inf, 0.0), (Fk[0] + mu * Fk[1], 0.0, ca.inf)]
    if tmap is not None:
        A, lo, hi = linear_bounds(tmap)
        tau = ca.mtimes(ca.DM(A), Fk)
        rows += [(tau[i], float(lo[i]), float(hi[i])) for i in range(A.shape[0])]
    return rows


class JumpPlanner:
    """The NLP of one model, built once (module docstring); ``solve`` plans one jump.

    dyn: the model (``PlanDynamics``); mass kg: the robot's, for the scale of the force terms
    and the first guess; guards: the phase-switch rule; torque_map: (A (m, 2), limits (m,))
    with A F the joint torques (N m) a summed force F asks of the legs, bounded by the limits,
    or (A, lower, upper) with bounds of each side (a rear pair's pitching moment among the
    rows, ``jump.pitch_bounds``), or one such per stance phase (a dict by phase); stances: the
    push's stances in turn (default: one ``contact`` stance of ``config.knots`` intervals,
    ``config.stance_min`` to ``config.stance_max`` s); release: what follows the push in the last
    stance before lift-off (``Release``), or None."""

    def __init__(self, dyn: PlanDynamics, mass: float, config: PlanConfig | None = None,
                 guards: Guards | None = None, torque_map: TorqueMap | dict[str, TorqueMap] | None = None,
                 stances: tuple[Stance, ...] | None = None, release: Release | None = None,
                 bias: FlightBias | None = None):
        self.dyn, self.mass, self.release, self.bias = dyn, float(mass), release, bias
        self.config = cfg = config or PlanConfig()
        self.guards = guards or HeightGuards()
        self.stances = stances = tuple(stances or (Stance(STANCE_PHASE, cfg.knots, cfg.stance_min, cfg.stance_max),))
        if not isinstance(torque_map, dict):
            torque_map = {st.phase: torque_map for st in stances}
        self.torque_maps = torque_map
        P_st = len(stances)
        n, K, M = dyn.n_state, cfg.flight_intervals, cfg.substeps
        N = sum(st.knots for st in stances)
        w = self.mass * GRAVITY
        # parameters: start state, target x, target apex, its weight, least apex, lift-off and
        # touchdown heights
        s0 = ca.SX.sym("s0", n)
        target_x, apex_ref, w_apex, min_apex, z_lo, z_td = (ca.SX.sym(k) for k in
                                                            ("target_x", "apex", "w_apex", "min_apex", "z_lo", "z_td"))
        P = ca.vertcat(s0, target_x, apex_ref, w_apex, min_apex, z_lo, z_td)
        T = ca.SX.sym("T", P_st + 2)  # stance durations, rise, fall
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
        col = 0
        for p, st in enumerate(stances):
            h_st = T[p] / (st.knots * M)
            tmap = torque_map.get(st.phase)
            for _ in range(st.knots):  # the stance, F_k held
                Fk = F[:, col]
                eq(_rk4(lambda s, Fk=Fk, ph=st.phase: self.dyn.stance(s, Fk, ph), prev, h_st, M) - S[:, col])
                prev = S[:, col]
                add([(dyn.velocity(prev)[1], 0.0, ca.inf)])  # the base rises all through the push
                add(force_rows(Fk, cfg.mu, tmap))  # friction, and the torques the force asks of the legs
                col += 1
        prev = _released(dyn, prev, release, stances[-1].phase, M)
        lift = prev
        add(self.guards.liftoff(dyn, prev, z_lo, F[:, N - 1]))
        for phase, dur in ((0, T[P_st]), (1, T[P_st + 1])):  # rise, then fall
            h = dur / (K * M)
            for k in range(K):
                c = N + phase * K + k
                eq(_rk4(self.dyn.flight, prev, h, M) - S[:, c])
                prev = S[:, c]
            if phase == 0:
                apex_state = prev
                add(self.guards.apex(dyn, prev))
                add([(dyn.position(prev)[1] - min_apex, 0.0, ca.inf)])
        add(self.guards.touchdown(dyn, prev, z_td))
        x_td = dyn.position(prev)[0] - dyn.position(s0)[0] + _biased(dyn, lift, bias)
        z_apex = dyn.position(apex_state)[1]
        Fn = (F - ca.repmat(ca.DM([0.0, w]), 1, N)) / w
        if P_st == 1:
            smooth = ca.sumsqr(ca.diff(F, 1, 1) / w)
        else:  # within each stance: the force may jump where the feet change
            first, smooth = 0, 0
            for st in stances:
                smooth = smooth + ca.sumsqr(ca.diff(F[:, first:first + st.knots], 1, 1) / w)
                first += st.knots
        effort = cfg.w_effort * ca.sumsqr(Fn) / N + cfg.w_smooth * smooth
        J = cfg.w_x * (x_td - target_x) ** 2 + w_apex * (z_apex - apex_ref) ** 2 + effort
        X = ca.vertcat(T, ca.vec(F), ca.vec(S))
        self._lbx = np.concatenate([[st.t_min for st in stances], [cfg.t_min, cfg.t_min],
                                    np.tile([-cfg.mu * cfg.fz_max, 0.0], N), np.full(S.numel(), -np.inf)])
        self._ubx = np.concatenate([[st.t_max for st in stances], [cfg.t_max, cfg.t_max],
                                    np.tile([cfg.mu * cfg.fz_max, cfg.fz_max], N), np.full(S.numel(), np.inf)])
        self._lbg, self._ubg = np.array(lbg), np.array(ubg)
        self._opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": cfg.tol,
                      "ipopt.max_iter": cfg.max_iter, "ipopt.linear_solver": "mumps"}
        self._solver = ca.nlpsol("jump", "ipopt", {"x": X, "p": P, "f": J, "g": ca.vertcat(*g)}, self._opts)
        self._readout = ca.Function("readout", [X, P], [x_td, z_apex, dyn.velocity(S[:, N - 1]),
                                    ca.horzcat(dyn.position(s0),
                                               *[dyn.position(S[:, c]) for c in range(S.shape[1])]).T])
        # what the reach problem is built from (``reach``)
        self._reach_parts = (X, P, ca.vertcat(*g), x_td, z_apex, effort)
        self._reach_solver = None
        Fc, hh = ca.SX.sym("Fc", 2), ca.SX.sym("h")
        self._stance_step = {st.phase: ca.Function("stance_step", [s0, Fc, hh],
                                                   [_rk4(lambda s, ph=st.phase: dyn.stance(s, Fc, ph), s0, hh, 1)])
                             for st in stances}
        self._flight_step = ca.Function("flight_step", [s0, hh], [_rk4(dyn.flight, s0, hh, 1)])
        self._n_knots = N
        self._warm: np.ndarray | None = None

    # ------------------------------------------------------------------ guesses
    def _first_guess(self, s0: np.ndarray, target_x: float, apex: float, z_lo: float) -> np.ndarray:
        """A constant-force ballistic jump of the point mass, its states rolled out with the model."""
        cfg, dyn, stances = self.config, self.dyn, self.stances
        z0 = float(np.asarray(ca.DM(dyn.position(ca.DM(s0)))).ravel()[1])
        vz = np.sqrt(2 * GRAVITY * max(apex - z_lo, 0.02))
        t_min, t_max = sum(st.t_min for st in stances), sum(st.t_max for st in stances)
        t_st = float(np.clip(2 * max(z_lo - z0, 0.02) / vz, t_min, t_max))
        t_up = float(np.clip(vz / GRAVITY, cfg.t_min, cfg.t_max))
        vx = target_x / (0.5 * t_st + 2 * t_up)
        Fc = np.array([self.mass * vx / t_st, self.mass * (vz / t_st + GRAVITY)])
        Fc[0] = np.clip(Fc[0], -cfg.mu * Fc[1], cfg.mu * Fc[1])
        K, M = cfg.flight_intervals, cfg.substeps
        if len(stances) == 1:
            durations = [t_st]
        else:  # each stance's share of the push by the middle of its bounds, within its bounds
            mids = np.array([(st.t_min + st.t_max) / 2 for st in stances])
            durations = [float(np.clip(t_st * m / mids.sum(), st.t_min, st.t_max)) for m, st in zip(mids, stances)]
        nodes, s = [], ca.DM(s0)
        for st, d in zip(stances, durations):
            for _ in range(st.knots):
                for _ in range(M):
                    s = self._stance_step[st.phase](s, Fc, d / (st.knots * M))
                nodes.append(np.asarray(s).ravel())
        s = _released(dyn, s, self.release, stances[-1].phase, M)
        for _ in range(2 * K):
            for _ in range(M):
                s = self._flight_step(s, t_up / (K * M))
            nodes.append(np.asarray(s).ravel())
        return np.concatenate([durations, [t_up, t_up], np.tile(Fc, self._n_knots), np.concatenate(nodes)])

    def _params(self, s0: np.ndarray, target_x: float, z_liftoff: float, apex: float | None,
                min_apex: float | None, z_touchdown: float | None) -> np.ndarray:
        cfg = self.config
        w_apex = cfg.w_apex if apex is not None else 0.0
        ref = apex if apex is not None else min_apex
        lo = min_apex if apex is None else z_liftoff
        z_td = z_liftoff if z_touchdown is None else z_touchdown
        return np.concatenate([s0, [target_x, ref, w_apex, lo, z_liftoff, z_td]])

    def _check_start(self, s0: np.ndarray) -> np.ndarray:
        s0 = np.asarray(s0, dtype=float)
        if s0.shape != (self.dyn.n_state,) or not np.isfinite(s0).all():
            raise PlanError(f"start state: expected {self.dyn.n_state} finite numbers, got {s0.tolist()}")
        return s0

    # ------------------------------------------------------------------ solve
    def solve(self, s0: np.ndarray, target_x: float, z_liftoff: float, apex: float | None = None,
              min_apex: float | None = None, warm: bool = True, z_touchdown: float | None = None,
              remember: bool = True) -> Plan:
        """Plan a jump from the model state s0 (n,) landing ``target_x`` m ahead of the start,
        lifting off at base height ``z_liftoff`` m and touching down at ``z_touchdown`` m
        (default: the lift-off height); with ``apex`` (m) aimed at that apex height, else held
        at or above ``min_apex`` m. ``warm``: start from the previous solution; ``remember``: a
        solution found becomes the next solve's start."""
        s0 = self._check_start(s0)
        if apex is None and min_apex is None:
            raise PlanError("give a target apex height or a least apex height")
        p = self._params(s0, target_x, z_liftoff, apex, min_apex, z_touchdown)
        ref = apex if apex is not None else min_apex
        x_init = self._warm if (warm and self._warm is not None) else self._first_guess(s0, target_x, ref, z_liftoff)
        t, c = time.perf_counter(), time.process_time()
        sol = self._solver(x0=x_init, p=p, lbx=self._lbx, ubx=self._ubx, lbg=self._lbg, ubg=self._ubg)
        elapsed, cpu = time.perf_counter() - t, time.process_time() - c
        stats = self._solver.stats()
        x = np.asarray(sol["x"]).ravel()
        if not np.isfinite(x).all():
            raise PlanError(f"the {self.dyn.name} plan has non-finite numbers (IPOPT: {stats['return_status']})")
        success = bool(stats["success"])
        if success and remember:
            self._warm = x
        return self._plan(x, p, elapsed, str(stats["return_status"]), success, int(stats["iter_count"]), cpu)

    def _plan(self, x: np.ndarray, p: np.ndarray, elapsed: float, status: str, success: bool, iterations: int,
              cpu: float) -> Plan:
        x_td, z_apex, v_lo, nodes = (np.asarray(v) for v in self._readout(x, p))
        P_st, N, n = len(self.stances), self._n_knots, self.dyn.n_state
        durations = tuple(float(v) for v in x[:P_st])
        states = np.vstack([p[:n], x[P_st + 2 + 2 * N:].reshape(-1, n)])
        return Plan(forces=x[P_st + 2:P_st + 2 + 2 * N].reshape(N, 2), t_stance=float(sum(durations)),
                    t_rise=float(x[P_st]), t_fall=float(x[P_st + 1]), x0=float(nodes[0, 0]),
                    landing_x=float(x_td.item()), apex_z=float(z_apex.item()), liftoff=v_lo.ravel(), nodes=nodes,
                    solve_time_s=elapsed, status=status, success=success, iterations=iterations, solve_cpu_s=cpu,
                    stances=self.stances, durations=durations, states=states)

    # ------------------------------------------------------------------ reach
    def _build_reach(self):
        X, P, g, x_td, z_apex, effort = self._reach_parts
        c_x, c_z, min_x, max_x, max_apex = (ca.SX.sym(k) for k in ("c_x", "c_z", "min_x", "max_x", "max_apex"))
        # a linear objective in dm; the effort terms, much smaller, keep the optimum unique
        J = 10.0 * (c_x * x_td + c_z * z_apex) + 1e-2 * effort
        g_r = ca.vertcat(g, x_td - min_x, x_td - max_x, z_apex - max_apex)
        self._reach_bounds = (np.concatenate([self._lbg, [0.0, -np.inf, -np.inf]]),
                              np.concatenate([self._ubg, [np.inf, 0.0, 0.0]]))
        opts = dict(self._opts, **{"ipopt.tol": 1e-6, "ipopt.max_iter": 300})
        self._reach_solver = ca.nlpsol("reach", "ipopt", {"x": X, "p": ca.vertcat(P, c_x, c_z, min_x, max_x, max_apex),
                                                          "f": J, "g": g_r}, opts)

    def _extreme(self, s0, z_liftoff, z_touchdown, min_apex, max_apex, min_x, max_x, c_x, c_z, guess) -> float | None:
        """The landing x (c_x) or apex (c_z) at its extreme, or None if infeasible."""
        if self._reach_solver is None:
            self._build_reach()
        p = np.concatenate([self._params(s0, 0.0, z_liftoff, None, min_apex, z_touchdown),
                            [c_x, c_z, min_x, max_x, max_apex]])
        lbg, ubg = self._reach_bounds
        sol = self._reach_solver(x0=guess, p=p, lbx=self._lbx, ubx=self._ubx, lbg=lbg, ubg=ubg)
        if not self._reach_solver.stats()["success"]:
            return None
        x = np.asarray(sol["x"]).ravel()
        x_td, z_apex = (float(np.asarray(v).item()) for v in self._readout(x, p[:len(p) - 5])[:2])
        return x_td if c_x else z_apex

    def reach(self, s0: np.ndarray, z_liftoff: float, min_apex: float, max_apex: float = np.inf,
              z_touchdown: float | None = None, x_range: tuple[float, float] = (0.0, np.inf)) -> Reach | None:
        """The farthest and nearest landing (m ahead of the start) with the apex within
        [min_apex, max_apex] m, and the highest and lowest apex (m) with the landing within
        ``x_range`` m, from the model state s0 (n,) under every constraint of ``solve``
        (module docstring); None if no jump of those is feasible."""
        s0 = self._check_start(s0)
        big = 1e3  # m: no bound (IPOPT takes finite numbers best)
        lo_x, hi_x = x_range[0], min(x_range[1], big)
        top = min(max_apex, big)
        guess = self._first_guess(s0, max(lo_x, 0.2), max(min_apex, z_liftoff + 0.05), z_liftoff)
        args = (s0, z_liftoff, z_touchdown)
        x_max = self._extreme(*args, min_apex, top, lo_x, hi_x, -1.0, 0.0, guess)
        x_min = self._extreme(*args, min_apex, top, lo_x, hi_x, 1.0, 0.0, guess)
        z_max = self._extreme(*args, z_liftoff, big, lo_x, hi_x, 0.0, -1.0, guess)
        z_min = self._extreme(*args, z_liftoff, big, lo_x, hi_x, 0.0, 1.0, guess)
        if None in (x_max, x_min, z_max, z_min):
            return None
        return Reach(x_min, x_max, z_min, z_max)
