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
period (so no jump is upsampled by default). A jump's period is its median
step; for a jump logged evenly (every step within ``EVEN`` of the median) it is
its mean step (an uneven one: its median step at 6 significant digits), the
mean taken at 6 significant digits (0.002, not 0.0019999999) only
where every sample stays within ``TimeBase.grid_tol`` seconds of that grid:
a file on its grid is never pushed off it by rounding. A jump whose every
sample lies on the dataset's grid (to ``grid_tol`` s) is stored as logged,
with ``t`` set to ``k dt``: importing it alone or beside files at other rates
gives the same arrays. Any other jump is resampled at
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

from symrom.data.dataset import ON_GRID  # a sample within this fraction of a step of k dt is on the grid
from symrom.names import BASE_RPY

GAP = 1.5  # a step longer than this many median steps is a gap (samples missing)
EVEN = 1e-3  # a jump whose steps all lie within this fraction of its median is logged evenly
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
    resampling it; grid_tol: s, a sample this close to k dt is on the grid (1 us: the
    resolution of a time column written to 6 decimals; stored datasets hold t = k dt to
    ``dataset.ON_GRID`` dt, which this must not exceed at any rate the import accepts)."""

    dt: float | None = None
    jitter: float = 0.1
    max_gap: float = 0.01
    resample: bool = True
    grid_tol: float = 1e-6

    def __post_init__(self) -> None:
        if self.dt is not None and not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt={self.dt}: the sample period must be a positive number of seconds")
        if not self.max_gap > 0:
            raise ValueError(f"max_gap={self.max_gap}: must be a positive number of seconds")
        if not self.grid_tol > 0:
            raise ValueError(f"grid tolerance must be a positive number of seconds, got {self.grid_tol}")
        if not self.jitter > 0:
            raise ValueError(f"jitter tolerance must be positive, got {self.jitter}")


@dataclass
class JumpTiming:
    """The timing of one logged jump: rows, median step (s), ``period`` (s, the period it is
    on: see the module docstring), the largest relative deviation
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
    period: float = float("nan")
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
    period = float(f"{med:.6g}")  # an uneven jump is resampled: a round period serves
    if dev.max() <= EVEN:
        period = float((t[-1] - t[0]) / (t.size - 1))
        nice = float(f"{period:.6g}")
        if on_grid(t - t[0], nice, cfg.grid_tol):
            period = nice
    return JumpTiming(file, jump, int(t.size), float(f"{med:.6g}"), float(dev.max()),
                      int(((dev > cfg.jitter) & ~gap).sum()), gaps, period=period)


def choose_dt(timings: list[JumpTiming], cfg: TimeBase) -> float:
    """The dataset's period: ``cfg.dt``, else the coarsest jump's period."""
    if cfg.dt is not None:
        return float(cfg.dt)
    periods = [x.period for x in timings if np.isfinite(x.period)]
    return max(periods) if periods else 0.002


def on_grid(t: np.ndarray, dt: float, tol: float | None = None) -> bool:
    """Whether every sample of t (n,) s lies at k dt, k = 0, 1, 2 ... to ``tol`` s (default
    ``ON_GRID`` dt), and never farther than ``ON_GRID`` dt (what a stored dataset allows)."""
    k = np.arange(t.size)
    tol = ON_GRID * dt if tol is None else min(tol, ON_GRID * dt)
    return bool(np.all(np.abs(t - k * dt) <= tol))


def check_gaps(timing: JumpTiming, cfg: TimeBase) -> None:
    """Refuse the longest gap of a jump if it is longer than ``cfg.max_gap``."""
    long = [g for g in timing.gaps if g["length"] > cfg.max_gap + 1e-12]
    if long:
        g = max(long, key=lambda g: g["length"])
        raise TimeBaseError(
            f"{timing.file}, jump {timing.jump}, line {g['line']}: a gap of {1e3 * g['length']:.3g} ms after "
            f"t = {g['t']:.4f} s (the jump is logged every {1e3 * timing.median_dt:.3g} ms); gaps longer than "
            f"{1e3 * cfg.max_gap:.3g} ms are not bridged: cut the jump there or raise max_gap={cfg.max_gap:g}")


def resample_jump(t: np.ndarray, arrays: dict[str, np.ndarray | None], contact: np.ndarray,
                  dt: float) -> tuple[np.ndarray, dict[str, np.ndarray | None], np.ndarray]:
    """One jump at t = k dt up to its last logged time (module docstring).

    t (n,) s since the jump's first sample; arrays: continuous signals (n, d) by name
    (``q`` (n, 18) with the base angles in columns 15-17; None entries pass through);
    contact (n, 4). Returns the new times (m,), the signals (m, d) and contact (m, 4).
    """
    from scipy.interpolate import Akima1DInterpolator  # here: scipy.interpolate is slow to import

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
