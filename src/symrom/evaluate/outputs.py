"""Writing evaluations: the one writer of ``metrics.json`` and ``table.md``, and the
evaluation and baseline folders built on it.

``metrics.json`` is strict JSON: a number that is not finite (NaN, infinity; e.g. an error
of a horizon at which no sample could be scored) is written as ``null``, never as the
``NaN`` token most JSON readers refuse.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.evaluate.plots import plot_jump
from symrom.evaluate.records import Metrics
from symrom.evaluate.tables import TABLE2_COMPONENTS, as_metrics, table2
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


def write_metrics(folder: str | Path, metrics: Metrics | dict, title: str = "",
                  components: tuple[str, ...] = TABLE2_COMPONENTS) -> list[Path]:
    """``metrics.json`` (``Metrics.to_dict``) and ``table.md`` (Table 2 of ``metrics`` over
    ``components``) in the existing directory ``folder``; the paths written."""
    folder = Path(folder)
    metrics = as_metrics(metrics)
    table = table2(metrics, components=components, title=title)
    if metrics.switching is not None:
        from symrom.evaluate.switching import switching_table

        table += "\nSwitching times, predicted phases (full horizon):\n\n" + switching_table(metrics.switching)
    write_text_atomic(folder / "table.md", table)
    return [write_json(folder / "metrics.json", metrics.to_dict()), folder / "table.md"]


def write_evaluation(out: Path, metrics: Metrics, rollouts: dict[str, Rollout], ds: Dataset,
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


def write_baseline(folder: str | Path, baseline, metrics: Metrics, title: str = "") -> list[Path]:
    """A baseline's folder in the existing directory ``folder``, the one writer of every
    baseline's files: its ``metrics.json`` and ``table.md`` over the components it predicts,
    and ``params.json`` (``baseline.to_dict()``, one format for every baseline). Returns the
    paths written."""
    folder = Path(folder)
    written = write_metrics(folder, metrics, title=title, components=tuple(baseline.components))
    written.append(write_json(folder / "params.json", baseline.to_dict()))
    return written


SPLITS = ("train", "val", "test")
INTEGRATORS = ("lsoda", "rk4")


def check_split_and_integrator(split: str, integrator: str) -> None:
    """ValueError naming ``split`` or ``integrator`` if it is not one of its choices."""
    if split not in SPLITS:
        raise ValueError(f"split={split!r}: choose train, val or test")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator={integrator!r}: choose lsoda or rk4")


@dataclass(frozen=True)
class Evaluation:
    """An evaluation written to ``out``: its metrics, the Table 2 title, the plotted jumps
    ``(k, dataset jump, file)`` (the k-th jump of the split, its index in the dataset, the PNG)
    and the components the model predicts (Table 2's columns)."""

    metrics: Metrics
    out: Path
    title: str = ""
    plots: tuple[tuple[int, int, Path], ...] = ()
    components: tuple[str, ...] = TABLE2_COMPONENTS

    def messages(self) -> list[tuple[bool, str]]:
        """The evaluation in words, in order: ``(is_warning, text)``: the table (and the switching
        times), the diverged and drifted jumps, the files."""
        out = [(False, table2(self.metrics, components=self.components, title=self.title))]
        if self.metrics.switching is not None:
            from symrom.evaluate.switching import switching_table

            out.append((False, "switching times, predicted phases (full horizon):\n"
                        + switching_table(self.metrics.switching)))
        out += [(True, w) for w in self.metrics.warnings()]
        out.append((False, f"metrics: {self.out / 'metrics.json'}"))
        split = self.metrics.split
        out += [(False, f"plot: {self.out / p.name}  ({split} jump {k}, dataset jump {j})") for k, j, p in self.plots]
        return out


def evaluate_into(out: str | Path, model_path: str | Path, data: str | Path, split: str = "test",
                  resets: tuple[float, ...] | None = None, integrator: str = "lsoda",
                  plot_jumps: tuple[int, ...] = (0,), phases: str = "logged", force: bool = False,
                  progress: Callable[[int, int], None] | None = None) -> Evaluation:
    """Roll the model file ``model_path`` out on ``split`` of the dataset file ``data`` at the
    full horizon and every reset period in ``resets`` (s; default 0.1), with ``integrator``
    and the ``phases`` (``logged`` or ``predicted``, rk4); write ``metrics.json``, ``table.md``
    and one ``jump_K.png`` per entry of ``plot_jumps`` (the k-th jumps of the split, K their
    index in the dataset) into the folder ``out`` (atomically; an existing folder only with
    ``force``, never one holding an input). Every option, the model and the data are checked
    before any work."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.data.io import read_dataset
    from symrom.evaluate.metrics import evaluate_model, horizons
    from symrom.evaluate.switching import PHASE_SOURCES
    from symrom.model.persistence import load_model
    from symrom.rollout.integrate import RolloutOptions

    out = Path(out)
    check_output_file(out, force, inputs=(model_path, data))
    check_split_and_integrator(split, integrator)
    if phases not in PHASE_SOURCES:
        raise ValueError(f"phases={phases!r}: choose {' or '.join(PHASE_SOURCES)}")
    if phases == "predicted" and integrator != "rk4":
        raise ValueError("phases='predicted' rolls out with rk4: integrator='rk4'")
    resets = horizons(resets)
    model = load_model(model_path)
    if phases == "predicted" and model.guards is None:
        raise ValueError(f"{model_path}: this model has no contact guards (model file format 3 or older): "
                         "train it again with this symrom, or use phases='logged'")
    ds = read_dataset(data)
    split_jumps = ds.jumps_in(split)
    if split_jumps.size == 0:
        raise ValueError(f"{data} has no {split!r} jumps")
    model.check_data(ds)  # robot, layout and phases: refused before any work starts
    model.phase_index(ds, ds.rows_of(split))
    bad = [k for k in plot_jumps if not 0 <= k < split_jumps.size]
    if bad:
        raise ValueError(f"plot_jumps={bad[0]}: counts the jumps of the {split} split, which has "
                         f"{split_jumps.size} (0..{split_jumps.size - 1})")
    plots = [int(split_jumps[k]) for k in plot_jumps]  # dataset jump indices
    metrics, rollouts = evaluate_model(model, ds, split, resets, RolloutOptions(method=integrator),
                                 model_name=str(model_path), data_name=str(data), progress=progress, phases=phases)
    with atomic_dir(out, force) as tmp:
        written = write_evaluation(tmp, metrics, rollouts, ds, plots, title=f"{ds.robot} {ds.motion} ({split})")
    return Evaluation(metrics, out, title="", plots=tuple((k, j, out / p.name) for k, j, p in
                                                          zip(plot_jumps, plots, written[2:])))


def baseline_into(out: str | Path, data: str | Path, name: str, split: str = "test",
                  resets: tuple[float, ...] | None = None, integrator: str = "lsoda", mass: float | None = None,
                  baseline=None, title: str | None = None, force: bool = False,
                  progress: Callable[[int, int], None] | None = None):
    """The baseline ``name`` (``symrom.baselines.BASELINES``, titled by it unless ``title``; or
    ``baseline``, already made)
    fitted on the train split of the dataset file ``data`` (mass ``mass`` kg, default the
    robot's) and evaluated on ``split`` at the full horizon and every reset period in
    ``resets`` (s; default 0.1): its folder ``out`` (``write_baseline``; atomically, an existing
    folder only with ``force``). Returns ``(baseline, Evaluation)``."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.baselines import BASELINES, fit_baseline
    from symrom.data.io import read_dataset
    from symrom.evaluate.metrics import evaluate_model, horizons
    from symrom.rollout.integrate import RolloutOptions

    out = Path(out)
    check_output_file(out, force, inputs=(data,))
    check_split_and_integrator(split, integrator)
    if baseline is None and name not in BASELINES:
        raise ValueError(f"baseline {name!r}: not one of {', '.join(BASELINES)}")
    resets = horizons(resets)
    ds = read_dataset(data)
    if ds.jumps_in(split).size == 0:
        raise ValueError(f"{data} has no {split!r} jumps")
    model = baseline if baseline is not None else fit_baseline(name, ds, m=mass)
    title = title or BASELINES.get(name, name)
    metrics, _ = evaluate_model(model, ds, split, resets, RolloutOptions(method=integrator), model_name=title,
                          data_name=str(data), progress=progress)
    title = f"{title}, {ds.robot} {ds.motion} ({split})"
    with atomic_dir(out, force) as tmp:
        write_baseline(tmp, model, metrics, title)
    return model, Evaluation(metrics, out, title, components=tuple(model.components))


def _jump_title(ds: Dataset, jump: int, title: str) -> str:
    """'go1 pronk (test): test jump 0 (dataset jump 13)': the split named is the jump's own."""
    split = str(ds.split[jump])
    k = int(list(ds.jumps_in(split)).index(jump))
    what = f"{split} jump {k} (dataset jump {jump})"
    return f"{title}: {what}" if title else what
