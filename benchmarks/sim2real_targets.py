"""``symrom reproduce``'s sim-to-real at its targets' full size on smaller sources (not a test).

    python benchmarks/sim2real_targets.py --run runs/s2r_mid --sources 40 --workers 2

The quick run's SIM Go1 and SIM A1 selections (``ReproduceConfig.quick``: their settings are what
the sources are trained with) and its datasets, but every sim-to-real target at the full run's
size, 24 jumps (12 train, 4 val, 8 test: the 12 real-like jumps the targets are judged on), and
each source (the noisy and the randomised Go1, the randomised A1 froggy) of ``--sources``
jumps. The run is ``symrom reproduce --only sim2real``'s (``experiments.reproduce.reproduce``):
each target logged with its faults, imported through the repair, fine-tuned and set beside a
model of its repaired jumps alone; it prints the side-by-side table and the targets' lines as
``reproduce`` does and leaves ``summary.json`` and the report's files in ``--run`` (resumable).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

from symrom.experiments.reproduce.config import ReproduceConfig
from symrom.experiments.reproduce.run import reproduce, summary_lines
from symrom.experiments.reproduce.sim2real import SIM2REAL, SIM2REAL_SOURCES
from symrom.report.sim2real import sim2real_markdown

TARGET_JUMPS, TARGET_SPLITS = 24, (12, 4, 8)


def config(sources: int, workers: int) -> ReproduceConfig:
    """The quick configuration with full-size targets and sources of ``sources`` jumps."""
    quick = ReproduceConfig.quick()
    targets = {t.name for t in SIM2REAL}
    source_sets = set(SIM2REAL_SOURCES.values())
    specs = tuple(replace(d, jumps=TARGET_JUMPS, splits=TARGET_SPLITS) if d.name in targets
                  else replace(d, jumps=sources) if d.name in source_sets else d for d in quick.datasets)
    return replace(quick, datasets=specs, workers=workers)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run", type=Path, required=True, help="run directory (resumable)")
    ap.add_argument("--sources", type=int, default=40, help="jumps of each source dataset")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    t0 = time.perf_counter()

    def say(message: str, transient: bool = False) -> None:
        if not transient:
            print(f"[{time.perf_counter() - t0:7.1f} s] {message}", flush=True)

    summary = reproduce(args.run, config(args.sources, args.workers), command="benchmarks/sim2real_targets.py",
                        say=say, only="sim2real")
    print("\n".join(summary_lines(summary)))
    print(sim2real_markdown(summary["sim2real"]["targets"]))
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
