"""The rest of the push re-planned from the measured state: a real-time iteration on a QP.

A closed loop (``symrom jump --control mpc``) cannot wait for IPOPT on the whole problem
(``plan.problem``) at 100 Hz. ``Replanner`` re-plans the rest of the push with the same
model, constraints and objective, shrinking its horizon as the push goes on:

- *Variables* y: what is left of the current stance (s) and the durations of the stances
  still to come, of the rise and of the fall (s); the summed ground force on ``knots`` equal
  intervals of each stance left (the current one's spread over what is left of it).
- *Model*: single shooting from the measured state (encoded to the model's state) through the
  stances left (RK4, ``substeps`` per interval), the release, the rise and the fall, as the
  NLP does (its flight bias added to the landing); its
  guards, the base rising through the push, the apex and the friction and torque bounds as the
  NLP's constraints; the objective the NLP's (landing distance, apex, effort, smoothness).
- *One step* (real-time iteration): the constraints linearised and the objective's residuals
  (Gauss-Newton) taken about the last re-plan's solution shifted to now, with a small
  proximal term (a larger one on the forces within a later stance: ``prox_later``); the QP
  (dense, tens of variables) solved by DAQP and its step taken. A QP DAQP cannot solve keeps
  the last schedule.

The first schedule is the NLP's plan; every re-plan warm-starts from the one before.

*The disturbance estimate* (``disturbance_gain`` > 0): an acceleration d of the state's velocity
part that the model lacks (a payload, weak motors). At each re-plan the model, with d, is rolled
from the last measured state under the schedule it was given, and ``disturbance_gain`` of the
velocity it missed per second is added to d; the re-plan's stances and release then carry d
(ds/dt + [0; d]), which is how the last interval of the push and the release, which no re-plan
corrects, get it too. Units: m, s, N; forces scaled by the robot's weight inside the QP.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import daqp
import numpy as np

from symrom.names import GRAVITY
from symrom.plan.problem import JumpPlanner, Plan, _biased, _released, _rk4, force_rows

DISTURBANCE_GAIN = 0.0  # the default disturbance_gain of a ``Replanner``
PREDICT_STEPS = 10  # the estimate's Runge-Kutta steps between two measured states


def check_disturbance_gain(gain: float) -> float:
    """``gain`` as a float, refused unless it lies in [0, 1] (a share of the missed acceleration)."""
    gain = float(gain)
    if not 0.0 <= gain <= 1.0:
        raise ValueError(f"disturbance_gain must lie in [0, 1], got {gain:g}")
    return gain


def _offset(n: int, d):
    """ds/dt's offset (n,) of an acceleration d (n/2,) on the state's velocity part."""
    return ca.vertcat(ca.DM.zeros(n - d.shape[0]), d)


@dataclass
class Schedule:
    """The push as last planned, from its start (s since the push began): the stances left
    from stance ``first`` (an index into the planner's stances) on, each ending at ``ends[i]``
    s, with forces (k_i, 2) N on equal intervals of [start_i, ends[i]); t_rise, t_fall s;
    predicted landing_x m (from the push start) and apex_z m."""

    first: int
    starts: list[float]
    ends: list[float]
    forces: list[np.ndarray]
    t_rise: float
    t_fall: float
    landing_x: float = float("nan")
    apex_z: float = float("nan")

    @property
    def end(self) -> float:
        return self.ends[-1]

    def force_at(self, tau: float) -> np.ndarray:
        """F (2,) N at tau s after the push began (the last interval's beyond it; zero after)."""
        if tau >= self.end:
            return np.zeros(2)
        for a, b, F in zip(self.starts, self.ends, self.forces):
            if tau < b:
                n = len(F)
                k = int((tau - a) / (b - a) * n) if b > a else n - 1
                return F[min(max(k, 0), n - 1)]
        return self.forces[-1][-1]

    def stance_at(self, tau: float) -> int:
        """The planner's stance index at tau s after the push began (the last one after)."""
        for i, b in enumerate(self.ends):
            if tau < b:
                return self.first + i
        return self.first + len(self.ends) - 1


@dataclass
class ReplanStats:
    """Per re-plan: t s since the push began, solve_time_s (wall time: linearisation, QP and
    update), solve_cpu_s (the process's CPU time during it: one core), status (``ok``;
    ``softened``: the guards met as closely as the bounds allow; or why the last schedule was
    kept), landing_x m and apex_z m the new schedule predicts, and the disturbance estimate it
    was made with (the state's velocity part's acceleration; zeros without one)."""

    t: list[float] = field(default_factory=list)
    solve_time_s: list[float] = field(default_factory=list)
    solve_cpu_s: list[float] = field(default_factory=list)
    status: list[str] = field(default_factory=list)
    landing_x: list[float] = field(default_factory=list)
    apex_z: list[float] = field(default_factory=list)
    disturbance: list[list[float]] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"t_s": self.t, "solve_time_s": self.solve_time_s, "solve_cpu_s": self.solve_cpu_s,
                "status": self.status, "landing_x_m": self.landing_x, "apex_z_m": self.apex_z,
                "disturbance": self.disturbance}


class Replanner:
    """Real-time re-planning of the rest of a push for one ``JumpPlanner`` (module docstring).

    ``begin(plan, ...)`` takes the NLP's plan and the targets; ``step(s, tau)`` re-plans from
    the model state s (n,) measured tau s after the push began and returns the ``Schedule``.
    prox: the proximal weight on each step (per s^2 on durations, per (m g)^2 on forces);
    prox_later: the weight on the forces of a re-plan made within a stance after the first (a
    froggy's rear-only part, 2-4 re-plans long: nothing later takes an overreaction back), chosen
    on simulated froggy jumps; min_left: the least time left in the current stance, s;
    disturbance_gain: how much of each interval's unexplained acceleration the disturbance
    estimate takes up (0: none; default ``DISTURBANCE_GAIN``; module docstring)."""

    def __init__(self, nlp: JumpPlanner, prox: float = 0.03, prox_time: float = 0.03, prox_later: float = 0.1,
                 min_left: float = 0.004, disturbance_gain: float | None = None):
        self.nlp, self.prox, self.prox_time, self.min_left = nlp, float(prox), float(prox_time), float(min_left)
        self.prox_later = float(prox_later)
        self.disturbance_gain = check_disturbance_gain(DISTURBANCE_GAIN if disturbance_gain is None
                                                       else disturbance_gain)
        self._nv = nlp.dyn.n_state // 2  # the state's velocity part: its second half, in every PlanDynamics
        self.disturbance = np.zeros(self._nv)
        self._last: tuple[np.ndarray, float] | None = None  # the last measured state and its time
        self._predictors: dict[str, ca.Function] = {}  # per stance phase, built at its first estimate
        self._fns: dict[int, ca.Function] = {}
        self._bounds: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._began: dict[int, float] = {}  # when each stance began, s since the push began
        self._stats = ReplanStats()
        self.schedule: Schedule | None = None
        for first in range(len(nlp.stances)):  # built once, ahead of the first re-plan
            self._function(first)

    # ----------------------------------------------------------------- the QP's pieces
    def _function(self, first: int) -> ca.Function:
        """(y, p) -> residuals r, dr/dy, constraints c, dc/dy, lower and upper bounds of c, for
        the stances from ``first`` on; p = [s (n), target x, apex, w_apex, min_apex, z_lo, z_td,
        disturbance (n/2)]."""
        if first in self._fns:
            return self._fns[first]
        nlp = self.nlp
        dyn, cfg, stances = nlp.dyn, nlp.config, nlp.stances[first:]
        n, K, M = dyn.n_state, cfg.flight_intervals, cfg.substeps
        P_st = len(stances)
        N = sum(st.knots for st in stances)
        w = nlp.mass * GRAVITY
        y = ca.SX.sym("y", P_st + 2 + 2 * N)
        s0 = ca.SX.sym("s0", n)
        target_x, apex_ref, w_apex, min_apex, z_lo, z_td = (ca.SX.sym(k) for k in
                                                            ("tx", "apex", "w_apex", "min_apex", "z_lo", "z_td"))
        d = ca.SX.sym("d", self._nv)  # the disturbance estimate, an acceleration of the state's velocity part
        p = ca.vertcat(s0, target_x, apex_ref, w_apex, min_apex, z_lo, z_td, d)
        off = _offset(n, d)
        T = y[:P_st + 2]
        F = ca.reshape(y[P_st + 2:] * w, 2, N)  # forces in units of the weight inside y
        c, lo, hi = [], [], []

        def add(constraints):
            for e, a, b in constraints:
                c.append(e)
                lo.append(a)
                hi.append(b)

        s, col = s0, 0
        for p_i, st in enumerate(stances):
            h = T[p_i] / (st.knots * M)
            tmap = nlp.torque_maps.get(st.phase)
            for _ in range(st.knots):
                Fk = F[:, col]
                s = _rk4(lambda v, Fk=Fk, ph=st.phase: dyn.stance(v, Fk, ph) + off, s, h, M)
                add([(dyn.velocity(s)[1], 0.0, ca.inf)])
                add(force_rows(Fk, cfg.mu, tmap))
                col += 1
        s = _released(dyn, s, nlp.release, stances[-1].phase, M, off)
        bias = _biased(dyn, s, nlp.bias)
        add(nlp.guards.liftoff(dyn, s, z_lo, F[:, N - 1]))
        for phase, dur in ((0, T[P_st]), (1, T[P_st + 1])):
            s = _rk4(dyn.flight, s, dur / (K * M), K * M)
            if phase == 0:
                apex_state = s
                add(nlp.guards.apex(dyn, s))
                add([(dyn.position(s)[1] - min_apex, 0.0, ca.inf)])
        add(nlp.guards.touchdown(dyn, s, z_td))
        x_td = dyn.position(s)[0] + bias
        z_apex = dyn.position(apex_state)[1]
        Fn = (F - ca.repmat(ca.DM([0.0, w]), 1, N)) / w
        smooth, first_k = [], 0
        for st in stances:
            if st.knots > 1:
                smooth.append(ca.vec(ca.diff(F[:, first_k:first_k + st.knots], 1, 1) / w))
            first_k += st.knots
        r = ca.vertcat(np.sqrt(cfg.w_x) * (x_td - target_x), ca.sqrt(w_apex) * (z_apex - apex_ref),
                       np.sqrt(cfg.w_effort / N) * ca.vec(Fn), np.sqrt(cfg.w_smooth) * ca.vertcat(*smooth))
        cc = ca.vertcat(*c)
        fn = ca.Function(f"replan_{first}", [y, p], [r, ca.jacobian(r, y), cc, ca.jacobian(cc, y), x_td, z_apex])
        self._fns[first] = fn
        self._bounds[first] = (np.array(lo, float), np.array(hi, float))
        return fn

    # ----------------------------------------------------------------- use
    def begin(self, plan: Plan, target_x: float, x0: float, z_liftoff: float, z_touchdown: float,
              apex: float | None, min_apex: float | None) -> Schedule:
        """Start from the NLP's ``plan`` (made at the push's start): landing ``target_x`` m ahead
        of x0 (the model's x at the push start, m), lift-off at ``z_liftoff`` m, touchdown at
        ``z_touchdown`` m, the apex aimed at ``apex`` m or held above ``min_apex`` m."""
        cfg = self.nlp.config
        self._p_tail = np.array([x0 + target_x, apex if apex is not None else min_apex,
                                 cfg.w_apex if apex is not None else 0.0,
                                 min_apex if apex is None else z_liftoff, z_liftoff, z_touchdown])
        self._x0 = float(x0)
        starts, ends, forces, t, first = [], [], [], 0.0, 0
        for st, d in zip(plan.stances, plan.durations):
            starts.append(t)
            ends.append(t + d)
            forces.append(plan.forces[first:first + st.knots].copy())
            t, first = t + d, first + st.knots
        self.schedule = Schedule(0, starts, ends, forces, plan.t_rise, plan.t_fall, plan.landing_x, plan.apex_z)
        self._stats = ReplanStats()
        self._began = {0: 0.0}
        self.disturbance = np.zeros(self._nv)
        self._last = (np.asarray(plan.states[0], float), 0.0) if plan.states is not None else None
        return self.schedule

    @property
    def stats(self) -> ReplanStats:
        return self._stats

    def _warm(self, tau: float, first: int) -> np.ndarray:
        """y of the last schedule seen from tau s after the push began, stances from ``first`` on:
        its forces sampled at the middles of the new intervals."""
        sch, stances = self.schedule, self.nlp.stances
        w = self.nlp.mass * GRAVITY
        T, F = [], []
        for i, st in enumerate(stances[first:]):
            j = first + i - sch.first
            a = max(sch.starts[j], tau) if i == 0 else sch.starts[j]
            b = sch.ends[j]
            if i == 0:
                b = max(b, a + self.min_left)
            T.append(b - a)
            mids = a + (np.arange(st.knots) + 0.5) * (b - a) / st.knots
            # past the stance's old end (it was lengthened to min_left): its last force
            F.extend(sch.force_at(m) if m < sch.ends[j] else sch.forces[j][-1] for m in mids)
        T += [sch.t_rise, sch.t_fall]
        return np.concatenate([T, np.asarray(F, float).ravel() / w])

    def _bounds_y(self, tau: float, first: int) -> tuple[np.ndarray, np.ndarray]:
        cfg, stances = self.nlp.config, self.nlp.stances[first:]
        w = self.nlp.mass * GRAVITY
        since = tau - self._began[first]  # time spent in the current stance
        lo = [max(stances[0].t_min - since, self.min_left)] + [st.t_min for st in stances[1:]] + [cfg.t_min] * 2
        hi = [max(stances[0].t_max - since, self.min_left)] + [st.t_max for st in stances[1:]] + [cfg.t_max] * 2
        N = sum(st.knots for st in stances)
        lo = np.concatenate([lo, np.tile([-cfg.mu * cfg.fz_max / w, 0.0], N)])
        hi = np.concatenate([hi, np.tile([cfg.mu * cfg.fz_max / w, cfg.fz_max / w], N)])
        return lo, hi

    def step(self, s: np.ndarray, tau: float) -> Schedule:
        """Re-plan the rest of the push from the model state s (n,) measured ``tau`` s after the
        push began (module docstring); returns the new ``Schedule`` (the last one if the QP
        failed), recording the solve's wall time."""
        t0, c0 = time.perf_counter(), time.process_time()
        s = np.asarray(s, float)
        self._estimate(s, tau)
        sch = self.schedule
        first = sch.stance_at(tau)
        if first not in self._began:  # a stance began at the end of the one before
            self._began[first] = sch.ends[first - 1 - sch.first]
        fn = self._function(first)
        y0 = self._warm(tau, first)
        lo_y, hi_y = self._bounds_y(tau, first)
        y0 = np.clip(y0, lo_y, hi_y)
        p = np.concatenate([s, self._p_tail, self.disturbance])
        r, Jr, c, Jc, _, _ = (np.asarray(v) for v in fn(y0, p))
        r, c = r.ravel(), c.ravel()
        lo_c, hi_c = self._bounds[first]
        ny = y0.size
        n_t = len(self.nlp.stances) - first + 2  # durations come first in y
        prox = self.prox if first == 0 else self.prox_later
        H = Jr.T @ Jr + np.diag(np.r_[np.full(n_t, self.prox_time), np.full(ny - n_t, prox)])
        f = Jr.T @ r
        bu = np.concatenate([hi_y - y0, hi_c - c])
        bl = np.concatenate([lo_y - y0, lo_c - c])
        sense = np.zeros(bu.size, dtype=np.int32)
        sense[ny:][lo_c == hi_c] = 5
        d, _, flag, _ = daqp.solve(H, f, Jc, bu, bl, sense)
        status = "ok"
        if flag < 1 or not np.all(np.isfinite(d)):
            # soften the guards and the apex: a step that meets the bounds and comes closest
            soft = sense.copy()
            soft[ny:] = 8
            d, _, flag, _ = daqp.solve(H, f, Jc, bu, bl, soft)
            status = "softened"
        if flag < 1 or not np.all(np.isfinite(d)):
            status = f"kept the last schedule (DAQP exit flag {flag})"
        else:
            y = np.clip(y0 + d, lo_y, hi_y)
            self.schedule = self._schedule(y, tau, first, fn, p)
        elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0
        st = self._stats
        st.t.append(float(tau))
        st.solve_time_s.append(elapsed)
        st.solve_cpu_s.append(cpu)
        st.status.append(status)
        st.landing_x.append(self.schedule.landing_x)
        st.apex_z.append(self.schedule.apex_z)
        st.disturbance.append(self.disturbance.tolist())
        return self.schedule

    def _estimate(self, s: np.ndarray, tau: float) -> None:
        """Update the disturbance estimate from the state s measured at tau: the model, with the
        estimate so far, rolled from the last measured state under the schedule it was given
        (``PREDICT_STEPS`` steps), and ``disturbance_gain`` of the velocity it missed per second
        taken up. An interval across a change of stance is left out (its phases' laws differ)."""
        last, self._last = self._last, (s.copy(), float(tau))
        if self.disturbance_gain == 0.0 or last is None or not tau > last[1]:
            return
        s_prev, t_prev = last
        sch = self.schedule
        stance = sch.stance_at(t_prev)
        if sch.stance_at(np.nextafter(tau, t_prev)) != stance:
            return
        h = (tau - t_prev) / PREDICT_STEPS
        forces = np.stack([sch.force_at(t_prev + (k + 0.5) * h) for k in range(PREDICT_STEPS)], axis=1)
        pred = self._predictor(self.nlp.stances[stance].phase)(s_prev, forces, self.disturbance, h)
        missed = (s[self._nv:] - np.asarray(pred)[self._nv:, -1]) / (tau - t_prev)
        if np.all(np.isfinite(missed)):
            self.disturbance = self.disturbance + self.disturbance_gain * missed

    def _predictor(self, phase: str) -> ca.Function:
        """(s, F (2, PREDICT_STEPS), d, h) -> the states after each of ``PREDICT_STEPS`` Runge-Kutta
        steps of stance ``phase`` with the estimate d, one force per step, in one call; built once
        (only a loop with a disturbance estimate needs it)."""
        if phase not in self._predictors:
            n = self.nlp.dyn.n_state
            sv, Fv, dv, hv = ca.SX.sym("s", n), ca.SX.sym("F", 2), ca.SX.sym("d", self._nv), ca.SX.sym("h")
            step = _rk4(lambda v: self.nlp.dyn.stance(v, Fv, phase) + _offset(n, dv), sv, hv, 1)
            self._predictors[phase] = ca.Function("predict", [sv, Fv, dv, hv], [step]).mapaccum(PREDICT_STEPS)
        return self._predictors[phase]

    def _schedule(self, y: np.ndarray, tau: float, first: int, fn: ca.Function, p: np.ndarray) -> Schedule:
        stances = self.nlp.stances[first:]
        w = self.nlp.mass * GRAVITY
        P_st = len(stances)
        starts, ends, forces = [], [], []
        t, k = tau, P_st + 2
        for i, st in enumerate(stances):
            a = tau if i == 0 else t
            b = a + float(y[i])
            starts.append(a)
            ends.append(b)
            forces.append(y[k:k + 2 * st.knots].reshape(st.knots, 2) * w)
            t, k = b, k + 2 * st.knots
        x_td, z_apex = (float(np.asarray(v).item()) for v in fn(y, p)[4:6])
        return Schedule(first, starts, ends, forces, float(y[P_st]), float(y[P_st + 1]), x_td - self._x0, z_apex)


__all__ = ["DISTURBANCE_GAIN", "ReplanStats", "Replanner", "Schedule", "check_disturbance_gain"]
