"""Part files: each finished jump saved at once, so an interrupted generation resumes.

``OUT.parts/jump_00012.npz`` holds one jump's log arrays and a JSON ``meta``
string (the options' fingerprint, the jump's record and how its task ran: wall
time, worker, attempts lost to a dying worker); plain npz, no pickle, written
atomically by the driver (tasks return arrays, never files).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

LOG_KEYS = ("t", "q", "dq", "tau", "contact", "foot_pos", "contact_force")


def jsonable(x: Any) -> Any:
    """``x`` with numpy arrays and scalars turned into lists and Python numbers."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def parts_dir(out: str | os.PathLike) -> Path:
    """Sidecar folder of per-jump part files of ``out``."""
    return Path(str(out) + ".parts")


def part_path(parts: Path, jump: int) -> Path:
    return parts / f"jump_{jump:05d}.npz"


def write_part(path: Path, log: dict[str, np.ndarray], record: dict, fingerprint: str,
               execution: dict | None = None) -> None:
    """Write one jump's part atomically (npz, no pickle); ``execution``: how its task ran."""
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    meta = json.dumps({"fingerprint": fingerprint, "record": jsonable(record),
                       "execution": jsonable(execution)}, sort_keys=True)
    np.savez(tmp, meta=np.array(meta), **log)
    os.replace(tmp, path)


def read_part(path: Path) -> tuple[dict[str, np.ndarray], dict, str, dict | None]:
    """One jump's log arrays, record, options' fingerprint and how its task ran (seconds, worker,
    retries; None if not recorded)."""
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        log = {k: z[k] for k in LOG_KEYS}
    return log, meta["record"], meta["fingerprint"], meta.get("execution")
