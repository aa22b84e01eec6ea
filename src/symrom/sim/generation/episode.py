"""The episode loop: one controller driving one world, the same for every run of a controller.

``run_episode`` resets the world to the start configuration, then per physics tick reads
the state (optionally through a reading model, e.g. sensor noise), stops once the
controller is done, asks it for torques, applies a scheduled push on the base, steps the
world, and on every ``log_every``-th tick (``WorldConfig.log_every``: 500 Hz at 1 kHz
physics) hands the sample to ``on_sample`` and its contact flags to a watcher that may stop
the attempt. Generation (``runner.run_jump``) and the planner's execution
(``symrom.plan.execute``) both run their jumps through it.

The caller owns the world (makes and closes it) and the controller (calls its ``reset``
for the start configuration, which may configure the world, before the loop). Units: s, N.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from symrom.sim.controllers.motion import Controller, Watcher
from symrom.sim.engines.world import RobotState, World

Sample = Callable[[int, RobotState, np.ndarray], None]


@dataclass(frozen=True)
class BasePush:
    """A constant force (3,) N on the base's centre of mass (world) for the ticks whose state's
    time is in [t_start, t_end) s."""

    force: np.ndarray
    t_start: float
    t_end: float


@dataclass(frozen=True)
class EpisodeEnd:
    """How an episode ended: finished (the controller said done), ticks (physics ticks stepped),
    stopped_at (the tick at which the watcher stopped it, else None)."""

    finished: bool
    ticks: int
    stopped_at: int | None = None


def run_episode(world: World, controller: Controller, q0: np.ndarray, max_time: float, *,
                on_sample: Sample | None = None, watch: Watcher | None = None,
                reading: Callable[[RobotState], RobotState] | None = None,
                push: BasePush | None = None) -> EpisodeEnd:
    """Run ``controller`` on ``world`` from configuration q0 (18,) for at most ``max_time`` s.

    Per tick: s = world.state() (passed through ``reading`` if given); stop if
    ``controller.done(s)``; tau = controller.torque(s); the ``push`` if its window holds s.t;
    applied = world.step(tau) (read back on logged ticks only). On a logged tick (every
    ``world.config.log_every``-th, the first included) ``on_sample(tick, s, applied)`` is
    called after the step (the world then holds that tick's contact forces), then
    ``watch.update(s.contact)``; True stops the episode there. The world is not closed.
    """
    cfg = world.config
    every = cfg.log_every
    world.reset(q0)
    ticks = 0
    for tick in range(int(round(max_time * cfg.physics_hz)) + 1):
        s = world.state()
        if reading is not None:
            s = reading(s)
        if controller.done(s):
            return EpisodeEnd(True, ticks)
        tau = controller.torque(s)
        if push is not None and push.t_start <= s.t < push.t_end:
            world.apply_base_force(push.force)
        logged = tick % every == 0
        applied = world.step(tau, report=logged)
        ticks += 1
        if logged:
            if on_sample is not None:
                on_sample(tick, s, applied)
            if watch is not None and watch.update(s.contact):
                return EpisodeEnd(False, ticks, tick)
    return EpisodeEnd(False, ticks)


__all__ = ["BasePush", "EpisodeEnd", "run_episode"]
