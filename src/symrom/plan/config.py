"""The planner's settings (``PlanConfig``), apart from the problem so that what only reads them
(the selection's check of the planner's RK4 step, ``experiments.select.plan_steps``) needs no
CasADi, which only the ``export`` extra installs."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PlanConfig"]


@dataclass(frozen=True)
class PlanConfig:
    """knots: force intervals over the stance (of a one-stance push); substeps: RK4 steps per
    shooting interval; flight_intervals: shooting intervals of the rise and of the fall each;
    mu: friction coefficient; fz_max: largest summed normal force, N; stance_min / stance_max:
    bounds of the stance duration, s (the pronk's pushes last 0.15-0.2 s); t_min / t_max:
    bounds of the rise's and the fall's durations, s; w_x (1/m^2), w_apex (1/m^2), w_effort,
    w_smooth: objective weights; tol: IPOPT's tolerance; max_iter: IPOPT's iteration limit."""

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
