"""``ImportReport``: what an import found and did, as a typed record.

The dataset keeps the import's record as its ``generator`` attribute (JSON, the dataset file's
format, unchanged); ``ImportReport.from_generator`` reads that record into the types below,
and ``import_logs`` returns one beside the dataset. ``messages()`` says it in words, in the
order a reader needs it: values kept as logged (``lenient``), the topics read, failed
physical checks, stale rows, segments, the torques, rebased positions, the time base.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Implausible:
    """A column of one log outside its plausible range (kept as logged with ``lenient``):
    its header in the file, where it first fails (jump, row within the jump, line of the
    file), how many rows fail, the range (``low``, ``high`` in ``unit``, None for unbounded)
    and what set it (``limit``), the worst value and the likely unit mistake (``hint``)."""

    header: str
    jump: int
    row: int
    line: int | None
    rows: int
    low: float | None
    high: float | None
    unit: str
    limit: str
    worst: float
    hint: str | None

    @classmethod
    def from_dict(cls, d: dict) -> Implausible:
        return cls(str(d["header"]), int(d["jump"]), int(d["row"]), d.get("line"), int(d["rows"]), d.get("low"),
                   d.get("high"), str(d["unit"]), str(d["limit"]), float(d["worst"]), d.get("hint"))

    def text(self) -> str:
        return (f"column {self.header!r} (first at jump {self.jump}, row {self.row}, line {self.line}): {self.rows} "
                f"rows outside [{self.low}, {self.high}] {self.unit} ({self.limit}), worst {self.worst:.6g}"
                + (f"; it looks like {self.hint}" if self.hint else ""))


@dataclass(frozen=True)
class StaleRows:
    """Rows of one jump repeating the previous row's ``group`` exactly; ``retimed``: how many
    were re-timed by interpolation (None: not asked)."""

    jump: int
    group: str
    message: str
    retimed: int | None = None

    def text(self) -> str:
        done = (f"; {self.retimed} re-timed by interpolation between the fresh rows" if self.retimed is not None
                else "; retime=True interpolates them between the fresh rows")
        return f"stale rows: {self.message}{done}"


@dataclass(frozen=True)
class ImportedFile:
    """One log file: its name, layout, the bag topics read (None for a CSV log), the
    columns kept implausible, the failed physical checks (their messages) and its stale rows."""

    name: str
    layout: str
    topics: dict[str, Any] | None
    implausible: tuple[Implausible, ...]
    inconsistent: tuple[str, ...]
    stale: tuple[StaleRows, ...]


@dataclass(frozen=True)
class Segment:
    """One jump cut from a recording: its time span and its flight's (s, of the recording's jump)."""

    t: tuple[float, float]
    flight: tuple[float, float]


@dataclass(frozen=True)
class Segmentation:
    """A logged jump holding several flights, cut into one jump per flight."""

    file: str
    jump: int
    segments: tuple[Segment, ...]

    def text(self) -> str:
        n = len(self.segments)
        return (f"segments: {self.file} jump {self.jump} holds {n} flights, cut into {n} jumps: " + ", ".join(
            f"t {s.t[0]:.3f}-{s.t[1]:.3f} s (flight {s.flight[0]:.3f}-{s.flight[1]:.3f} s)" for s in self.segments))


@dataclass(frozen=True)
class Rebased:
    """A jump whose logged base positions started at 0: its height ``z_offset`` (m) back, and how."""

    file: str
    jump: int
    z_offset: float
    how: str


@dataclass(frozen=True)
class JumpTime:
    """One jump's time base: the file, jump, median step (s), steps more than 10 % off
    (``jitter_steps``, the largest relative deviation), the gaps bridged (``(t, length)`` s)
    and whether it was stored ``as logged`` or ``resampled``."""

    file: str
    jump: int
    median_dt: float
    jitter_steps: int
    max_deviation: float
    gaps: tuple[tuple[float, float], ...]
    stored: str


@dataclass(frozen=True)
class TimeBaseReport:
    """The dataset's period ``dt`` (s), the rule that set it, and every jump's timing."""

    dt: float
    rule: str
    jumps: tuple[JumpTime, ...]


@dataclass(frozen=True)
class ImportReport:
    """What an import found and did (module docstring)."""

    files: tuple[ImportedFile, ...]
    segments: tuple[Segmentation, ...] = ()
    torques: str | None = None
    rebased: tuple[Rebased, ...] = ()
    time_base: TimeBaseReport | None = None
    repairs: tuple[str, ...] = ()  # one line per repaired jump (``repair.JumpRepair.line``)

    @classmethod
    def from_generator(cls, g: dict) -> ImportReport:
        """The report of an import's record (a dataset's ``generator`` attribute)."""
        files = tuple(ImportedFile(
            str(f["name"]), str(f.get("layout", "")), f.get("topics") or None,
            tuple(Implausible.from_dict(p) for p in f.get("checks") or []),
            tuple(str(p["message"]) for p in f.get("consistency") or []),
            tuple(StaleRows(int(s.get("jump", 0)), str(s.get("group", "")), str(s["message"]), s.get("retimed"))
                  for s in f.get("stale") or []))
            for f in g.get("files", []))
        segments = tuple(Segmentation(str(s["file"]), int(s["jump"]), tuple(
            Segment(tuple(x["t"]), tuple(x["flight"])) for x in s["segments"])) for s in g.get("segments") or [])
        rebased = tuple(Rebased(str(r["file"]), int(r["jump"]), float(r["z_offset"]), str(r["from"]))
                        for r in g.get("rebased") or [])
        tb = g.get("time_base")
        time_base = None if not tb else TimeBaseReport(float(tb["dt"]), str(tb["rule"]), tuple(
            JumpTime(str(j["file"]), int(j["jump"]), float(j["median_dt"]), int(j["jitter_steps"]),
                     float(j["max_deviation"]), tuple((float(x["t"]), float(x["length"])) for x in j["gaps"]),
                     str(j["stored"])) for j in tb["jumps"]))
        repairs = tuple(str(r["line"]) for r in (g.get("repairs") or {}).get("jumps", []))
        return cls(files, segments, g.get("torques"), rebased, time_base, repairs)

    def messages(self) -> list[tuple[bool, str]]:
        """The report in words, in order: ``(is_warning, line)``."""
        out: list[tuple[bool, str]] = []
        for f in self.files:
            if f.implausible:
                out.append((True, f"{f.name}: {len(f.implausible)} column(s) fail the plausibility checks; kept "
                                  "as logged (lenient=True):"))
                out += [(False, "  " + p.text()) for p in f.implausible]
        for f in self.files:
            if f.topics:
                tp = f.topics
                out.append((False, f"{f.name}: {f.layout}, joints {tp['joints']}, base {tp['base']}, contacts "
                                   f"{tp['contacts']}"))
            out += [(True, f"kept as logged (lenient=True): {m}") for m in f.inconsistent]
            out += [(True, s.text()) for s in f.stale]
        out += [(False, s.text()) for s in self.segments]
        if self.torques:
            out.append((False, f"torques: {self.torques}"))
        out += [(False, f"repair: {line}") for line in self.repairs]
        if self.rebased:
            offsets = [r.z_offset for r in self.rebased]
            how = sorted({r.how for r in self.rebased})
            out.append((False, f"positions: {len(self.rebased)} jump(s) start at z = 0 (rebased); z raised by "
                               f"{min(offsets):.4g}..{max(offsets):.4g} m so that " + "; ".join(how)))
        tb = self.time_base
        if tb:
            moved = [j for j in tb.jumps if j.stored == "resampled"]
            jitter = [j for j in tb.jumps if j.jitter_steps]
            gaps = [(j, x) for j in tb.jumps for x in j.gaps]
            line = f"time base: dt {tb.dt:g} s ({tb.rule}); "
            line += (f"{len(moved)} of {len(tb.jumps)} jumps resampled to it (modified Akima; contact flags by the "
                     f"nearest sample): " + ", ".join(f"{Path(j.file).name} jump {j.jump} "
                                                      f"(logged every {1e3 * j.median_dt:.4g} ms)" for j in moved[:6])
                     + (" ..." if len(moved) > 6 else "") if moved else "every jump is on it, stored as logged")
            out.append((False, line))
            if jitter:
                out.append((True, f"jitter: {len(jitter)} jump(s) have steps more than 10 % off their median "
                                  f"(up to {100 * max(j.max_deviation for j in jitter):.3g} %)"))
            if gaps:
                out.append((True, "gaps bridged by interpolation: " + ", ".join(
                    f"{Path(j.file).name} jump {j.jump}: {1e3 * length:.3g} ms after t = {t:.3f} s"
                    for j, (t, length) in gaps[:6]) + (" ..." if len(gaps) > 6 else "")))
        return out
