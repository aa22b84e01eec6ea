"""The one protocol every model that can be rolled out implements.

A model (the learned ``HybridModel``, the aSLIP, the Newton baseline, ...)
is a second-order system x'' = a(x, x', drive) in coordinates of its own
(latent xi for the learned model, the CoM position for the CoM baselines),
driven by per-sample inputs logged in the data and held over each sample.
Given a dataset and its jumps it returns a ``RolloutSystem``: the true state
in its coordinates (the start, and the reset targets), the held drive, the
acceleration function, the divergence bound and the map from its state back
to the configuration components it predicts. ``symrom.rollout.integrate``
integrates any such system; ``symrom.evaluate.metrics`` scores it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from symrom.data.dataset import Dataset

# acceleration(drive at one sample {name: (J, ...)}, x (J, d), v (J, d)) -> (J, d)
Acceleration = Callable[[dict[str, np.ndarray], np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class GeneratedCode:
    """A system's own compiled code, for the ``generated`` backend and the compiled LSODA.

    The integrators hand it the drive as they hold it and never look inside:

    integrator: a fixed-step RK4 integrator with the interface of ``RolloutSystem.compiled``;
    rhs: LSODA's right-hand side ``rhs(y (2d,), t, *rhs_args(drive, k)) -> dy/dt (2d,)``;
    rhs_args(drive, k): those extra arguments at sample k of one jump's drive {name: (n, ...)};
    c_rhs(): the address of the same right-hand side as a C function
    ``void f(double t, double *y, double *dy, double *p)`` (compiled on the first call);
    c_params(drive): (n, m) float, the data ``p`` of each sample of one jump's drive.
    """

    integrator: Callable
    rhs: Callable
    rhs_args: Callable[[dict[str, np.ndarray], int], tuple]
    c_rhs: Callable[[], int]
    c_params: Callable[[dict[str, np.ndarray]], np.ndarray]


@dataclass(frozen=True)
class Padded:
    """A system's per-jump arrays stacked as the fixed-step integrators take them, each jump's
    last sample repeated past its end (``symrom.rollout.integrate.pad_edge``): drive {name:
    (J, n_max, ...)}, lens (J,) the jumps' lengths, and states(rows) -> x, v (J, n_max, d), the
    true state at the samples that rows (n_max,) bool marks (the start and the resets: all an
    integrator reads of it; what the other samples hold is unspecified)."""

    states: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    drive: dict[str, np.ndarray]
    lens: np.ndarray


@dataclass
class RolloutSystem:
    """A model set up on J jumps of a dataset, for the integrators.

    x, v: per jump (n_j, d) the true state in the model's coordinates (start and
    reset values); drive: per name, per jump (n_j, ...) inputs held over each
    sample; scale: (J, 2d) the yardstick of |[x, v]|: a rollout has diverged once
    it leaves ``bound`` (``RolloutOptions``) times it; acceleration: see ``Acceleration``; observe(i, X): the model's
    prediction (n, C) of its ``components`` from its path X (n, d) on jump i;
    compiled: optionally, a compiled fixed-step RK4 integrator of this system
    (``symrom.compiled.table_integrator`` gives the learned model's), used by
    ``rk4`` unless another backend is asked for; generated: optionally, a factory of
    the system's own compiled code (``GeneratedCode``), called only when the
    ``generated`` backend or the compiled LSODA is asked for (or by ``auto`` when
    ``has_build()`` says it is compiled already, or the work pays for compiling it);
    padded: optionally, the same stacked (``Padded``), which spares the fixed-step
    integrators the copy and the model the encoding of states they do not read; observe_padded:
    optionally, ``observe`` on all jumps at once, observe_padded(X (J, n_max, d), lens (J,))
    -> per jump (lens[j], C); key: optionally, the identity of the system's dynamics, the same
    for every system of one model (``auto`` counts the NumPy work done on it in a process).
    """

    x: Sequence[np.ndarray]
    v: Sequence[np.ndarray]
    drive: dict[str, Sequence[np.ndarray]]
    scale: np.ndarray
    acceleration: Acceleration
    observe: Callable[[int, np.ndarray], np.ndarray]
    compiled: Callable | None = None
    generated: Callable[[], GeneratedCode] | None = None
    has_build: Callable[[], bool] | None = None
    padded: Padded | None = None
    observe_padded: Callable[[np.ndarray, np.ndarray], list[np.ndarray]] | None = None
    key: str | None = None

    @property
    def n_jumps(self) -> int:
        return len(self.x)


@runtime_checkable
class Rollable(Protocol):
    """What ``rollout`` and ``evaluate`` need of a model.

    components: the configuration components (``symrom.names.Q_NAMES``) it
    predicts, in the order of ``observe``'s columns.
    """

    components: tuple[str, ...]

    def rollout_system(self, ds: Dataset, jumps: np.ndarray) -> RolloutSystem:
        """Set the model up on ``jumps`` of ``ds``; raise ValueError with one clear
        message when the data do not fit the model (phases, robot, inputs)."""
        ...
