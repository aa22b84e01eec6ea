"""Robot logs -> dataset: the two CSV layouts, the kinds of log file, and the import itself.

A log is a delimited text file with one header line and one sample per line.
The layout is recognised from the header (the delimiter from the header line:
``;`` if it holds one, else ``,``; with ``;`` decimal commas such as ``0,002``
are read as ``0.002``). Columns are matched by name, in any order, ignoring
surrounding whitespace, runs of inner whitespace and letter case; the set of
columns is strict: every required column must be there, no unknown column may.

**hardware** - the published Go1 hardware-log layout, 500 Hz::

    Time
    <leg>.<joint> Position | Velocity | Acceleration | Torque     leg in fr fl rr rl, joint in hx hy kn
    Body linear Position|Velocity|Acceleration x|y|z             base x, y, z (m, m/s, m/s^2)
    Body angular Position|Velocity|Acceleration x|y|z            base roll, pitch, yaw (rad, ...)
    <leg> Foot                                                   contact flag 0/1

A new jump begins wherever ``Time`` decreases (the logger restarts it at each
jump).

**plain** - comma-separated with the dataset's own names (``names.py``)::

    jump        optional jump id; without it, the Time-restart rule as above
    t           s
    fr_hx ... rl_kn, x, y, z, roll, pitch, yaw          q (18)
    d_<name>    for each q name                          dq (18)
    dd_<name>   for each q name, optional                ddq (18)
    tau_<joint> for each of the 12 joints                tau (12), N m
    c_fr, c_fl, c_rr, c_rl                               contact flags 0/1

In both layouts the acceleration columns are optional as a group: present,
they are used; absent, ``dq`` is differentiated (``savgol`` or ``central``).
Several files are concatenated as consecutive jumps.

A log may also be a ROS 1 bag, a ROS 2 bag folder or an MCAP file (``log_kind``
tells them apart by their content): ``bags.read_bag`` reads it into the same
per-file table (``RawLog``) as a CSV log, so what follows is shared.

The import then, in this order:

1. cuts jumps holding several flights (a continuous recording) into one jump
   per flight by the motion's phase rule (``segment``; ``segment="off"``
   keeps them);
2. reports stale rows (a group of columns repeating the previous row) and,
   with ``retime``, interpolates them between the fresh rows (``consistency``);
3. gives rebased jumps their height back (``restore_height``: a logger that
   starts every segment's position at 0); with ``repair``, then repairs each jump
   from physics (``repair``: its clock and velocities, contact flags, torque gain
   and height offset of any size), the values' units checked first;
4. checks every value against the robot's description (``checks``; the
   torques as commanded or measured): the first implausible one is refused in
   one line naming the file, jump, row, line, column, value and limit, with
   the likely unit mistake; ``lenient`` records them per file instead;
5. checks each jump against physics (``consistency``: velocities against
   positions, vertical momentum against the weight, stance feet on the
   ground), refused or recorded likewise;
6. brings every jump to one time base (``timebase``): the period is checked
   per jump (median, jitter, gaps), the dataset's ``dt`` is the coarsest
   jump's period (or the one given), and jumps off its grid (to a tolerance in
   time) are resampled (or refused);
7. differentiates velocities that came without accelerations over a window
   set in seconds (``diff_samples``), and computes the CoM wrench and the
   phase labels (``preprocess.assemble``).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from symrom.data.checks import PlausibilityLimits, check_samples
from symrom.data.consistency import (
    ConsistencyLimits,
    foot_height,
    retime_stale,
    stale_rows,
    time_scale,
    vertical_impulse,
)
from symrom.data.dataset import Dataset
from symrom.data.preprocess import DIFF_METHODS, DIFF_WINDOW, assemble, differentiate
from symrom.data.rawlog import LogError, RawLog, log_kind, sha256_file
from symrom.data.repair import RepairLimits, repair_log, repairs_record
from symrom.data.report import ImportReport
from symrom.data.segment import SEGMENT, segment_log
from symrom.data.timebase import METHOD as TIMEBASE_METHOD
from symrom.data.timebase import TimeBase, TimeBaseError, check_gaps, choose_dt, jump_timing, on_grid, resample_jump
from symrom.motions import get_motion
from symrom.names import BASE_NAMES, DEFAULT_DT, JOINT_NAMES, LEGS, Q_NAMES, SPLITS
from symrom.robots import get_robot

# ----------------------------------------------------------------- layouts

@dataclass(frozen=True)
class Layout:
    """Column names of one log layout, per field, in symrom's order.

    ``t`` (1), ``q``/``dq``/``ddq`` (18 each), ``tau`` (12), ``contact`` (4);
    ``jump`` (0 or 1 names). ``ddq`` and ``jump`` are optional groups.
    """

    name: str
    t: tuple[str, ...]
    q: tuple[str, ...]
    dq: tuple[str, ...]
    ddq: tuple[str, ...]
    tau: tuple[str, ...]
    contact: tuple[str, ...]
    jump: tuple[str, ...] = ()

    @property
    def required(self) -> tuple[str, ...]:
        return self.t + self.q + self.dq + self.tau + self.contact

    @property
    def optional_groups(self) -> tuple[tuple[str, ...], ...]:
        return tuple(g for g in (self.ddq, self.jump) if g)

    @property
    def all_names(self) -> tuple[str, ...]:
        return self.required + self.ddq + self.jump


def _hw_joint(name: str, quantity: str) -> str:
    leg, joint = name.split("_")
    return f"{leg}.{joint} {quantity}"


_HW_BASE = {"x": ("linear", "x"), "y": ("linear", "y"), "z": ("linear", "z"),
            "roll": ("angular", "x"), "pitch": ("angular", "y"), "yaw": ("angular", "z")}


def _hw_names(quantity: str) -> tuple[str, ...]:
    """Hardware column names of the 18 q components for Position/Velocity/Acceleration."""
    joints = tuple(_hw_joint(n, quantity) for n in JOINT_NAMES)
    base = tuple(f"Body {_HW_BASE[n][0]} {quantity} {_HW_BASE[n][1]}" for n in BASE_NAMES)
    return joints + base


HARDWARE = Layout(
    name="hardware", t=("Time",),
    q=_hw_names("Position"), dq=_hw_names("Velocity"), ddq=_hw_names("Acceleration"),
    tau=tuple(_hw_joint(n, "Torque") for n in JOINT_NAMES),
    contact=tuple(f"{leg} Foot" for leg in LEGS))

PLAIN = Layout(
    name="plain", t=("t",), q=Q_NAMES,
    dq=tuple(f"d_{n}" for n in Q_NAMES), ddq=tuple(f"dd_{n}" for n in Q_NAMES),
    tau=tuple(f"tau_{n}" for n in JOINT_NAMES),
    contact=tuple(f"c_{leg}" for leg in LEGS), jump=("jump",))

LAYOUTS: tuple[Layout, ...] = (HARDWARE, PLAIN)


def _norm(name: str) -> str:
    """Matching key of a column name: inner whitespace collapsed, case folded."""
    return " ".join(name.replace("\ufeff", "").split()).casefold()


def detect_layout(header: list[str]) -> Layout:
    """The layout whose names best match ``header`` (most known columns)."""
    keys = {_norm(h) for h in header}
    scores = [len(keys & {_norm(n) for n in lay.all_names}) for lay in LAYOUTS]
    return LAYOUTS[int(np.argmax(scores))]


def _listing(names: list[str]) -> str:
    return ", ".join(names)


def _column_map(path: Path, header: list[str], layout: Layout) -> dict[str, int]:
    """Header position of each known column name; one LogError for all problems (the time
    column's absence is the caller's to judge: a log read at a nominal period has none)."""
    pos: dict[str, int] = {}
    seen: dict[str, str] = {}
    dupes, unknown = [], []
    known = {_norm(n): n for n in layout.all_names}
    for i, h in enumerate(header):
        key = _norm(h)
        if key in seen:
            dupes.append(h.strip())
            continue
        seen[key] = h
        if key in known:
            pos[known[key]] = i
        else:
            unknown.append(h.strip() or f"<empty name in column {i + 1}>")
    if not pos:
        first = ", ".join(repr(h.strip()) for h in header[:4])
        raise LogError(f"{path}: the header matches neither log layout (hardware: 'Time', "
                       f"'fr.hx Position', ...; plain: 't', 'fr_hx', ...); it starts {first}")
    missing = [n for n in layout.required if n not in pos and n not in layout.t]
    for group in layout.optional_groups:
        present = [n for n in group if n in pos]
        if present and len(present) < len(group):
            missing += [n for n in group if n not in pos]
    problems = []
    if missing:
        problems.append(f"missing columns: {_listing(missing)}")
    if unknown:
        problems.append(f"unknown columns: {_listing(unknown)}")
    if dupes:
        problems.append(f"duplicate columns: {_listing(dupes)}")
    if problems:
        raise LogError(f"{path}: {layout.name} log layout; " + "; ".join(problems))
    return pos


# ----------------------------------------------------------------- reading

def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]], str]:
    """Header cells, (line number, cells) of every non-blank line, and the delimiter."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            lines = f.read().splitlines()
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise LogError(f"{path}: not a text (UTF-8) CSV file") from None
    except OSError as e:
        raise LogError(f"{path}: cannot read ({e.strerror or e})") from None
    numbered = [(i + 1, line) for i, line in enumerate(lines) if line.strip()]
    if not numbered:
        raise LogError(f"{path}: empty file")
    delim = ";" if ";" in numbered[0][1] else ","
    parsed = list(csv.reader([line for _, line in numbered], delimiter=delim))
    header = parsed[0]
    while header and not header[-1].strip():  # a trailing delimiter
        header = header[:-1]
    rows = [(numbered[k][0], cells) for k, cells in enumerate(parsed) if k > 0]
    return header, rows, delim


def _to_matrix(path: Path, header: list[str], rows: list[tuple[int, list[str]]],
               delim: str) -> np.ndarray:
    """(n, len(header)) float array; LogError naming file, line and column on a bad cell."""
    width = len(header)
    table = []
    for line, cells in rows:
        if len(cells) > width and not any(c.strip() for c in cells[width:]):
            cells = cells[:width]  # trailing delimiters
        if len(cells) != width:
            raise LogError(f"{path}, line {line}: {len(cells)} cells, the header has {width}")
        table.append([c.replace(",", ".") for c in cells] if delim == ";" else cells)
    try:
        out = np.array(table, dtype=float).reshape(len(rows), width)
        if np.isfinite(out).all():
            return out
    except ValueError:
        pass
    out = np.empty((len(rows), width))
    for r, ((line, cells), texts) in enumerate(zip(rows, table)):  # cell by cell, naming the bad one
        for c, text in enumerate(texts):
            try:
                out[r, c] = float(text)
            except ValueError:
                out[r, c] = np.nan
            if not math.isfinite(out[r, c]):
                raise LogError(f"{path}, line {line}, column {header[c].strip()!r}: "
                               f"{cells[c]!r} is not a finite number")
    return out


def _jumps_from_time(path: Path, t: np.ndarray, lines: list[int]) -> np.ndarray:
    """Local jump ids (n,): a new jump wherever time decreases; equal times are an error."""
    d = np.diff(t)
    same = np.flatnonzero(d == 0)
    if same.size:
        i = int(same[0]) + 1
        raise LogError(f"{path}, line {lines[i]}: time {t[i]:g} repeats the previous sample's")
    return np.r_[0, np.cumsum(d < 0)].astype(np.int32)


def _jumps_from_column(path: Path, ids: np.ndarray, t: np.ndarray, lines: list[int],
                       col: str) -> np.ndarray:
    """Local jump ids (n,) from a jump column: contiguous blocks renumbered 0..k-1."""
    bad = np.flatnonzero(ids != np.round(ids))
    if bad.size:
        i = int(bad[0])
        raise LogError(f"{path}, line {lines[i]}, column {col!r}: {ids[i]:g} is not a jump number")
    change = np.r_[False, ids[1:] != ids[:-1]]
    local = np.cumsum(change).astype(np.int32)
    first = {}
    for i in np.flatnonzero(np.r_[True, change[1:]]):
        if ids[i] in first:
            raise LogError(f"{path}, line {lines[i]}, column {col!r}: jump {ids[i]:g} "
                           f"continues after another jump (line {lines[first[ids[i]]]})")
        first[ids[i]] = i
    back = np.flatnonzero((np.diff(t) <= 0) & ~change[1:])
    if back.size:
        i = int(back[0]) + 1
        raise LogError(f"{path}, line {lines[i]}: time does not increase within jump {ids[i]:g}")
    return local


def read_log(path: str | os.PathLike, period: float | None = None) -> RawLog:
    """Read one CSV log (either layout, see the module docstring) into a ``RawLog``.

    period: s, for a log without a time column (a controller that logs no timestamps): its
    rows are read ``period`` apart, the loop's nominal period (``RawLog.period``), one jump
    per file or per ``jump`` value; the repair then estimates the true clock from the flight
    (``data.repair``). A log without a time column is refused without it; a log with one
    ignores it."""
    path = Path(path)
    if period is not None and not (math.isfinite(period) and period > 0):
        raise ValueError(f"period={period!r}: must be a positive number of seconds")
    if path.is_dir():
        raise LogError(f"{path}: is a directory, expected a CSV file")
    kind = log_kind(path)
    if kind != "csv":
        raise LogError(f"{path}: not a CSV log ({kind}); read it with symrom.data.bags.read_bag")
    header, rows, delim = _read_rows(path)
    if not rows:
        raise LogError(f"{path}: no samples after the header")
    layout = detect_layout(header)
    pos = _column_map(path, header, layout)
    data = _to_matrix(path, header, rows, delim)
    lines = [line for line, _ in rows]

    def cols(names: tuple[str, ...]) -> np.ndarray:
        return data[:, [pos[n] for n in names]]

    timed = layout.t[0] in pos
    if not timed and period is None:
        raise LogError(f"{path}: {layout.name} log layout without a time column ({layout.t[0]!r}); give the "
                       "nominal period of its rows in seconds (period=) to read them that far apart, and the "
                       "repair (repair=) finds their true clock from the flight")
    has_jump = bool(layout.jump) and layout.jump[0] in pos
    if timed:
        t = cols(layout.t)[:, 0]
    else:  # the rows of each jump period apart: the time column _jumps_from_column needs
        ids = cols(layout.jump)[:, 0] if has_jump else np.zeros(len(rows))
        new_jump = np.r_[True, ids[1:] != ids[:-1]]
        starts = np.flatnonzero(new_jump)
        t = (np.arange(len(rows)) - np.repeat(starts, np.diff(np.r_[starts, len(rows)]))) * period
    if has_jump:
        jump = _jumps_from_column(path, cols(layout.jump)[:, 0], t, lines, header[pos["jump"]].strip())
    elif timed:
        jump = _jumps_from_time(path, t, lines)
    else:
        jump = np.zeros(len(rows), np.int32)
    contact = cols(layout.contact)
    bad = np.argwhere((contact != 0) & (contact != 1))
    if bad.size:
        r, c = bad[0]
        raise LogError(f"{path}, line {lines[r]}, column {layout.contact[c]!r}: contact flag "
                       f"{contact[r, c]:g}, expected 0 or 1")
    starts = np.flatnonzero(np.r_[True, np.diff(jump) != 0])
    t0 = np.repeat(t[starts], np.diff(np.r_[starts, len(t)]))
    has_acc = all(n in pos for n in layout.ddq)
    names = {f: tuple(header[pos[n]].strip() for n in getattr(layout, f)) for f in ("q", "dq", "tau")}
    return RawLog(path=path, layout=layout.name, sha256=sha256_file(path), jump=jump, t=t - t0,
                  q=cols(layout.q), dq=cols(layout.dq), ddq=cols(layout.ddq) if has_acc else None,
                  tau=cols(layout.tau), contact=contact.astype(np.uint8), lines=np.asarray(lines),
                  columns=names, period=None if timed else float(period))


# ----------------------------------------------------------------- splits, dt

def parse_split(spec: str | None, n_jumps: int) -> np.ndarray:
    """Per-jump split names (n_jumps,) from ``"train,val,test"`` counts or fractions.

    Counts (all whole numbers) must add up to ``n_jumps``; fractions must add
    up to 1 and are rounded to counts by largest remainder. Jumps are assigned
    in order: the first ones train, then val, then test. ``None``: all train.
    """
    if spec is None:
        return np.array(["train"] * n_jumps, dtype=object)
    parts = [p.strip() for p in spec.split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        vals = []
    if len(parts) != len(SPLITS) or len(vals) != len(SPLITS) or any(
            not math.isfinite(v) or v < 0 for v in vals):
        raise ValueError(f"split={spec!r}: expected three non-negative numbers train,val,test "
                         f"(counts like 12,2,1 or fractions like 0.8,0.1,0.1)")
    whole = all(v == int(v) for v in vals)
    if whole and sum(vals) == n_jumps:
        counts = [int(v) for v in vals]
    elif abs(sum(vals) - 1.0) <= 1e-6:
        exact = [v * n_jumps for v in vals]
        counts = [math.floor(x) for x in exact]
        for k in sorted(range(len(SPLITS)), key=lambda k: exact[k] - counts[k], reverse=True):
            if sum(counts) >= n_jumps:
                break
            counts[k] += 1
        empty = [s for s, v, c in zip(SPLITS, vals, counts) if v > 0 and c == 0]
        if empty:  # a split asked for but left without a jump: the evaluation would silently skip it
            got = ", ".join(f"{c} {s}" for s, c in zip(SPLITS, counts))
            raise ValueError(f"split={spec!r}: {n_jumps} jumps divide as {got}: the {' and '.join(empty)} "
                             f"split{'s are' if len(empty) > 1 else ' is'} empty though asked for; give counts "
                             f"that add up to {n_jumps} (e.g. {_example_counts(n_jumps)}) or import more jumps")
    elif whole:
        raise ValueError(f"split={spec!r}: the counts add up to {int(sum(vals))} jumps, "
                         f"the logs hold {n_jumps}")
    else:
        raise ValueError(f"split={spec!r}: fractions must add up to 1 (they add up to {sum(vals):g})")
    return np.array([s for s, c in zip(SPLITS, counts) for _ in range(c)], dtype=object)


def split_counts(spec: str | None, n_jumps: int) -> tuple[int, int, int] | None:
    """The (train, val, test) jump counts ``spec`` gives ``n_jumps`` jumps (``parse_split``: counts
    or fractions); None for None."""
    if spec is None:
        return None
    labels = parse_split(spec, n_jumps)
    return tuple(int((labels == s).sum()) for s in SPLITS)


def _example_counts(n: int) -> str:
    """A train,val,test count example for n jumps with every split used (if n >= 3)."""
    if n < 3:
        return f"{n},0,0"
    v = t = max(1, round(0.1 * n))
    return f"{n - v - t},{v},{t}"


def sample_period(t: np.ndarray, jump: np.ndarray) -> float:
    """Median time step within jumps, s (``DEFAULT_DT`` if no jump has 2 samples)."""
    same = np.diff(jump) == 0
    steps = np.diff(t)[same]
    if steps.size == 0:
        return DEFAULT_DT
    return float(f"{np.median(steps):.6g}")


# ----------------------------------------------------------------- rebased positions

POSITIONS = ("auto", "absolute", "rebased")
_Z = BASE_NAMES.index("z") + len(JOINT_NAMES)
REBASED_Z = 1e-9  # m: a jump whose first base height is 0 (to this) was rebased by its logger


def restore_height(lg: RawLog, robot: str, positions: str) -> list[dict]:
    """Give rebased jumps of ``lg`` their height above the ground back (in place); one record
    per jump restored.

    A logger that rebases positions per segment starts x, y and z at 0; a base
    cannot sit at ground level, so with ``positions="auto"`` a jump whose first
    base height is 0 is taken as rebased (``"rebased"``: every jump; ``"absolute"``:
    none). Its z is shifted so that the feet in contact touch the ground (their
    centres one foot radius above it; the median over the jump's rows with a foot
    down) or, in a jump without a contact row, so that the lowest foot of its first
    sample does (the segment is taken to start at take-off). x and y are left as
    logged: a horizontal shift does not change the dynamics.
    """
    if positions not in POSITIONS:
        raise ValueError(f"positions={positions!r}: choose from {', '.join(POSITIONS)}")
    if positions == "absolute":
        return []
    from symrom.data.preprocess import foot_positions_world
    from symrom.robots import get_robot

    radius = get_robot(robot).foot_radius
    out = []
    for j, (a, b) in enumerate(lg.bounds()):
        if positions == "auto" and abs(lg.q[a, _Z]) > REBASED_Z:
            continue
        feet = foot_positions_world(robot, lg.q[a:b])[:, :, 2]  # (n, 4) m, with the logged z
        down = lg.contact[a:b].astype(bool)
        rows = np.flatnonzero(down.any(axis=1))
        if rows.size:
            offset = float(np.median([radius - feet[r][down[r]].mean() for r in rows]))
            how = f"feet in contact on the ground ({rows.size} rows)"
        else:
            offset = float(radius - feet[0].min())
            how = "lowest foot on the ground at the first sample (no contact row: taken to start at take-off)"
        lg.q[a:b, _Z] += offset
        out.append({"file": lg.path.name, "jump": j, "z_offset": round(offset, 6), "from": how})
    return out


# ----------------------------------------------------------------- checks

def plausibility(lg: RawLog, robot: str, limits: PlausibilityLimits) -> list[dict]:
    """The plausibility problems of one log (``checks.check_samples``), each with the
    file's column name, line, jump and row of its first bad value: JSON-ready."""
    out = []
    for prob in check_samples(robot, lg.q, lg.dq, lg.tau, limits, t=lg.t):
        r = prob.first
        j = int(lg.jump[r])
        header = lg.columns[prob.field][prob.index] if lg.columns else prob.name
        out.append({**prob.to_dict(), "header": header, "line": int(lg.lines[r]) if lg.lines is not None else None,
                    "jump": j, "row": r - int(lg.bounds()[j, 0]),
                    "message": (f"{lg.where(r)}, column {header!r}: {prob.what} {prob.value:.6g} {prob.unit} is "
                                f"outside {prob.range_text()} ({prob.limit}); {prob.rows} of {len(lg.t)} rows "
                                f"are outside, worst {prob.worst:.6g}{prob.hint_text()}")})
    return out


def _refuse(problems: list[dict], what: str = "column") -> None:
    first = problems[0]
    more = len(problems) - 1
    tail = (f" ({more} more {what}{'s' if more > 1 else ''} fail; lenient=True lists them all)" if more else "")
    raise LogError(first["message"] + tail)


def consistency(lg: RawLog, robot: str, limits: ConsistencyLimits, rebased: set[int]) -> list[dict]:
    """The physical-consistency problems of one log, per jump (``consistency``): time scale,
    vertical momentum, and (jumps not rebased) the height of the feet in contact."""
    out = []
    for j, (a, b) in enumerate(lg.bounds()):
        where = f"{lg.path}, jump {j}"
        t, q, dq, tau, c = lg.t[a:b], lg.q[a:b], lg.dq[a:b], lg.tau[a:b], lg.contact[a:b]
        probs = time_scale(where, t, q, dq, limits)
        probs += vertical_impulse(where, robot, t, q, dq, tau, c, limits)
        if j not in rebased:
            probs += foot_height(where, robot, q, c, limits)
        out += [{**p, "jump": j} for p in probs]
    return out


def diff_samples(window: float, dt: float) -> int:
    """The odd number of samples nearest to ``window`` / ``dt`` (halves up), at least 3:
    the differentiation window of ``window`` s at the period ``dt`` s (18 ms: 9 at 500 Hz,
    19 at 1 kHz)."""
    if not (math.isfinite(window) and window > 0):
        raise ValueError(f"diff_window={window}: must be a positive number of seconds")
    return max(3, 2 * math.floor((window / dt - 1) / 2 + 0.5) + 1)


def read_source(path: str | os.PathLike, robot: str, topics: dict[str, str] | None = None,
                period: float | None = None) -> RawLog:
    """Any log symrom reads (``log_kind``): a CSV log (``period``: ``read_log``'s, for one without a
    time column), a ROS 1 or ROS 2 bag, an MCAP file."""
    kind = log_kind(path)
    if kind == "csv":
        return read_log(path, period)
    from symrom.data.bags import read_bag

    return read_bag(path, robot, topics)


# ----------------------------------------------------------------- import

def import_logs(paths: list[str | os.PathLike], robot: str, motion: str = "pronk",
                source: str = "hardware", split: str | None = None,
                diff_method: str = "savgol", lenient: bool = False,
                limits: PlausibilityLimits = PlausibilityLimits(),
                time_base: TimeBase = TimeBase(), positions: str = "auto",
                physics: ConsistencyLimits | None = ConsistencyLimits(), segment: str = "auto",
                retime: bool = False, diff_window: float = DIFF_WINDOW,
                topics: dict[str, str] | None = None,
                repair: RepairLimits | None = None, period: float | None = None) -> tuple[Dataset, ImportReport]:
    """Read logs (CSV, ROS 1/2 bags, MCAP; concatenated as consecutive jumps) into a checked,
    validated dataset; the dataset and what the import found and did (``ImportReport``, the
    typed view of the dataset's ``generator`` record).

    robot: a built-in name or a robot description file (the wrench uses its URDF,
    the checks its limits); motion: a registered motion, whose phase rule labels
    the samples (``pronk``, ``froggy``) and cuts continuous recordings; split: see
    ``parse_split`` (applied to the jumps after segmentation); diff_method:
    ``savgol`` or ``central``, used where a log has no acceleration columns, over
    ``diff_window`` s (``diff_samples``).

    Every log is checked against the robot (``checks.check_samples``; ``limits.torques``
    says whether its torques are commanded or measured) and against physics
    (``consistency``, with ``physics``; None skips it): the first problem raises
    ``LogError`` naming the file, jump, rows, the figure and the limit; ``lenient``
    keeps the values as logged and records every problem in
    ``generator["files"][i]["checks"]`` and ``["consistency"]``.
    segment: ``auto`` cuts a jump holding several flights (``segment.segment_log``),
    ``off`` keeps jumps as logged. Stale rows are reported per file; ``retime``
    replaces them by interpolation between the fresh rows (``consistency.retime_stale``).
    positions: ``auto``, ``absolute`` or ``rebased`` (``restore_height``).
    time_base: the dataset's sample period and how jumps at other rates are brought
    to it (``timebase``); what was done per jump is in ``generator["time_base"]``.
    topics: bag topics by role (``bags.DEFAULT_TOPICS``).
    repair: repair each jump from physics before the checks (``repair.repair_log``, with
    these limits; None: as logged): its clock and velocities, contact flags, torque gain
    and height offset (``positions="absolute"`` leaves z as logged); the values' units are
    checked first (the base height and the torques' size only after it); what was found per
    jump is in ``generator["repairs"]``. A fault the data cannot determine, where the jump
    fails the consistency checks as logged, raises ``repair.RepairError`` (``lenient`` keeps
    it as logged).
    period: s, the nominal period of CSV logs without a time column (``read_log``; their
    rows are read that far apart, recorded per file as ``time``), for the repair to retime.
    """
    robot = get_robot(robot).key
    get_motion(motion)
    if diff_method not in DIFF_METHODS:
        raise ValueError(f"diff_method={diff_method!r}: unknown differentiation method; choose from {DIFF_METHODS}")
    if positions not in POSITIONS:
        raise ValueError(f"positions={positions!r}: choose from {', '.join(POSITIONS)}")
    if segment not in SEGMENT:
        raise ValueError(f"segment={segment!r}: choose from {', '.join(SEGMENT)}")
    diff_samples(diff_window, DEFAULT_DT)  # refuse a bad window before any work
    if not paths:
        raise ValueError("no log files given")
    logs = [read_source(p, robot, topics, period) for p in paths]
    segments = []
    if segment == "auto":
        for lg in logs:
            segments += segment_log(lg, motion)
    n_jumps = sum(lg.n_jumps for lg in logs)
    splits = parse_split(split, n_jumps)

    restored, checks, physical, stale, repairs = [], [], [], [], []
    for lg in logs:
        per_file = []
        for j, (a, b) in enumerate(lg.bounds()):
            found = stale_rows(f"{lg.path}, jump {j}", j, lg.q[a:b], lg.dq[a:b], lg.tau[a:b])
            if found and retime:
                done = retime_stale(lg.t[a:b], lg.q[a:b], lg.dq[a:b], lg.tau[a:b])
                for x in found:
                    x["retimed"] = done.get(x["group"], 0)
            per_file += found
        stale.append(per_file)
        back = restore_height(lg, robot, positions)
        restored += back
        if repair is not None:  # units first (a repair cannot undo degrees for radians), then the repair
            units = plausibility(lg, robot, replace(limits, height=(-math.inf, math.inf), torques="measured",
                                                    torque_factor=4 * limits.torque_factor))
            if units and not lenient:
                _refuse(units)
            repairs += repair_log(lg, robot, repair, physics, lenient, heights=positions != "absolute")
        problems = plausibility(lg, robot, limits)
        if problems and not lenient:
            _refuse(problems)
        checks.append(problems)
        found = [] if physics is None else consistency(lg, robot, physics, {r["jump"] for r in back})
        if found and not lenient:
            _refuse(found, "check")
        physical.append(found)

    timings = [[jump_timing(str(lg.path), j, lg.t[a:b], list(lg.lines[a:b]) if lg.lines is not None
                            else list(range(a, b)), time_base)
                for j, (a, b) in enumerate(lg.bounds())] for lg in logs]
    flat = [x for per_file in timings for x in per_file]
    for x in flat:
        check_gaps(x, time_base)
    dt = choose_dt(flat, time_base)

    parts: dict[str, list] = {k: [] for k in ("t", "q", "dq", "ddq", "tau", "contact", "jump")}
    jump_no = 0
    for lg, per_file in zip(logs, timings):
        for j, ((a, b), timing) in enumerate(zip(lg.bounds(), per_file)):
            t = lg.t[a:b]
            signals = {"q": lg.q[a:b], "dq": lg.dq[a:b], "tau": lg.tau[a:b],
                       "ddq": None if lg.ddq is None or j in lg.ddq_dropped else lg.ddq[a:b]}
            if on_grid(t, dt, time_base.grid_tol):
                timing.stored = "as logged"
                t_new, sig, contact = np.arange(t.size) * dt, signals, lg.contact[a:b]
            elif not time_base.resample:
                raise TimeBaseError(f"{timing.file}, jump {timing.jump}: logged every "
                                    f"{1e3 * timing.median_dt:.4g} ms (steps deviate up to "
                                    f"{100 * timing.max_deviation:.3g} %), not on the dataset's grid of "
                                    f"{1e3 * dt:.4g} ms; let the import resample it (not resample=False) "
                                    "or import it separately")
            else:
                timing.stored = "resampled"
                t_new, sig, contact = resample_jump(t, signals, lg.contact[a:b], dt)
            timing.rows_out = int(t_new.size)
            parts["t"].append(t_new)
            parts["contact"].append(contact)
            parts["jump"].append(np.full(t_new.size, jump_no, np.int32))
            for k in ("q", "dq", "tau"):
                parts[k].append(sig[k])
            parts["ddq"].append(sig["ddq"])
            jump_no += 1
    jump = np.concatenate(parts["jump"])
    t = np.concatenate(parts["t"])
    q, dq, tau = (np.concatenate(parts[k]) for k in ("q", "dq", "tau"))
    contact = np.concatenate(parts["contact"]).astype(np.uint8)
    window = diff_samples(diff_window, dt)
    ddq = differentiate(dq, dt, jump, diff_method, window=window)  # where a log has none
    row = 0
    for x, n in zip(parts["ddq"], (p.size for p in parts["t"])):
        if x is not None:
            ddq[row:row + n] = x
        row += n
    how = f"differentiated dq ({diff_method}, {diff_window:g} s: {window} samples)"
    generator = {
        "kind": "import",
        "files": [{"name": lg.path.name, "path": str(lg.path), "sha256": lg.sha256,
                   "layout": lg.layout, "rows": int(len(lg.t)), "jumps": lg.n_jumps,
                   "ddq": "logged" if lg.ddq is not None else how,
                   "checks": probs, "consistency": phys, "stale": st,
                   **({"time": {"column": False, "period": lg.period}} if lg.period is not None else {}),
                   **({"topics": lg.topics} if lg.topics else {})}
                  for lg, probs, phys, st in zip(logs, checks, physical, stale)],
        "options": {"robot": robot, "motion": motion, "source": source, "split": split,
                    "diff": diff_method, "diff_window": diff_window, "lenient": lenient,
                    "positions": positions, "limits": limits.to_dict(), "time_base": asdict(time_base),
                    "physics": None if physics is None else physics.to_dict(), "segment": segment,
                    "retime": retime, **({"topics": topics} if topics else {}),
                    **({"repair": repair.to_dict()} if repair is not None else {}),
                    **({"period": period} if period is not None else {})},
        "torques": limits.torques,
        "dt": dt,
        "time_base": {"dt": dt, "rule": "given (dt)" if time_base.dt is not None
                      else "the coarsest jump's period", "method": TIMEBASE_METHOD,
                      "jumps": [x.to_dict() for x in flat]},
        "rebased": restored,
        "segments": segments,
        **({"repairs": repairs_record(repairs, repair)} if repair is not None else {}),
    }
    ds = assemble(robot=robot, motion=motion, source=source, jump=jump, t=t, q=q, dq=dq,
                  tau=tau, contact=contact, ddq=ddq, split=splits, dt=dt,
                  generator=generator, diff_method=diff_method)
    return ds, ImportReport.from_generator(generator)


def import_into(out: str | os.PathLike, paths: list[str | os.PathLike], force: bool = False,
                **options) -> tuple[Dataset, ImportReport]:
    """``import_logs`` of ``paths`` written to the dataset file ``out`` (atomically; an existing
    file only with ``force``, never one of the logs); the dataset and the report."""
    from symrom.atomic import check_output_file
    from symrom.data.io import check_dataset_path, write_dataset

    check_dataset_path(out)
    check_output_file(out, force, inputs=tuple(paths))
    ds, report = import_logs([str(p) for p in paths], **options)
    write_dataset(ds, out)
    return ds, report


# ----------------------------------------------------------------- export

def write_plain_csv(ds: Dataset, path: str | os.PathLike, accelerations: bool = True) -> None:
    """Write ``ds``'s arrays to ``path`` in the plain layout (exact float round trip)."""
    from symrom.atomic import atomic_path

    cols = [ds.jump[:, None], ds.t[:, None], ds.q, ds.dq]
    names = [*PLAIN.jump, *PLAIN.t, *PLAIN.q, *PLAIN.dq]
    if accelerations:
        cols.append(ds.ddq)
        names += PLAIN.ddq
    cols += [ds.tau, ds.contact]
    names += [*PLAIN.tau, *PLAIN.contact]
    table = np.concatenate([np.asarray(c, dtype=float) for c in cols], axis=1)
    n_int = {0, len(names) - 4, len(names) - 3, len(names) - 2, len(names) - 1}
    with atomic_path(path, suffix=".csv") as tmp:
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(names)
            for row in table:
                w.writerow([str(int(v)) if i in n_int else repr(float(v)) for i, v in enumerate(row)])
