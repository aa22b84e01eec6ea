"""Evaluation commands: ``evaluate`` (a model on a split), and the baselines ``aslip`` and
``newton`` (fitted on the train split, evaluated the same way)."""

from pathlib import Path
from typing import Annotated

import typer

from symrom.cli.common import Command, Force, app, flag_text, guarded, progress_bar, say, warn

Reset = Annotated[list[float] | None, typer.Option(
    "--reset", help="Reset period(s) in s (repeatable; default 0.1).")]


def _show(evaluation) -> None:
    """An evaluation's own summary: the table on stdout, warnings on stderr, then the files."""
    for is_warning, text in evaluation.messages():
        if is_warning:
            warn(flag_text(text))
        elif text.startswith(("metrics:", "plot:")):
            say(text)
        else:
            typer.echo(text)


@app.command("evaluate", cls=Command)
@guarded
def evaluate_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory.")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    reset: Reset = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda (the paper's) or rk4 (batch).")] = "lsoda",
    plot_jump: Annotated[list[int] | None, typer.Option(
        "--plot-jump", help="K-th jump of the evaluated split to plot, from 0 (repeatable; default 0).")] = None,
    phases: Annotated[str, typer.Option(
        "--phases", help="logged (the data's phase sequence) or predicted (the model's contact guards; rk4; "
                         "adds the switching-time errors).")] = "logged",
    force: Force = False,
) -> None:
    """Roll the model out on a split (full horizon and periodic resets); write metrics, table, plots."""
    from symrom.evaluate.outputs import evaluate_into

    with progress_bar("rollouts") as bar:
        evaluation = evaluate_into(out, model_path, data, split=split, resets=reset, integrator=integrator,
                                   plot_jumps=tuple(plot_jump or (0,)), phases=phases, force=force,
                                   progress=bar.count)
    _show(evaluation)


@app.command("aslip", cls=Command)
@guarded
def aslip_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (metrics.json, params.json, table.md).")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    fit: Annotated[str, typer.Option(
        "--fit", help="residual (acceleration residual) or rollout (CoM rollout error, "
                      "from the residual fit).")] = "residual",
    fixed: Annotated[bool, typer.Option(
        "--fixed", help="Use the paper's k_s=250 N/m, l_0=0.32 m, m=12.01 kg (overridable) "
                        "instead of fitting.")] = False,
    k_s: Annotated[float | None, typer.Option("--k-s", help="Spring constant, N/m (with --fixed).")] = None,
    l0: Annotated[float | None, typer.Option("--l0", help="Rest length, m (with --fixed).")] = None,
    mass: Annotated[float | None, typer.Option(
        "--mass", help="Body mass, kg (default: URDF total; paper's with --fixed).")] = None,
    reset: Reset = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda (the paper's) or rk4 (batch).")] = "lsoda",
    force: Force = False,
) -> None:
    """Fit (train split) or fix the aSLIP baseline and evaluate its CoM prediction on a split."""
    from symrom.baselines.aslip import OBJECTIVES, ASlip
    from symrom.evaluate.outputs import baseline_into

    if fit not in OBJECTIVES:
        raise ValueError(f"--fit must be residual or rollout, got {fit!r}")
    if not fixed and (k_s is not None or l0 is not None):
        raise ValueError("--k-s/--l0 set a fixed model: add --fixed (without it both are fitted)")
    name = "aslip_rollout" if fit == "rollout" else "aslip"
    baseline = ASlip.paper(k_s, l0, mass) if fixed else None
    with progress_bar("aSLIP rollouts") as bar:
        model, evaluation = baseline_into(out, data, name, split=split, resets=reset, integrator=integrator,
                                          mass=mass, baseline=baseline, title="aSLIP (fixed)" if fixed else None,
                                          force=force, progress=bar.count)
    _show(evaluation)
    p = model.params
    say(f"aSLIP ({model.source}): k_s {p.k_s:.4g} N/m, l_0 {p.l_0:.4g} m, m {p.m:.4g} kg; "
        f"params: {out / 'params.json'}")


@app.command("newton", cls=Command)
@guarded
def newton_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (metrics.json, params.json, table.md).")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    mass: Annotated[float | None, typer.Option("--mass", help="Body mass, kg (default: the robot's total).")] = None,
    reset: Reset = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda or rk4 (batch).")] = "lsoda",
    fit: Annotated[bool, typer.Option(
        "--fit", help="Fit b'' = c + A F/m (contact), c_f (flight) on the train split.")] = False,
    force: Force = False,
) -> None:
    """Evaluate Newton's law on the measured ground force, b'' = g + F/m, on a split (--fit: its
    gains and offsets fitted on the train split)."""
    from symrom.evaluate.outputs import baseline_into

    with progress_bar("Newton rollouts") as bar:
        model, evaluation = baseline_into(out, data, "newton_fitted" if fit else "newton", split=split, resets=reset,
                                          integrator=integrator, mass=mass, force=force, progress=bar.count)
    _show(evaluation)
    say(f"{'Newton (fitted)' if fit else 'Newton'} (m {model.m:.4g} kg): metrics: {out / 'metrics.json'}")
