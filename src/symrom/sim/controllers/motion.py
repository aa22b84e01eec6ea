"""What a motion plug-in provides: a ``Controller`` per jump and the ``Motion`` that makes it.

A motion's registry entry (``symrom.motions``) names its plug-in as
``"module:attribute"``; ``load_motion`` imports it only here, in the
simulator. Generation (``symrom.sim.generation.runner``, through the episode loop
``symrom.sim.generation.episode.run_episode``) uses nothing else of a motion:

    params = motion.sample_params(rng, robot, variant, dataset_rng)  # a dataclass with max_time (s)
    world = motion.make_world(robot, world_config, params, engine)   # symrom.sim.engines.world.World
    ctrl = motion.make_controller(robot, params, mpc_solver="osqp")
    q0 = ctrl.reset(world)                             # start pose (18,), before world.reset
    watch = motion.watch()                             # sees a certain failure while it runs
    world.reset(q0)
    while not ctrl.done(s := world.state()):
        world.step(ctrl.torque(s))                     # (12,) N m per physics tick
        watch.update(s.contact)                        # on logged samples; True: stop
    motion.check(log, dt, checks)                      # the motion's own checks, reasons
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from symrom.motions import get_motion
from symrom.sim.controllers.flight import FlightWatch, one_main_flight
from symrom.sim.engines.registry import make_world
from symrom.sim.engines.world import RobotState, World, WorldConfig
from symrom.sim.proxy import ProxyWorld

# The QP solvers of a motion's MPC (``make_controller``'s ``mpc_solver``; ``symrom.sim.controllers.mpc``)
QP_SOLVERS = ("osqp", "daqp")


@dataclass(frozen=True)
class PushCommand:
    """A push policy's command for one tick of a push (the pronk's ``PushPolicy``, the froggy's
    ``FroggyPushPolicy``): force (3,) N, the summed ground force on the feet down, and moment
    (3,) N m, its moment (about the CoM for the pronk, about the base for the froggy), both
    world; the legs' torques stand for them. timing: the push's new timing (the motion's
    record: ``pronk.PushTiming``, ``froggy.FroggyPushTiming``) when the policy re-planned it,
    else None (the last one holds)."""

    force: np.ndarray
    moment: np.ndarray
    timing: Any = None


@runtime_checkable
class Controller(Protocol):
    """One jump's controller: the same three methods for every motion."""

    def reset(self, world: World) -> np.ndarray:
        """The start configuration q (18,) of the jump on ``world``, which the runner then
        resets to; a controller may also configure the world here (e.g. hold joints)."""

    def torque(self, state: RobotState) -> np.ndarray:
        """Joint torques (12,) N m for ``state``, called every physics tick."""

    def done(self, state: RobotState) -> bool:
        """Whether the jump is over (settled after landing, or out of time)."""

    def diagnostics(self) -> dict[str, Any]:
        """JSON-ready facts of the run for benchmarks (e.g. MPC solve times, s); not stored."""


class Motion(Protocol):
    """A kind of jump, as its plug-in module exports it."""

    def sample_params(self, rng: np.random.Generator, robot: str, variant: str | None,
                      dataset_rng: np.random.Generator | None = None) -> Any:
        """One jump's parameters: a dataclass (recorded with ``asdict``) with ``max_time`` s.
        variant: one of the motion's registered variants (e.g. ``proxy``, ``randomized``) or None.
        dataset_rng: a generator seeded by the generation seed alone, so it draws the same in
        every jump of a file: for what a dataset's jumps share (the proxy's one robot); None
        draws that per jump too."""

    def make_world(self, robot: str, config: WorldConfig, params: Any, engine: str) -> World:
        """The world of ``engine`` (``symrom.sim.engines.registry.ENGINES``) the jump runs in (e.g. a
        hardware-like proxy of it)."""

    def make_controller(self, robot: str, params: Any, mpc_solver: str = "osqp") -> Controller:
        """A fresh controller for one jump; mpc_solver: the QP solver of its MPC, if it has one
        (``QP_SOLVERS``; ``GenerateConfig.mpc_solver``)."""

    def source(self, params: Any) -> str:
        """The dataset's ``source`` for jumps with ``params``: ``sim`` or ``proxy``."""

    def check(self, log: dict[str, np.ndarray], dt: float, checks: Any) -> list[str]:
        """Reasons the logged jump fails this motion's own checks (beyond ``JumpChecks``)."""

    def watch(self) -> Watcher:
        """A fresh watcher of one attempt (``Watcher``)."""


class Watcher(Protocol):
    """Watches one running attempt for a certain failure of its motion's own check."""

    reason: str  # the check that will fail, once ``update`` said so

    def update(self, contact: np.ndarray) -> bool:
        """Per logged sample, its contact flags (4,): True once the attempt has certainly failed."""


@dataclass(frozen=True)
class PlainMotion:
    """Defaults for a ``Motion`` of one main flight: the nominal world, seen through the
    proxy's motors and sensors when the jump's parameters hold a ``proxy`` configuration
    (``sim.proxy.ProxyWorld``), source ``sim``, the one-flight check
    (``flight.one_main_flight``) and its watcher (``flight.FlightWatch``)."""

    def make_world(self, robot: str, config: WorldConfig, params: Any, engine: str) -> World:
        world = make_world(engine, robot, config)
        proxy = getattr(params, "proxy", None)
        return world if proxy is None else ProxyWorld(world, proxy)

    def source(self, params: Any) -> str:
        return "sim"

    def check(self, log: dict[str, np.ndarray], dt: float, checks: Any) -> list[str]:
        return one_main_flight(log)

    def watch(self) -> Watcher:
        return FlightWatch()


def load_motion(name: str) -> Motion:
    """The plug-in of motion ``name``, imported from its registry entry."""
    module, _, attr = get_motion(name).plugin.partition(":")
    return getattr(importlib.import_module(module), attr)
