"""The jump dataset: samples of all jumps stacked along the first axis.

Layout and meaning of every array are fixed by the dataset-file contract
(schema_version 1); see ``DESIGN.md``. ``validate`` checks all of it and raises
``DatasetError`` naming the key, the jump and the row of the first problem.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from symrom.motions import MOTIONS
from symrom.names import DEFAULT_DT, N_JOINTS, N_LEGS, N_Q, SPLITS

SCHEMA_VERSION = 1
ON_GRID = 1e-3  # t of the k-th sample of a jump is k dt to this fraction of dt


def jump_bounds(jump: np.ndarray) -> np.ndarray:
    """(J, 2) ``[start, stop)`` rows of each contiguous block of equal values in ``jump`` (N,)."""
    starts = np.flatnonzero(np.r_[True, np.diff(jump) != 0])
    return np.stack([starts, np.r_[starts[1:], len(jump)]], axis=1)


class DatasetError(ValueError):
    """A dataset breaks the contract; the message names key, jump and row."""


@dataclass
class Dataset:
    """Jumps of one robot and motion, stacked sample-wise (N rows, J jumps).

    Arrays (SI units): ``jump`` (N,) int, ``t`` (N,) s since the jump's first
    sample, ``q``/``dq``/``ddq`` (N, 18), ``tau`` (N, 12) N m, ``contact``
    (N, 4) in {0, 1}, ``u`` (N, 18) ``[tau, wrench]``, ``phase`` (N,) index
    into ``phase_names``, ``split`` (J,) in {train, val, test}, and optional
    ``foot_pos`` (N, 4, 3) m in the world frame and ``contact_force`` (N, 4, 3) N,
    the engine's ground force on each foot in the world frame (a simulator's
    diagnostic, never a model input).
    """

    robot: str
    motion: str
    source: str
    phase_names: list[str]
    jump: np.ndarray
    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    tau: np.ndarray
    contact: np.ndarray
    u: np.ndarray
    phase: np.ndarray
    split: np.ndarray
    foot_pos: np.ndarray | None = None
    contact_force: np.ndarray | None = None
    dt: float = DEFAULT_DT
    generator: dict[str, Any] = field(default_factory=dict)

    # ----------------------------------------------------------------- views
    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_jumps(self) -> int:
        return int(self.split.shape[0])

    def jump_bounds(self) -> np.ndarray:
        """(J, 2) int array of ``[start, stop)`` row ranges, one per jump."""
        return jump_bounds(self.jump)

    def jumps_in(self, split: str) -> np.ndarray:
        """Indices of the jumps assigned to ``split``."""
        return np.flatnonzero(self.split == split)

    def select_jumps(self, jumps: np.ndarray | list[int]) -> Dataset:
        """A new dataset holding only ``jumps`` (renumbered 0..K-1, order kept)."""
        jumps = np.asarray(jumps, dtype=int)
        bounds = self.jump_bounds()
        rows = np.concatenate([np.arange(*bounds[j]) for j in jumps]) if len(jumps) else np.zeros(0, int)
        new_index = np.repeat(np.arange(len(jumps)), [bounds[j, 1] - bounds[j, 0] for j in jumps])
        arrays = {k: getattr(self, k)[rows] for k in ROW_KEYS if getattr(self, k) is not None}
        arrays["jump"] = new_index.astype(np.int32)
        return replace(self, split=self.split[jumps].copy(), **arrays)

    def split_subset(self, split: str) -> Dataset:
        """The jumps of one split, as a dataset of their own."""
        return self.select_jumps(self.jumps_in(split))

    def rows_of(self, split: str) -> np.ndarray:
        """Boolean (N,) mask of the rows whose jump belongs to ``split``."""
        return np.isin(self.jump, self.jumps_in(split))

    def phase_id(self, name: str) -> int:
        try:
            return self.phase_names.index(name)
        except ValueError:
            raise DatasetError(f"phase {name!r} is not one of {self.phase_names}") from None

    def generator_json(self) -> str:
        return json.dumps(self.generator, sort_keys=True)

    # ----------------------------------------------------------------- in words
    def phase_rows(self, rows: np.ndarray | None = None) -> str:
        """'contact 1200 rows, flight 400 rows, partial none' for ``rows`` (N,) bool (all by default)."""
        phase = self.phase if rows is None else self.phase[rows]
        counts = np.bincount(phase, minlength=len(self.phase_names))
        return ", ".join(f"{n} {c} rows" if c else f"{n} none" for n, c in zip(self.phase_names, counts))

    def summary(self) -> str:
        """Jumps, samples, dt, the rows per phase and the jumps per split, in one line."""
        counts = ", ".join(f"{s} {int((self.split == s).sum())}" for s in ("train", "val", "test"))
        return (f"{self.n_jumps} jumps, {self.n_samples} samples, dt {self.dt:g} s; phases: {self.phase_rows()}; "
                f"{counts}")


# Per-row keys with their trailing shape and dtype kind ('f' float, 'i' int, 'u' flag).
ROW_KEYS: dict[str, tuple[tuple[int, ...], str]] = {
    "jump": ((), "i"),
    "t": ((), "f"),
    "q": ((N_Q,), "f"),
    "dq": ((N_Q,), "f"),
    "ddq": ((N_Q,), "f"),
    "tau": ((N_JOINTS,), "f"),
    "contact": ((N_LEGS,), "u"),
    "u": ((N_Q,), "f"),
    "phase": ((), "i"),
    "foot_pos": ((N_LEGS, 3), "f"),
    "contact_force": ((N_LEGS, 3), "f"),
}
OPTIONAL_KEYS = {"foot_pos", "contact_force"}


def _where(jump: np.ndarray | None, row: int) -> str:
    if jump is not None and jump.ndim == 1 and 0 <= row < jump.shape[0]:
        return f"jump {int(jump[row])}, row {row}"
    return f"row {row}"


def validate(ds: Dataset) -> None:
    """Check ``ds`` against the contract; raise ``DatasetError`` on the first problem."""
    if not isinstance(ds.phase_names, list) or not ds.phase_names or not all(
            isinstance(p, str) and p for p in ds.phase_names):
        raise DatasetError("attr 'phase_names': must be a non-empty list of names")
    if ds.motion not in MOTIONS:
        raise DatasetError(f"attr 'motion': unknown motion {ds.motion!r}; known: {sorted(MOTIONS)}")
    if not (np.isfinite(ds.dt) and ds.dt > 0):
        raise DatasetError(f"attr 'dt': must be a positive number, got {ds.dt!r}")
    jump = ds.jump if isinstance(ds.jump, np.ndarray) else None
    if jump is None or jump.ndim != 1:
        raise DatasetError("key 'jump': must be a 1-D array of jump indices")
    n = jump.shape[0]
    if n == 0:
        raise DatasetError("key 'jump': the dataset has no samples")
    for key, (shape, kind) in ROW_KEYS.items():
        arr = getattr(ds, key)
        if arr is None and key in OPTIONAL_KEYS:
            continue
        if not isinstance(arr, np.ndarray):
            raise DatasetError(f"key {key!r}: missing")
        if arr.shape != (n, *shape):
            raise DatasetError(f"key {key!r}: shape {arr.shape}, expected {(n, *shape)}")
        if kind == "f":
            if not np.issubdtype(arr.dtype, np.floating):
                raise DatasetError(f"key {key!r}: dtype {arr.dtype}, expected float")
            bad = ~np.isfinite(arr.reshape(n, -1)).all(axis=1)
            if bad.any():
                r = int(np.flatnonzero(bad)[0])
                raise DatasetError(f"key {key!r}: non-finite value at {_where(jump, r)}")
        elif not np.issubdtype(arr.dtype, np.integer):
            raise DatasetError(f"key {key!r}: dtype {arr.dtype}, expected integer")
    # Jumps: 0..J-1, each one contiguous block, in order.
    if jump[0] != 0 or np.any(np.diff(jump) < 0) or np.any(np.diff(jump) > 1):
        d = np.diff(jump)
        bad = np.flatnonzero((d < 0) | (d > 1))
        r = int(bad[0] + 1) if bad.size else 0
        raise DatasetError(f"key 'jump': jumps must be numbered 0..J-1 in contiguous blocks; "
                           f"problem at {_where(jump, r)}")
    n_jumps = int(jump[-1]) + 1
    split = ds.split
    if not isinstance(split, np.ndarray) or split.shape != (n_jumps,):
        got = getattr(split, "shape", None)
        raise DatasetError(f"key 'split': shape {got}, expected ({n_jumps},) (one per jump)")
    for j, s in enumerate(split):
        if s not in SPLITS:
            raise DatasetError(f"key 'split': jump {j} has {s!r}, expected one of {list(SPLITS)}")
    same_jump = np.diff(jump) == 0
    backwards = same_jump & (np.diff(ds.t) <= 0)
    if backwards.any():
        r = int(np.flatnonzero(backwards)[0] + 1)
        raise DatasetError(f"key 't': time does not increase at {_where(jump, r)}")
    bounds = jump_bounds(jump)
    k = np.arange(n) - np.repeat(bounds[:, 0], bounds[:, 1] - bounds[:, 0])
    off = np.abs(ds.t - k * ds.dt) > ON_GRID * ds.dt
    if off.any():  # one time base: rollouts and metrics step in dt
        r = int(np.flatnonzero(off)[0])
        raise DatasetError(f"key 't': {ds.t[r]:.6g} s at {_where(jump, r)} is not sample {int(k[r])} x dt "
                           f"= {k[r] * ds.dt:.6g} s: every jump must be sampled every dt = {ds.dt:g} s from 0 "
                           "(import the logs again: the import resamples them)")
    flags = ds.contact
    if np.any((flags != 0) & (flags != 1)):
        r = int(np.flatnonzero(((flags != 0) & (flags != 1)).any(axis=1))[0])
        raise DatasetError(f"key 'contact': flag {int(flags[r][(flags[r] != 0) & (flags[r] != 1)][0])} "
                           f"at {_where(jump, r)}, expected 0 or 1")
    bad = (ds.phase < 0) | (ds.phase >= len(ds.phase_names))
    if bad.any():
        r = int(np.flatnonzero(bad)[0])
        raise DatasetError(f"key 'phase': index {int(ds.phase[r])} at {_where(jump, r)} is not a "
                           f"known phase ({len(ds.phase_names)} names: {ds.phase_names})")
    if not np.allclose(ds.u[:, :N_JOINTS], ds.tau, rtol=1e-9, atol=1e-9):
        r = int(np.flatnonzero(~np.isclose(ds.u[:, :N_JOINTS], ds.tau, rtol=1e-9, atol=1e-9).all(1))[0])
        raise DatasetError(f"key 'u': its first 12 columns differ from 'tau' at {_where(jump, r)}")
