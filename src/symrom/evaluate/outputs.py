"""Writing an evaluation to a directory: metrics.json, table.md and jump plots."""

from __future__ import annotations

import json
from pathlib import Path

from symrom.data.dataset import Dataset
from symrom.evaluate.plots import plot_jump
from symrom.evaluate.tables import table2
from symrom.rollout.integrate import Rollout


def write_evaluation(out: Path, metrics: dict, rollouts: dict[str, Rollout], ds: Dataset,
                     plot_jumps: list[int] | None = None, title: str = "") -> list[Path]:
    """Write ``metrics.json``, ``table.md`` and one ``jump_K.png`` per plotted jump
    into the directory ``out``; ``plot_jumps`` are dataset jump indices (K in the file
    name), each titled with its split and its position in that split. Returns the paths
    written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "metrics.json", out / "table.md"]
    written[0].write_text(json.dumps(metrics, indent=1, allow_nan=False))
    written[1].write_text(table2(metrics, title=title))
    for j in plot_jumps if plot_jumps is not None else list(rollouts.values())[0].jumps[:1]:
        p = out / f"jump_{int(j)}.png"
        plot_jump(ds, rollouts, int(j), p, title=_jump_title(ds, int(j), title))
        written.append(p)
    return written


def _jump_title(ds: Dataset, jump: int, title: str) -> str:
    """'go1 pronk (test): test jump 0 (dataset jump 13)': the split named is the jump's own."""
    split = str(ds.split[jump])
    k = int(list(ds.jumps_in(split)).index(jump))
    what = f"{split} jump {k} (dataset jump {jump})"
    return f"{title}: {what}" if title else what
