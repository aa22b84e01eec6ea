"""Sections every report has, whatever the run holds: its experiments, data and provenance."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from symrom.names import SPLITS
from symrom.report.document import Para, Pre, Table
from symrom.report.run import Run


def experiments_blocks(run: Run) -> list:
    """The manifest as a table: what this run holds and how each entry is shown."""
    if not run.entries:
        return [Para("This run lists no experiments.", note=True)]
    rows = [[e.name, e.role, e.title or "", e.of or "", ", ".join(f"{k}: {v}" for k, v in e.files.items())]
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


def data_blocks(run: Run) -> list:
    files = run.dataset_files()
    if not files:
        return [Para("No dataset files in this run (data/*.h5).", note=True)]
    rows = [dataset_row(p, ds) for p in files if (ds := run.dataset_at(p)) is not None]
    return [Table(["file", "robot", "motion", "source", "dt [s]", "jumps (train / val / test)",
                   "samples per jump", "phases: mean time per jump (segments)"], rows)]


def run_blocks(run: Run) -> list:
    r = run.summary.get("run") or {}
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
        blocks.append(Pre(json.dumps(r["config"], indent=1, sort_keys=True, default=str), caption="Configuration"))
    return blocks
