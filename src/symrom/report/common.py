"""Sections every report has, whatever the run holds: its experiments, data and provenance."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from symrom.names import SPLITS
from symrom.report.document import Link, Para, Pre, Table
from symrom.report.run import Run


def file_link(run: Run, rel: str, base: Path | None, text: str | None = None) -> Link | str:
    """A link to the run's file ``rel`` (relative to the run directory, or absolute) from
    the folder ``base`` the report is written in; plain text without ``base``."""
    text = rel if text is None else text
    if base is None:
        return text
    target = Path(rel) if Path(rel).is_absolute() else run.dir / rel
    return Link(text, Path(os.path.relpath(target.resolve(), Path(base).resolve())).as_posix())


def experiments_blocks(run: Run, base: Path | None = None) -> list:
    """The manifest as a table: what this run holds and how each entry is shown; its files
    are links relative to ``base``, the report's folder."""
    if not run.entries:
        return [Para("This run lists no experiments.", note=True)]
    rows = [[e.name, e.role, e.title or "", e.of or "",
             [file_link(run, v, base, f"{k}: {v}") for k, v in e.files.items()] or ""]
            for e in run.entries]
    return [Table(["experiment", "role", "title", "of", "files"], rows)]


def dataset_row(path: Path, ds) -> list[str]:
    """File, robot, motion, source, dt, jumps per split, samples per jump and, per phase,
    the mean time per jump and its number of segments."""
    bounds = ds.jump_bounds()
    per_phase = []
    for k, name in enumerate(ds.phase_names):
        tot, segs = [], []
        for a, b in bounds:
            m = ds.phase[a:b] == k
            tot.append(m.sum() * ds.dt)
            segs.append(int(np.sum(np.diff(np.r_[0, m.astype(int)]) == 1)))
        per_phase.append(f"{name} {np.mean(tot):.3f} s ({np.mean(segs):.3g} seg.)")
    splits = " / ".join(str(int((ds.split == s).sum())) for s in SPLITS)
    robot = Path(ds.robot).stem if ds.robot.endswith(".toml") else ds.robot  # a description file
    return [path.name, robot, ds.motion, ds.source, f"{ds.dt:g}", f"{ds.n_jumps} ({splits})",
            f"{np.mean(bounds[:, 1] - bounds[:, 0]):.0f}", "; ".join(per_phase)]


def data_blocks(run: Run, base: Path | None = None) -> list:
    files = run.dataset_files()
    if not files:
        return [Para("No dataset files in this run (data/*.h5).", note=True)]
    rows = [[file_link(run, str(p), base, p.name), *dataset_row(p, ds)[1:]]
            for p in files if (ds := run.dataset_at(p)) is not None]
    return [Table(["file", "robot", "motion", "source", "dt [s]", "jumps (train / val / test)",
                   "samples per jump", "phases: mean time per jump (segments)"], rows)]


def run_blocks(run: Run) -> list:
    r = run.summary.get("run") or {}
    if run.kind == "model folder":
        files = "; ".join(f"{k}: {v}" for e in run.entries for k, v in e.files.items())
        return [Para(f"A model folder (symrom train, evaluate), not a reproduction run: its files are {files}. "
                     "The training options are in model.json (provenance), the evaluation's in its metrics.json.")]
    if not isinstance(r, dict) or not r:
        return [Para("summary.json has no 'run' entry: commands, versions and seeds unknown.", note=True)]
    blocks: list = [Pre(str(r.get("command") or "(command not recorded)"), caption="Command that produced this run")]
    versions = r.get("versions") or {}
    want = ["python", "numpy", "scipy", "pybullet", "symrom"]
    vrows = [[k, str(versions[k]) if k in versions else "not recorded"] for k in want]
    vrows += [[k, str(v)] for k, v in versions.items() if k not in want]
    blocks.append(Table(["package", "version"], vrows, caption="Versions"))
    blocks.append(Pre(json.dumps(r.get("seeds", {}), indent=1, sort_keys=True), caption="Seeds"))
    if isinstance(r.get("wall_time_s"), (int, float)):
        blocks.append(Para(f"Wall time of the run: {float(r['wall_time_s']):.1f} s."))
    if r.get("config"):
        rows = [[k, v] for k, v in flatten(r["config"])]
        blocks.append(Table(["setting", "value"], rows, caption="Configuration of the run", collapsed=True))
    return blocks


def flatten(value, prefix: str = "") -> list[tuple[str, str]]:
    """(dotted key, value) pairs of a nested JSON value: ``datasets[0].jumps``, ``seed``;
    a list of plain values stays one comma-separated value."""
    if isinstance(value, dict):
        return [kv for k, v in sorted(value.items()) for kv in flatten(v, f"{prefix}.{k}" if prefix else str(k))]
    if isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        return [kv for i, v in enumerate(value) for kv in flatten(v, f"{prefix}[{i}]")]
    if isinstance(value, list):
        return [(prefix, ", ".join(v if isinstance(v, str) else json.dumps(v, default=str) for v in value) or "[]")]
    return [(prefix, value if isinstance(value, str) else json.dumps(value, default=str))]
