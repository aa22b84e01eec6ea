"""Whether a model can be acted on, beyond how well it rolls out along logged jumps.

A model that scores well on logged rollouts may still be useless to a planner
or a controller. Two checks say why (the validation selection applies them to
every candidate; docs/design.md, "Model selection"):

- **Integrator** (``integrator_check``): each phase's dynamics linearised at
  states of the phase's rows (``STATES`` of them, evenly spaced, and the
  operating point) give its modes lambda; one classical Runge-Kutta step of h
  maps a mode by R(h lambda) = 1 + z + z^2/2 + z^3/6 + z^4/24, the flow by
  exp(h lambda). A step carries the phase when, for every mode,
  |R(h lambda) - exp(h lambda)| <= ``STEP_TOLERANCE`` max(1, |exp(h lambda)|):
  one step moves each mode as the model does, to a tenth of the state. The
  steps are the caller's: a planner's (its shooting intervals over a stance
  and a flight) and a rollout's (the data's sample period over its substeps).
  A stiff mode (a contact at -207 /s) passes at a rollout's 1 ms and fails at
  a planner's 30 ms, where one step amplifies it 36-fold.
- **Physics** (``physics_check``): the model's decoded base acceleration
  (x and z, W_d ddxi at the logged states, inputs and phases) against the
  data's, per phase and split (its mean over the phase's rows). In flight the
  base falls at the data's acceleration: the z means within ``FLIGHT_SHARE``
  (5 %) of the data's, plus the noise below (on a robot's data the flights fall
  alike and it is small; on data whose flights differ, it is what they differ
  by). In every phase the means differ by no more than the
  noise allows: ``NOISE_SE`` standard errors of the data's mean, the error
  taken between the phase's stays (the jumps differ; the samples of one stay
  do not make independent draws): the spread of the stay means over the train
  and val stays together, over the root of the split's stays (a split of one
  val jump still has its noise), plus ``FLIGHT_SHARE`` of the data's flight
  acceleration (what the flight test allows; without flight rows, of g).
  A model that trades the momentum balance for rollout accuracy (a flight that
  falls upward, a push without its force) is caught here whatever its scores.
  Nor does the law read what cannot move the base (``MOVES``): on flat ground,
  with the wrench the input holds, neither where the robot stands sideways nor
  how fast it drifts sideways (the whole robot moved 5 cm along world y, the
  base set moving 0.1 m/s along it), and in flight, where nothing but gravity
  acts on the robot, not how fast the base goes forward or up (0.1 m/s added).
  Each may change no phase's decoded base acceleration (its mean absolute change
  over the phase's rows) by more than the same allowance. The data's jumps hardly
  move sideways, so a law that reads it has fitted noise: a Go1 flight selected
  on MuJoCo data read the lateral position and speed (-1.55e4 m/s^2 per m and
  2.6e3 per m/s), and its closed loop with a payload landed 21 cm off (1.4 cm
  without those two terms); the next candidate damped the flight's forward speed
  (-8.2 /s) and its jumps landed backwards. The forward position is not moved:
  every jump of a dataset starts at the same place, so there it also tells how
  far the push has gone and every law of the paper's formulation reads it; the
  selection keeps it out of its candidates instead (``SymbolicROM.invariant``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from symrom.data.dataset import Dataset, jump_bounds
from symrom.names import BASE_POS, FLIGHT_PHASE, GRAVITY  # GRAVITY: the allowance's scale without flight rows

STEP_TOLERANCE = 0.1  # largest |R(h lambda) - exp(h lambda)| / max(1, |exp(h lambda)|) of a carried mode
STATES = 32  # states per phase where the modes are taken (evenly spaced over its rows)
FLIGHT_SHARE = 0.05  # the flight's z acceleration within this share of the data's
NOISE_SE = 3.0  # standard errors of the data's phase mean a model's mean may differ by (beyond FLIGHT_SHARE)
AXES = {"x": BASE_POS.start, "z": BASE_POS.start + 2}  # decoded base axes checked: index into q


@dataclass(frozen=True)
class Move:
    """A change of the logged states the law of motion must not notice (module docstring):
    ``amount`` (m or m/s) added to column ``column`` of ``q`` or ``dq`` (``array``), in every
    phase or in flight only; ``what`` says the change (``{}`` the amount), ``reads`` what a law that
    notices it reads."""

    kind: str
    array: str
    column: int
    amount: float
    flight_only: bool
    what: str
    reads: str


MOVES = (
    Move("sideways", "q", BASE_POS.start + 1, 0.05, False, "moved {:g} m sideways", "where the robot stands"),
    Move("sideways speed", "dq", BASE_POS.start + 1, 0.1, False, "drifting {:g} m/s sideways",
         "how fast it drifts sideways"),
    Move("forward speed", "dq", BASE_POS.start, 0.1, True, "{:g} m/s faster forward",
         "how fast the base goes in flight"),
    Move("vertical speed", "dq", BASE_POS.start + 2, 0.1, True, "{:g} m/s faster upward",
         "how fast the base goes in flight"),
)


def rk4_map(z: np.ndarray) -> np.ndarray:
    """R(z) (complex, any shape): one classical Runge-Kutta step's factor on a linear mode, z = h lambda."""
    return 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24


@dataclass(frozen=True)
class StepCheck:
    """One phase against one integrator step: integrator (``planner``, ``rollout``); step_s,
    s; eigenvalue: the mode worst carried (1/s); error: its |R(h lambda) - exp(h lambda)|
    / max(1, |exp(h lambda)|); carried: error <= ``STEP_TOLERANCE``."""

    phase: str
    integrator: str
    step_s: float
    eigenvalue: complex
    error: float
    carried: bool

    def text(self) -> str:
        z = self.eigenvalue
        mode = f"{z.real:.3g}{z.imag:+.3g}j" if abs(z.imag) > 1e-9 else f"{z.real:.3g}"
        return (f"{self.phase}: the {self.integrator}'s RK4 step of {self.step_s * 1e3:.3g} ms "
                f"{'carries' if self.carried else 'cannot carry'} mode {mode} /s (step error {self.error:.2g})")

    def to_dict(self) -> dict:
        return {"phase": self.phase, "integrator": self.integrator, "step_s": self.step_s,
                "eigenvalue": [float(self.eigenvalue.real), float(self.eigenvalue.imag)],
                "error": float(self.error), "carried": self.carried}


def phase_modes(model, ds: Dataset, rows: np.ndarray, phase: str, states: int = STATES) -> np.ndarray:
    """Eigenvalues (M,) complex (1/s) of ``phase``'s dynamics linearised at ``states`` of its
    ``rows`` (N,) bool (evenly spaced) and at its operating point."""
    k = model.phase_names.index(phase)
    idx = np.flatnonzero(rows & (model.phase_index(ds) == k)) if rows.any() else np.zeros(0, int)
    idx = idx[np.linspace(0, idx.size - 1, min(states, idx.size)).round().astype(int)] if idx.size else idx
    ae, l = model.autoencoder, model.latent_dim
    xi, dxi, nu = ae.encode(ds.q[idx]), ae.encode_derivative(ds.dq[idx]), ae.encode_input(ds.u[idx])
    info = model.phase_info.get(phase)
    if info is not None and info.operating_point is not None:
        op = np.asarray(info.operating_point, dtype=float)
        xi, dxi, nu = np.r_[xi, op[None, :l]], np.r_[dxi, op[None, l:2 * l]], np.r_[nu, op[None, 2 * l:]]
    if not len(xi):
        return np.zeros(0, complex)
    J = model.library.jacobian(xi, dxi, nu)  # (M, p, 2l)
    A = np.zeros((len(xi), 2 * l, 2 * l))
    A[:, :l, l:] = np.eye(l)
    A[:, l:] = np.einsum("pj,mpd->mjd", model.Xi[k], J)
    with np.errstate(all="ignore"):
        return np.linalg.eigvals(A).reshape(-1)


def integrator_check(model, ds: Dataset, rows: np.ndarray, steps: dict[str, dict[str, float]],
                     tolerance: float = STEP_TOLERANCE) -> list[StepCheck]:
    """Per phase of ``steps`` ({phase: {integrator: step s}}) trained in the model, whether each
    step carries the phase's modes at the states of ``rows`` (N,) bool (module docstring)."""
    out = []
    for phase, by in steps.items():
        if phase not in model.trained_phases():
            continue
        lam = phase_modes(model, ds, rows, phase)
        for who, h in by.items():
            if not lam.size:
                continue
            z = h * lam
            with np.errstate(all="ignore"):
                exact = np.exp(np.minimum(z.real, 700.0)) * np.exp(1j * z.imag)
                err = np.abs(rk4_map(z) - exact) / np.maximum(1.0, np.abs(exact))
            err = np.where(np.isfinite(err), err, np.inf)
            i = int(np.argmax(err))
            out.append(StepCheck(phase, who, float(h), complex(lam[i]), float(err[i]), bool(err[i] <= tolerance)))
    return out


@dataclass(frozen=True)
class AccelerationCheck:
    """The decoded base acceleration of one phase, axis and split: kind (``flight``: z within
    ``FLIGHT_SHARE`` of the data's and the noise; ``momentum``: within the noise; a ``Move``'s
    kind: model the mean absolute change it makes, data 0); data and model: the mean over the
    rows, m/s^2; allowed: the largest |model - data| that passes; ok;
    rows, stays: how many rows and stays the mean is over."""

    kind: str
    phase: str
    split: str
    axis: str
    data: float
    model: float
    allowed: float
    ok: bool
    rows: int
    stays: int

    def text(self) -> str:
        move = next((mv for mv in MOVES if mv.kind == self.kind), None)
        if move is not None:
            return (f"{self.phase} ({self.split} rows): {move.what.format(move.amount)}, the base's acceleration in "
                    f"{self.axis} changes by {self.model:.3g} m/s^2 (allowed {self.allowed:.2g}): the law reads "
                    f"{move.reads}")
        what = "falls" if self.kind == "flight" else "accelerates"
        return (f"{self.phase} ({self.split} rows): the base {what} at {self.model:+.3g} m/s^2 in {self.axis} "
                f"where the data {'do' if self.ok else 'do not'} allow it ({self.data:+.3g} +- {self.allowed:.2g})")

    def to_dict(self) -> dict:
        return {"kind": self.kind, "phase": self.phase, "split": self.split, "axis": self.axis,
                "data": float(self.data), "model": float(self.model), "allowed": float(self.allowed),
                "ok": self.ok, "rows": self.rows, "stays": self.stays}


def _stays(phase: np.ndarray, jump: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """A stay number (N,) for every row of ``sel``: contiguous runs of one phase within a jump."""
    key = np.full(phase.shape[0], -1)
    n = 0
    for a, b in jump_bounds(jump):
        r = np.flatnonzero(sel[a:b]) + a
        if not r.size:
            continue
        cut = np.flatnonzero((np.diff(r) != 1) | (np.diff(phase[r]) != 0)) + 1
        for part in np.split(r, cut):
            key[part] = n
            n += 1
    return key


def _stay_spread(data: np.ndarray, ds: Dataset, rows: np.ndarray) -> np.ndarray:
    """(P, A): per phase and axis, the standard deviation of the data's stay means (``data``
    (N, A)) over every stay of ``rows`` (N,) bool, all splits together (one spread for the
    split's means, whatever stays a split has); 0 for a phase with fewer than two stays."""
    out = np.zeros((len(ds.phase_names), data.shape[1]))
    key = _stays(ds.phase, ds.jump, rows)
    for k in range(len(ds.phase_names)):
        sel = rows & (ds.phase == k)
        if not sel.any():
            continue
        _, which = np.unique(key[sel], return_inverse=True)
        if which.max() < 1:
            continue
        count = np.bincount(which)
        for a in range(data.shape[1]):
            out[k, a] = float((np.bincount(which, weights=data[sel, a]) / count).std(ddof=1))
    return out


def decoded_acceleration(model, ds: Dataset, rows: np.ndarray, columns: list[int] | None = None) -> np.ndarray:
    """The model's decoded acceleration W_d ddxi (n, 18) (or its ``columns`` of q) at the logged
    states, inputs and phases of ``rows`` (N,) bool."""
    ae = model.autoencoder
    W_d = ae.W_d if columns is None else ae.W_d[columns]
    idx = np.flatnonzero(rows)
    phase = model.phase_index(ds, rows)
    out = np.zeros((idx.size, W_d.shape[0]))
    for k in np.unique(phase):
        r = idx[phase == k]
        theta = model.library.transform(ae.encode(ds.q[r]), ae.encode_derivative(ds.dq[r]), ae.encode_input(ds.u[r]))
        out[phase == k] = theta @ (model.Xi[k] @ W_d.T)
    return out


def physics_check(model, ds: Dataset, splits: tuple[str, ...] = ("train", "val"),
                  share: float = FLIGHT_SHARE, noise_se: float = NOISE_SE) -> list[AccelerationCheck]:
    """The model's decoded base accelerations (x, z) against the data's, per trained phase and
    split (module docstring)."""
    out = []
    flight = ds.phase_names.index(FLIGHT_PHASE) if FLIGHT_PHASE in ds.phase_names else None
    every = np.zeros(ds.n_samples, bool)
    for split in splits:
        every |= ds.rows_of(split)
    pred = np.full((ds.n_samples, len(AXES)), np.nan)
    moved = {mv.kind: np.full((ds.n_samples, len(AXES)), np.nan) for mv in MOVES}
    if every.any():
        pred[every] = decoded_acceleration(model, ds, every, list(AXES.values()))
        in_flight = every & (ds.phase == flight) if flight is not None else np.zeros(ds.n_samples, bool)
        for mv in MOVES:
            at = in_flight if mv.flight_only else every
            if not at.any():
                continue
            arr = getattr(ds, mv.array).copy()
            arr[:, mv.column] += mv.amount
            moved[mv.kind][at] = np.abs(decoded_acceleration(model, replace(ds, **{mv.array: arr}), at,
                                                             list(AXES.values())) - pred[at])
    data = ds.ddq[:, list(AXES.values())]
    spread = _stay_spread(data, ds, every)
    for split in splits:
        rows = ds.rows_of(split)
        if not rows.any():
            continue
        key = _stays(ds.phase, ds.jump, rows)
        fl = rows & (ds.phase == flight) if flight is not None else np.zeros(ds.n_samples, bool)
        scale = abs(float(data[fl, 1].mean())) if fl.any() else GRAVITY
        for k, name in enumerate(ds.phase_names):
            if name not in model.trained_phases():
                continue
            sel = rows & (ds.phase == k)
            if not sel.any():
                continue
            n_stays = np.unique(key[sel]).size
            for a, axis in enumerate(AXES):
                d, m = float(data[sel, a].mean()), float(pred[sel, a].mean())
                se = float(spread[k, a] / np.sqrt(n_stays))
                allowed = noise_se * se + share * scale
                out.append(AccelerationCheck("momentum", name, split, axis, d, m, allowed,
                                             bool(abs(m - d) <= allowed), int(sel.sum()), int(n_stays)))
                for mv in MOVES:
                    if mv.flight_only and k != flight:
                        continue
                    c = float(moved[mv.kind][sel, a].mean())
                    out.append(AccelerationCheck(mv.kind, name, split, axis, 0.0, c, allowed, bool(c <= allowed),
                                                 int(sel.sum()), int(n_stays)))
                if k == flight and axis == "z":
                    allowed = share * abs(d) + noise_se * se
                    out.append(AccelerationCheck("flight", name, split, axis, d, m, allowed,
                                                 bool(abs(m - d) <= allowed), int(sel.sum()), int(n_stays)))
    return out
