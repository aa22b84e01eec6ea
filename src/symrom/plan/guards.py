"""Where a planned jump switches phase: lift-off, apex and touchdown as constraints.

The planning problem asks its guards for constraints on the states at the
phase boundaries, so that another rule (e.g. contact-switching functions
learned from data and saved with the model) replaces this one without touching
the problem. ``HeightGuards`` is the rule the pronk executes:

- lift-off at the end of the planned stance, where the base has risen to the
  lift-off height z_lo (the motion's take-off height: the legs are then still
  within reach) and moves up;
- apex where the base's vertical speed is zero;
- touchdown where the base height has come back to the touchdown level z_td,
  moving down: the pronk's flight controller holds the legs at the take-off
  length, so its feet meet the ground when the base is back at the lift-off
  height (z_td = z_lo); a froggy jump lands nose down, lower than it left
  (z_td from its training data, ``plan.jump``).

``LearnedGuards`` puts the model's own learned switches (``model.guards``) in
their place. Each method returns ``(expression, lower, upper)`` triples, CasADi SX.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import casadi as ca

from symrom.names import FLIGHT_PHASE, STANCE_PHASE

Constraint = tuple[ca.SX, float, float]


class Guards(Protocol):
    def liftoff(self, dyn, s: ca.SX, z_lo: ca.SX, F: ca.SX) -> list[Constraint]:
        """Constraints on the state s at the end of the stance, under the last force F (2,) N."""

    def apex(self, dyn, s: ca.SX) -> list[Constraint]:
        """Constraints on the state s at the top of the flight."""

    def touchdown(self, dyn, s: ca.SX, z_td: ca.SX) -> list[Constraint]:
        """Constraints on the state s at touchdown (z_td: the motion's touchdown height, m)."""


@dataclass(frozen=True)
class HeightGuards:
    """The pronk's guards (module docstring); min_rise_speed m/s: the least upward speed at
    lift-off, so that the feet leave the ground."""

    min_rise_speed: float = 0.3

    def liftoff(self, dyn, s, z_lo, F):
        return [(dyn.position(s)[1] - z_lo, 0.0, 0.0), (dyn.velocity(s)[1], self.min_rise_speed, ca.inf)]

    def apex(self, dyn, s):
        return [(dyn.velocity(s)[1], 0.0, 0.0)]

    def touchdown(self, dyn, s, z_td):
        return [(dyn.position(s)[1] - z_td, 0.0, 0.0), (dyn.velocity(s)[1], -ca.inf, 0.0)]


@dataclass(frozen=True)
class LearnedGuards:
    """The model's own learned switches (``model.guards``: an affine g of z = [xi, dxi, nu]
    that fires at g >= 0), for a ``LearnedDynamics`` planner:

    - lift-off: the ``contact -> flight`` guard (a froggy's ``partial -> flight``) is met
      (g = 0) at the end of the planned push, nu = B F of the last force, the base rising;
    - apex: the vertical speed is zero and the ``flight -> contact`` guard has not fired (g <= 0);
    - touchdown: the ``flight -> contact`` guard is met (g = 0, nu = 0 in flight), falling.

    Their dwells (the least time in the phase before a switch) are not constraints: the
    crouch already keeps the robot in contact longer than any learned dwell, and a pronk's
    flight lasts twice the ``flight`` dwell or more."""

    lift: object  # symrom.model.guards.Guard, the last stance phase -> flight
    land: object  # symrom.model.guards.Guard, flight -> contact
    min_rise_speed: float = 0.3  # m/s, as HeightGuards

    @classmethod
    def of(cls, model, stance: str = STANCE_PHASE, flight: str = FLIGHT_PHASE,
           landing: str = STANCE_PHASE) -> LearnedGuards:
        """The guards of ``model`` (a ``HybridModel``): lift-off ``stance -> flight`` (the push's
        last stance phase), touchdown ``flight -> landing``; ValueError if it lacks either or
        either is a clock (``Guard.clock``)."""
        found = {(g.source, g.target): g for g in getattr(model, "guards", None) or []}
        for pair in ((stance, flight), (flight, landing)):
            if pair not in found:
                raise ValueError(f"the model has no learned {pair[0]} -> {pair[1]} guard (a model trained "
                                 "before guards were learned, or without that transition)")
            if found[pair].clock:
                raise ValueError(f"the model's {pair[0]} -> {pair[1]} guard is a clock ({found[pair].text()}): "
                                 "a plan's lift-off and touchdown need a guard on the state")
        return cls(found[(stance, flight)], found[(flight, landing)])

    @staticmethod
    def _g(guard, dyn, s, nu):
        l = dyn.l
        z = ca.vertcat(s[:l], s[l:], nu)
        return guard.bias + sum(float(w) * z[int(i)] for w, i in zip(guard.weights, guard.indices(l)))

    def liftoff(self, dyn, s, z_lo, F):
        nu = ca.mtimes(ca.DM(dyn.B_of[self.lift.source]), F)
        return [(self._g(self.lift, dyn, s, nu), 0.0, 0.0), (dyn.velocity(s)[1], self.min_rise_speed, ca.inf)]

    def apex(self, dyn, s):
        return [(dyn.velocity(s)[1], 0.0, 0.0), (self._g(self.land, dyn, s, ca.DM.zeros(dyn.l)), -ca.inf, 0.0)]

    def touchdown(self, dyn, s, z_td):
        return [(self._g(self.land, dyn, s, ca.DM.zeros(dyn.l)), 0.0, 0.0), (dyn.velocity(s)[1], -ca.inf, 0.0)]
