"""A resumable keyed grid: the cells of a sweep or of a selection, run as tasks on an
execution back end, each stored as it finishes and reused on a resumed run.

A cell is stored as one JSON file (``path(cell)``) holding ``key(cell)``, a hash of
everything its result depends on; a stored cell is reused only when it parses and its
key matches (``load_cell``), else it runs again. What a stored file holds besides the key
(``record``) and how the result is read back from it (``value``) is the caller's.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from symrom.evaluate.outputs import write_json
from symrom.execution import Backend


def load_cell(path: Path, key: str) -> dict[str, Any] | None:
    """The stored cell (a JSON object) if it exists, parses and carries ``key``; else None
    (recompute)."""
    try:
        cell = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return cell if isinstance(cell, dict) and cell.get("key") == key else None


@dataclass
class Store:
    """Where and how a grid keeps its cells. path(cell) -> file; key(cell) -> its hash;
    record(cell, result, key, execution) -> the JSON object stored (must hold ``key``);
    value(stored object) -> the result it holds."""

    path: Callable[[Any], Path]
    key: Callable[[Any], str]
    record: Callable[[Any, Any, str, dict[str, Any]], dict[str, Any]]
    value: Callable[[dict[str, Any]], Any]


@dataclass
class GridRun:
    """results: per cell its result, in the grid's order; ran: the cells run now (the others
    were reused); retries: per cell run now, the attempts lost to dying workers."""

    results: dict[Any, Any]
    ran: list[Any]
    retries: dict[Any, list[dict[str, Any]]] = field(default_factory=dict)


# progress(cells done, cells in total, the cell, the finished task or None if reused)
GridProgress = Callable[[int, int, Any, Any], None]


def run_grid(cells: Sequence[Hashable], task: Callable, args: tuple, backend: Backend, label: str,
             store: Store | None = None, order: Callable[[Any], Any] | None = None,
             progress: GridProgress | None = None, preload: Sequence[str] = ()) -> GridRun:
    """``task(*args, *cell)`` for every cell (a tuple) on ``backend``; with ``store``, the
    cells stored with a matching key are reused and every cell run is stored as it
    finishes (strict JSON, atomically). ``order``: sort key of the cells to run (e.g. the
    longest first, so that the workers stay busy to the end); ``preload``: modules a fresh
    worker imports before its first cell (``Backend.map``)."""
    tell = progress or (lambda done, total, cell, t: None)
    results: dict[Any, Any] = {}
    todo = []
    for c in cells:
        stored = load_cell(store.path(c), store.key(c)) if store is not None else None
        if stored is None:
            todo.append(c)
        else:
            results[c] = store.value(stored)
            tell(len(results), len(cells), c, None)
    if order is not None:
        todo.sort(key=order)
    retries = {}
    for t in backend.map(task, [(c, c) for c in todo], args, label=label, preload=preload):
        results[t.key] = t.value
        retries[t.key] = t.retries
        if store is not None:
            execution = {"backend": backend.name, "worker": t.worker, "retries": t.retries}
            store.path(t.key).parent.mkdir(parents=True, exist_ok=True)
            write_json(store.path(t.key), store.record(t.key, t.value, store.key(t.key), execution))
        tell(len(results), len(cells), t.key, t)
    return GridRun({c: results[c] for c in cells}, todo, retries)
