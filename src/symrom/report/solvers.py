"""Renderer of the solver comparison: one row per solver entry (training of the same data)."""

from __future__ import annotations

from symrom.evaluate.records import ManifestEntry
from symrom.report.context import Context
from symrom.report.document import Table
from symrom.report.format import DASH, fmt
from symrom.report.run import Run


def solver_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    rows = []
    for e in entries:
        metrics, model = run.metrics(e), run.model(e)
        full = metrics.horizons.get("full") if metrics else None
        mae = [full.stat(c, "mae") if full else None for c in ("x", "z")]
        wall = e.facts.get("wall_time_s")
        rows.append([e.title or e.name, DASH if wall is None else f"{wall:.3g}",
                     ", ".join(f"{k} {v}" for k, v in model.active_terms().items()) if model else DASH,
                     *(DASH if m is None else fmt(m) for m in mae),
                     f"{full.diverged_jumps} of {metrics.n_jumps}" if full else DASH])
    of = sorted({e.of for e in entries if e.of})
    return [Table(["solver", "training wall time [s]", "active terms", "full CoM x MAE [m]",
                   "full CoM z MAE [m]", "diverged (full)"], rows,
                  caption=f"Solvers on {', '.join(of)}" if of else "Solvers")]
