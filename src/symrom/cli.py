"""The ``symrom`` command line: parses, calls the library, prints.

Every command exits non-zero with one clear line on bad input (a traceback
only with ``--debug``), writes its outputs atomically and never overwrites an
existing output without ``--force``.
"""

from __future__ import annotations

import functools
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Symbolic reduced-order models of legged-robot jumping, learned from data.")
console = Console(stderr=True)
out_console = Console()

_STATE = {"debug": False}

Force = Annotated[bool, typer.Option("--force", help="Overwrite an existing output.")]


@app.callback()
def _main(debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks on errors.")] = False) -> None:
    _STATE["debug"] = debug


def guarded(fn: Callable) -> Callable:
    """Turn library errors into one red line and exit code 1 (tracebacks with --debug)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except typer.Exit:
            raise
        except KeyboardInterrupt:
            console.print("[red]interrupted[/red]")
            raise typer.Exit(130) from None
        except Exception as e:  # noqa: BLE001 - the CLI boundary
            if _STATE["debug"]:
                raise
            msg = str(e).strip().splitlines()[0] if str(e).strip() else e.__class__.__name__
            console.print(f"[red]error:[/red] {msg}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None

    return wrapper


def progress_bar() -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                    TimeElapsedColumn(), console=console, transient=False)


def _parse_resets(reset: list[float] | None) -> tuple[float | None, ...]:
    return (None, *sorted(set(reset or [0.1])))


@app.command("import")
@guarded
def import_cmd(
    logs: Annotated[list[Path], typer.Argument(help="CSV log file(s); several are concatenated as consecutive jumps.")],
    robot: Annotated[str, typer.Option("--robot", help="Robot of the logs (go1 or a1); its URDF gives the wrench.")],
    out: Annotated[Path, typer.Option("--out", help="Output dataset file (HDF5).")],
    motion: Annotated[str, typer.Option("--motion", help="Motion (pronk, froggy); sets the phase rule.")] = "pronk",
    source: Annotated[str, typer.Option("--source", help="Source attribute of the dataset.")] = "hardware",
    split: Annotated[Optional[str], typer.Option("--split", help="train,val,test counts (12,2,1) or fractions (0.8,0.1,0.1); default all train.")] = None,
    diff: Annotated[str, typer.Option("--diff", help="savgol or central: differentiation where a log has no accelerations.")] = "savgol",
    force: Force = False,
) -> None:
    """Import CSV robot logs (Go1 hardware layout or plain layout) into a dataset file."""
    from symrom.data.importers import import_logs
    from symrom.data.io import check_output_file, write_dataset

    check_output_file(out, force)
    resolved = {p.resolve() for p in logs}
    if out.resolve() in resolved:
        raise ValueError(f"--out {out} is one of the input logs")
    with console.status(f"importing {len(logs)} log file(s)"):
        ds = import_logs([str(p) for p in logs], robot=robot, motion=motion, source=source,
                         split=split, diff_method=diff)
        write_dataset(ds, out)
    counts = ", ".join(f"{s} {int((ds.split == s).sum())}" for s in ("train", "val", "test"))
    out_console.print(f"dataset: {out}  ({ds.n_jumps} jumps, {ds.n_samples} samples, dt {ds.dt:g} s, "
                      f"phases {', '.join(ds.phase_names)}; {counts})", highlight=False, soft_wrap=True)


@app.command("train")
@guarded
def train_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (model.json, equations.txt).")],
    latent_dim: Annotated[int, typer.Option("--latent-dim", help="Latent dimension l.")] = 2,
    poly_order: Annotated[int, typer.Option("--poly-order", help="Polynomial order p of the library.")] = 1,
    solver: Annotated[str, typer.Option("--solver", help="exact (closed form) or adam (torch).")] = "exact",
    threshold: Annotated[float, typer.Option("--threshold", help="Sparsity threshold on |Xi|.")] = 0.01,
    epochs: Annotated[Optional[int], typer.Option("--epochs", help="adam: epochs (default 501).")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed (adam initialisation).")] = 0,
    force: Force = False,
) -> None:
    """Train a hybrid symbolic model on the dataset's train split."""
    from symrom.data.io import atomic_dir, check_output_file, read_dataset
    from symrom.model.persistence import save_model
    from symrom.model.training import AdamConfig, TrainConfig, train

    check_output_file(out, force)
    adam = AdamConfig() if epochs is None else AdamConfig(epochs=epochs)
    config = TrainConfig(latent_dim=latent_dim, poly_order=poly_order, solver=solver,
                         threshold=threshold, seed=seed, adam=adam)
    ds = read_dataset(data)
    with progress_bar() as bar:
        task = bar.add_task("training", total=1.0)
        model = train(ds, config, progress=lambda stage, frac: bar.update(
            task, completed=frac, description=f"training: {stage}"))
    model.info["data_path"] = str(data)
    with atomic_dir(out, force) as tmp:
        save_model(model, tmp / "model.json")
        (tmp / "equations.txt").write_text(model.equations_text() + "\n")
    terms = ", ".join(f"{k} {v}" for k, v in model.active_terms().items())
    out_console.print(f"model: {out / 'model.json'}  (l={latent_dim}, p={poly_order}, "
                      f"{model.library.n_features} candidates; active terms: {terms})")


@app.command("evaluate")
@guarded
def evaluate_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory.")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    reset: Annotated[Optional[list[float]], typer.Option("--reset", help="Reset period(s) in s (repeatable).")] = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda (the paper's) or rk4 (batch).")] = "lsoda",
    plot_jump: Annotated[Optional[list[int]], typer.Option("--plot-jump", help="Jump index to plot (repeatable).")] = None,
    force: Force = False,
) -> None:
    """Roll the model out on a split (full horizon and periodic resets); write metrics, table, plots."""
    from symrom.data.io import atomic_dir, check_output_file, read_dataset
    from symrom.evaluate.metrics import evaluate
    from symrom.evaluate.outputs import write_evaluation
    from symrom.evaluate.tables import table2
    from symrom.model.persistence import load_model
    from symrom.rollout.integrate import RolloutOptions

    check_output_file(out, force)
    model = load_model(model_path)
    ds = read_dataset(data)
    if split not in ("train", "val", "test"):
        raise ValueError(f"--split must be train, val or test, got {split!r}")
    if ds.jumps_in(split).size == 0:
        raise ValueError(f"{data} has no {split!r} jumps")
    if plot_jump:
        bad = [j for j in plot_jump if not 0 <= j < ds.n_jumps]
        if bad:
            raise ValueError(f"--plot-jump {bad[0]}: the dataset has jumps 0..{ds.n_jumps - 1}")
    resets = _parse_resets(reset)
    with progress_bar() as bar:
        task = bar.add_task("rollouts", total=len(resets) * ds.jumps_in(split).size)
        done = {"n": 0, "last": 0}

        def tick(i, n):
            if i < done["last"]:
                done["n"] += done["last"]
            done["last"] = i
            bar.update(task, completed=done["n"] + i)

        metrics, rollouts = evaluate(model, ds, split, resets, RolloutOptions(method=integrator),
                                     model_name=str(model_path), data_name=str(data), progress=tick)
    plots = plot_jump if plot_jump else [int(ds.jumps_in(split)[0])]
    with atomic_dir(out, force) as tmp:
        write_evaluation(tmp, metrics, rollouts, ds, plots, title=f"{ds.robot} {ds.motion} ({split})")
    typer.echo(table2(metrics))
    for key, h in metrics["horizons"].items():
        if h["diverged_jumps"]:
            console.print(f"[yellow]warning:[/yellow] {h['diverged_jumps']} of {metrics['n_jumps']} "
                          f"jumps diverged at horizon {key}; they are excluded from the statistics")
    out_console.print(f"metrics: {out / 'metrics.json'}")


@app.command("equations")
@guarded
def equations_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    latex: Annotated[bool, typer.Option("--latex", help="Print LaTeX.")] = False,
    digits: Annotated[int, typer.Option("--digits", help="Significant digits (2-3).")] = 3,
) -> None:
    """Print each phase's learned latent equations."""
    from symrom.model.persistence import load_model

    model = load_model(model_path)
    typer.echo(model.equations_text(latex=latex, digits=digits))


@app.command("demo")
@guarded
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output directory.")] = Path("symrom-demo"),
    force: Force = False,
) -> None:
    """Run the whole pipeline on a small default and print where the results are."""
    from symrom.data.io import atomic_dir
    from symrom.evaluate.tables import table2
    from symrom.experiments.demo import run_demo

    with atomic_dir(out, force) as tmp:
        with console.status("demo") as status:
            paths = run_demo(tmp, progress=lambda msg: status.update(f"demo: {msg}"))
        metrics = json.loads(paths["metrics"].read_text())
        equations = paths["equations"].read_text()
    typer.echo(equations)
    typer.echo(table2(metrics, title="test split"))
    out_console.print(f"results: {out}/ (data.h5, model.json, equations.txt, eval/)")


def main() -> None:  # pragma: no cover - entry point
    app(sys.argv[1:])
