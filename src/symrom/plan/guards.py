"""Where a planned jump switches phase: lift-off, apex and touchdown as constraints.

The planning problem asks its guards for constraints on the states at the
phase boundaries, so that another rule (e.g. contact-switching functions
learned from data and saved with the model) replaces this one without touching
the problem. ``HeightGuards`` is the rule the pronk executes:

- lift-off at the end of the planned stance, where the base has risen to the
  lift-off height z_lo (the motion's take-off height: the legs are then still
  within reach) and moves up;
- apex where the base's vertical speed is zero;
- touchdown where the base height has come back to the lift-off level, moving
  down: the flight controller holds the legs at the take-off length, so the feet
  meet the ground when the base is back at that height.

Each method returns ``(expression, lower, upper)`` triples, CasADi SX.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import casadi as ca

Constraint = tuple[ca.SX, float, float]


class Guards(Protocol):
    def liftoff(self, dyn, s: ca.SX, z_lo: ca.SX) -> list[Constraint]:
        """Constraints on the state s at the end of the stance."""

    def apex(self, dyn, s: ca.SX) -> list[Constraint]:
        """Constraints on the state s at the top of the flight."""

    def touchdown(self, dyn, s: ca.SX, z_lo: ca.SX) -> list[Constraint]:
        """Constraints on the state s at touchdown."""


@dataclass(frozen=True)
class HeightGuards:
    """The pronk's guards (module docstring); min_rise_speed m/s: the least upward speed at
    lift-off, so that the feet leave the ground."""

    min_rise_speed: float = 0.3

    def liftoff(self, dyn, s, z_lo):
        return [(dyn.position(s)[1] - z_lo, 0.0, 0.0), (dyn.velocity(s)[1], self.min_rise_speed, ca.inf)]

    def apex(self, dyn, s):
        return [(dyn.velocity(s)[1], 0.0, 0.0)]

    def touchdown(self, dyn, s, z_lo):
        return [(dyn.position(s)[1] - z_lo, 0.0, 0.0), (dyn.velocity(s)[1], -ca.inf, 0.0)]
