"""One time base per jump: the sampling period checked per jump, logs at other rates resampled.

A dataset has one sample period ``dt``, and every jump is stored on it:
``t = k dt`` for its k-th sample. Rollouts and metrics integrate and count in
that ``dt``, so a jump logged at another rate, or unevenly, must be brought to
it before it is stored.

Per jump of a log (``jump_timing``): the median step; *jitter*, the steps
that differ from it by more than ``TimeBase.jitter`` (relative); *gaps*, the
steps longer than 1.5 median steps (samples missing). Gaps longer than
``TimeBase.max_gap`` are refused, naming the file, the jump, the line and the
time.

The dataset's ``dt`` is ``TimeBase.dt`` if given, else the coarsest jump's
median period (so no jump is upsampled by default). A jump whose every
sample already lies on its grid (to ``ON_GRID`` of a step) is stored as
logged, with ``t`` set to ``k dt``: importing it alone or beside files at
other rates gives the same arrays. Any other jump is resampled at
``t = 0, dt, 2 dt ...`` up to its last logged time (``resample_jump``):

- positions, velocities, logged accelerations and torques by modified Akima
  interpolation (``scipy.interpolate.Akima1DInterpolator(method="makima")``):
  a piecewise cubic through every logged sample that does not overshoot at
  sharp changes (touch-down) the way a global cubic spline does; the base
  angles are unwrapped first. Each of q, dq, ddq is interpolated from its own
  logged samples, so on a smooth motion each stays the derivative of the one
  before to the interpolation's accuracy; where accelerations were not
  logged they are differentiated from the resampled velocities, in ``dt``;
- contact flags by the nearest logged sample in time (phases are labelled
  afterwards, from those flags, so they follow the same rule);
- no anti-alias filter: downsampling keeps the logged values at (or
  interpolated next to) the new sample times.

With ``TimeBase.resample`` False, a jump that is not on the grid is refused
with one clear message instead.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.interpolate import Akima1DInterpolator

from symrom.data.dataset import ON_GRID  # a sample within this fraction of a step of k dt is on the grid
from symrom.names import BASE_RPY

GAP = 1.5  # a step longer than this many median steps is a gap (samples missing)
METHOD = ("modified Akima interpolation (scipy.interpolate.Akima1DInterpolator, method='makima') of "
          "q, dq, logged ddq and tau, base angles unwrapped; contact flags by the nearest sample; "
          "phases labelled from the resampled flags; ddq not logged: differentiated after resampling")


class TimeBaseError(ValueError):
    """A jump's timing cannot be brought to the dataset's time base; one clear line."""


@dataclass(frozen=True)
class TimeBase:
    """dt: the dataset's sample period, s (None: the coarsest jump's median period);
    jitter: a step off the jump's median by more than this fraction is reported as
    jitter; max_gap: s, the longest gap (missing samples) bridged by interpolation,
    longer ones are refused; resample: False refuses any jump off the grid instead of
    resampling it."""

    dt: float | None = None
    jitter: float = 0.1
    max_gap: float = 0.01
    resample: bool = True

    def __post_init__(self) -> None:
        if self.dt is not None and not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"--dt {self.dt}: the sample period must be a positive number of seconds")
        if not self.max_gap > 0:
            raise ValueError(f"--max-gap {self.max_gap}: must be a positive number of seconds")
        if not self.jitter > 0:
            raise ValueError(f"jitter tolerance must be positive, got {self.jitter}")


@dataclass
class JumpTiming:
    """The timing of one logged jump: rows, median step (s), the largest relative deviation
    of a step from it, how many steps are jitter, the gaps (``{"t": s, "length": s,
    "line": int}``), and what the import did (``stored``: ``as logged`` or ``resampled``,
    ``rows_out``)."""

    file: str
    jump: int
    rows: int
    median_dt: float
    max_deviation: float
    jitter_steps: int
    gaps: list[dict] = field(default_factory=list)
    stored: str = ""
    rows_out: int = 0

    def to_dict(self) -> dict:
        return asdict(self)


def jump_timing(file: str, jump: int, t: np.ndarray, lines: list[int], cfg: TimeBase) -> JumpTiming:
    """Timing of one jump: t (n,) s since its first sample, lines (n,) the file's line of each."""
    steps = np.diff(t)
    if steps.size == 0:
        return JumpTiming(file, jump, int(t.size), float("nan"), 0.0, 0)
    med = float(np.median(steps))
    dev = np.abs(steps / med - 1.0)
    gap = steps > GAP * med
    gaps = [{"t": float(t[i]), "length": float(steps[i]), "line": int(lines[i + 1])} for i in np.flatnonzero(gap)]
    return JumpTiming(file, jump, int(t.size), float(f"{med:.6g}"), float(dev.max()),
                      int(((dev > cfg.jitter) & ~gap).sum()), gaps)


def choose_dt(timings: list[JumpTiming], cfg: TimeBase) -> float:
    """The dataset's period: ``cfg.dt``, else the coarsest jump's median period."""
    if cfg.dt is not None:
        return float(cfg.dt)
    periods = [x.median_dt for x in timings if np.isfinite(x.median_dt)]
    return max(periods) if periods else 0.002


def on_grid(t: np.ndarray, dt: float) -> bool:
    """Whether every sample of t (n,) lies at k dt, k = 0, 1, 2 ... (to ``ON_GRID`` of dt)."""
    k = np.arange(t.size)
    return bool(np.all(np.abs(t - k * dt) <= ON_GRID * dt))


def check_gaps(timing: JumpTiming, cfg: TimeBase) -> None:
    """Refuse the longest gap of a jump if it is longer than ``cfg.max_gap``."""
    long = [g for g in timing.gaps if g["length"] > cfg.max_gap + 1e-12]
    if long:
        g = max(long, key=lambda g: g["length"])
        raise TimeBaseError(
            f"{timing.file}, jump {timing.jump}, line {g['line']}: a gap of {1e3 * g['length']:.3g} ms after "
            f"t = {g['t']:.4f} s (the jump is logged every {1e3 * timing.median_dt:.3g} ms); gaps longer than "
            f"{1e3 * cfg.max_gap:.3g} ms are not bridged: cut the jump there or raise --max-gap")


def resample_jump(t: np.ndarray, arrays: dict[str, np.ndarray | None], contact: np.ndarray,
                  dt: float) -> tuple[np.ndarray, dict[str, np.ndarray | None], np.ndarray]:
    """One jump at t = k dt up to its last logged time (module docstring).

    t (n,) s since the jump's first sample; arrays: continuous signals (n, d) by name
    (``q`` (n, 18) with the base angles in columns 15-17; None entries pass through);
    contact (n, 4). Returns the new times (m,), the signals (m, d) and contact (m, 4).
    """
    m = int(np.floor(t[-1] / dt + ON_GRID)) + 1
    grid = np.arange(m) * dt
    out: dict[str, np.ndarray | None] = {}
    for name, x in arrays.items():
        if x is None:
            out[name] = None
            continue
        x = np.asarray(x, dtype=float).copy()
        if name == "q":
            x[:, BASE_RPY] = np.unwrap(x[:, BASE_RPY], axis=0)
        if t.size >= 3:
            out[name] = Akima1DInterpolator(t, x, axis=0, method="makima")(np.minimum(grid, t[-1]))
        else:  # too few samples for a cubic: straight lines
            out[name] = np.stack([np.interp(grid, t, col) for col in x.T], axis=1)
    right = np.clip(np.searchsorted(t, grid), 1, t.size - 1) if t.size > 1 else np.zeros(m, int)
    left = right - 1 if t.size > 1 else right
    nearest = np.where(np.abs(grid - t[left]) <= np.abs(t[right] - grid), left, right)
    return grid, out, np.asarray(contact)[nearest]
