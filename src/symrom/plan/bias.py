"""What a planner's flight misses of the base's forward travel, measured on the training jumps.

The base does not fly as the centre of mass does. In a pronk's flight the legs swing forward to
their landing posture, the trunk moves back against them, and the base's forward speed dips
before it recovers; the faster the jump, the further ahead the feet are placed and the larger
the dip. A flight that carries the base at a constant forward speed (a point mass, or a learned
model whose latents read the base's x and z) over-predicts the travel of fast jumps. On 40
MuJoCo Go1 pronks the learned flight's error (0.52 cm rms) is a line in the lift-off velocity to
within 0.13 cm rms (1.5 cm longer at rest, 2.6 cm shorter per m/s forward), and a closed loop
that plans with that flight lands on the line: short of long targets, past short ones.

``fit_flight_bias`` rolls the planner's own flight (``PlanDynamics.flight``) out from each
training jump's lift-off (``data.envelope``'s ``liftoffs``: the flight's first row) until the
base comes down to the height the planner's touchdown guard uses, and fits the measured travel
minus the predicted one as a line in the lift-off velocity (vx, vz) the planner's state reads
(least squares). The planner adds that line (``problem.FlightBias``) to the landing its flight
predicts. Units: m, s.
"""

from __future__ import annotations

from collections.abc import Mapping

import casadi as ca
import numpy as np

from symrom.names import N_Q
from symrom.plan.dynamics import PlanDynamics
from symrom.plan.problem import FlightBias, _rk4

LEAST_JUMPS = 6  # a line of three coefficients on fewer landed flights is not measured but fitted
STEP = 1e-3  # s: the flight's integration step (the crossing is interpolated within it)
LONGEST = 2.0  # s: a flight that has not come down by then is left out
CHUNK = 200  # steps rolled out per call


def _liftoffs(liftoffs: Mapping, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q (n, 18), dq (n, 18), travel (n,)) of ``liftoffs``, checked; errors name ``where``."""
    out = []
    for key, shape, said in (("q", (N_Q,), "(n, 18)"), ("dq", (N_Q,), "(n, 18)"), ("travel_x_m", (), "(n,)")):
        try:
            a = np.asarray(liftoffs[key], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"{where}.{key}: {'missing' if isinstance(e, KeyError) else e}") from None
        if a.ndim != 1 + len(shape) or a.shape[1:] != shape or not np.isfinite(a).all():
            raise ValueError(f"{where}.{key}: expected finite numbers of shape {said}, got shape {a.shape}")
        out.append(a)
    if not out[0].shape[0] == out[1].shape[0] == out[2].shape[0]:
        raise ValueError(f"{where}: q, dq and travel_x_m hold {out[0].shape[0]}, {out[1].shape[0]} and "
                         f"{out[2].shape[0]} jumps")
    return out[0], out[1], out[2]


class FlightTravel:
    """The base's forward travel the flight of a planner's model predicts (built once per model)."""

    def __init__(self, dyn: PlanDynamics):
        s = ca.SX.sym("s", dyn.n_state)
        step = ca.Function("flight_step", [s], [_rk4(dyn.flight, s, STEP, 1)])
        self._chunk = step.mapaccum(CHUNK)  # CHUNK steps in one call: (n, CHUNK) states
        read = ca.Function("read", [s], [ca.vertcat(dyn.position(s), dyn.velocity(s))])
        self._velocity = ca.Function("velocity", [s], [dyn.velocity(s)])
        self._read = read.map(CHUNK + 1)  # x, z, vx, vz of a chunk's states and the one before

    def velocity(self, s0: np.ndarray) -> np.ndarray:
        """(vx, vz) m/s of the state s0 (n,)."""
        return np.asarray(self._velocity(s0)).ravel()

    def __call__(self, s0: np.ndarray, z_touchdown: float) -> float | None:
        """The travel (m) from lift-off state s0 (n,) until the base comes down through
        ``z_touchdown`` m (interpolated within a step); None if it does not within ``LONGEST`` s."""
        cur = ca.DM(s0)
        x0 = None
        for _ in range(int(np.ceil(LONGEST / (STEP * CHUNK)))):
            states = self._chunk(cur)
            x, z, _, vz = np.asarray(self._read(ca.horzcat(cur, states)))
            if x0 is None:
                x0 = x[0]
            if not np.isfinite(z).all():
                return None
            down = np.flatnonzero((vz[1:] < 0) & (z[1:] <= z_touchdown) & (z[:-1] > z_touchdown))
            if down.size:
                k = down[0]
                return float(x[k] + (x[k + 1] - x[k]) * (z[k] - z_touchdown) / (z[k] - z[k + 1]) - x0)
            cur = states[:, -1]
        return None


def fit_flight_bias(dyn: PlanDynamics, liftoffs: Mapping, z_touchdown: float,
                    where: str = "liftoffs") -> FlightBias | None:
    """The line (``FlightBias``) the travel of the jumps in ``liftoffs`` ({"q": (n, 18),
    "dq": (n, 18), "travel_x_m": (n,)}, ``data.envelope``) lies on past what the flight of ``dyn``
    predicts from their lift-offs down to ``z_touchdown`` m (module docstring); None if fewer than
    ``LEAST_JUMPS`` of their flights come down. Malformed ``liftoffs`` are refused naming
    ``where``."""
    q, dq, travel = _liftoffs(liftoffs, where)
    flight = FlightTravel(dyn)
    rows, err = [], []
    for qi, dqi, t in zip(q, dq, travel):
        s0 = np.asarray(dyn.initial_state(qi, dqi), dtype=float)
        pred = flight(s0, z_touchdown)
        if pred is not None:
            rows.append([1.0, *flight.velocity(s0)])
            err.append(t - pred)
    if len(rows) < LEAST_JUMPS:
        return None
    A, e = np.asarray(rows), np.asarray(err)
    c, *_ = np.linalg.lstsq(A, e, rcond=None)
    rms = (float(np.sqrt(np.mean(e ** 2))), float(np.sqrt(np.mean((e - A @ c) ** 2))))
    return FlightBias(float(c[0]), (float(c[1]), float(c[2])), jumps=len(rows), rms_m=rms)


__all__ = ["LEAST_JUMPS", "FlightTravel", "fit_flight_bias"]
