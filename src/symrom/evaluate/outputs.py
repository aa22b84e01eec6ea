"""Writing evaluations: the one writer of ``metrics.json`` and ``table.md``, and the
evaluation and baseline folders built on it.

``metrics.json`` is strict JSON: a number that is not finite (NaN, infinity; e.g. an error
of a horizon at which no sample could be scored) is written as ``null``, never as the
``NaN`` token most JSON readers refuse.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.evaluate.plots import plot_jump
from symrom.evaluate.tables import TABLE2_COMPONENTS, table2
from symrom.rollout.integrate import Rollout


def finite_or_null(obj: Any) -> Any:
    """``obj`` (JSON-ready) with every non-finite float replaced by None."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_null(v) for v in obj]
    return obj


def write_json(path: str | Path, obj: Any) -> Path:
    """``obj`` as strict JSON (non-finite numbers as null), atomically."""
    write_text_atomic(path, json.dumps(finite_or_null(obj), indent=1, allow_nan=False) + "\n")
    return Path(path)


def write_metrics(folder: str | Path, metrics: dict, title: str = "",
                  components: tuple[str, ...] = TABLE2_COMPONENTS) -> list[Path]:
    """``metrics.json`` and ``table.md`` (Table 2 of ``metrics`` over ``components``) in the
    existing directory ``folder``; the paths written."""
    folder = Path(folder)
    table = table2(metrics, components=components, title=title)
    if metrics.get("switching") is not None:
        from symrom.evaluate.switching import switching_table

        table += "\nSwitching times, predicted phases (full horizon):\n\n" + switching_table(metrics["switching"])
    write_text_atomic(folder / "table.md", table)
    return [write_json(folder / "metrics.json", metrics), folder / "table.md"]


def write_evaluation(out: Path, metrics: dict, rollouts: dict[str, Rollout], ds: Dataset,
                     plot_jumps: list[int] | None = None, title: str = "") -> list[Path]:
    """Write ``metrics.json``, ``table.md`` and one ``jump_K.png`` per plotted jump
    into the directory ``out``; ``plot_jumps`` are dataset jump indices (K in the file
    name), each titled with its split and its position in that split. Returns the paths
    written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = write_metrics(out, metrics, title=title)
    for j in plot_jumps if plot_jumps is not None else list(rollouts.values())[0].jumps[:1]:
        p = out / f"jump_{int(j)}.png"
        plot_jump(ds, rollouts, int(j), p, title=_jump_title(ds, int(j), title))
        written.append(p)
    return written


def write_baseline(folder: str | Path, metrics: dict, components: tuple[str, ...], title: str,
                   files: dict[str, str] | None = None) -> list[Path]:
    """A baseline's folder in the existing directory ``folder``: its ``metrics.json`` and
    ``table.md`` over the components it predicts, and ``files`` (name -> text, e.g. its
    ``params.json``). Returns the paths written."""
    folder = Path(folder)
    written = write_metrics(folder, metrics, title=title, components=components)
    for name, text in (files or {}).items():
        write_text_atomic(folder / name, text)
        written.append(folder / name)
    return written


def _jump_title(ds: Dataset, jump: int, title: str) -> str:
    """'go1 pronk (test): test jump 0 (dataset jump 13)': the split named is the jump's own."""
    split = str(ds.split[jump])
    k = int(list(ds.jumps_in(split)).index(jump))
    what = f"{split} jump {k} (dataset jump {jump})"
    return f"{title}: {what}" if title else what
