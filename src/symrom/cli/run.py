"""Run commands: ``reproduce`` (the paper's experiments), ``demo`` (a small Go1 run) and
``report`` (the HTML report of a run or a model folder)."""

from pathlib import Path
from typing import Annotated

import typer

from symrom.cli.common import (
    ENGINE_HELP,
    WORKERS_HELP,
    Address,
    BackendName,
    Command,
    Force,
    app,
    command_line,
    console,
    guarded,
    invariant_components,
    say,
    start_backend,
    status_say,
)


@app.command("reproduce", cls=Command)
@guarded
def reproduce_cmd(
    out: Annotated[Path, typer.Option("--out", help="Run directory; existing datasets and results are reused.")],
    quick: Annotated[bool, typer.Option("--quick", help="A reduced run that takes a few minutes.")] = False,
    workers: Annotated[int | None, typer.Option(
        "--workers", help="Generation, selection and sweep: " + WORKERS_HELP.format(local=2))] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of every dataset and training run.")] = 0,
    no_report: Annotated[bool, typer.Option("--no-report", help="Skip the HTML/Markdown report.")] = False,
    backend: BackendName = "local",
    address: Address = None,
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    only: Annotated[str | None, typer.Option(
        "--only", help="Run one part only: sim2real (with the SIM Go1 and SIM A1 selections it needs).")] = None,
    max_terms: Annotated[int | None, typer.Option(
        "--max-terms", help="Term budget of the SIM selections: refinements pruned to at most N active terms "
                            "(compact models; e.g. 60). Default: none.")] = None,
    invariant: Annotated[str | None, typer.Option(
        "--invariant", help="Base components the selections hold the dynamics invariant to, as train --select "
                            "does: x or x,y. Default: none, the paper's formulation.")] = None,
) -> None:
    """Run the paper's experiments end to end into one directory (resumable)."""
    from symrom.atomic import check_writable
    from symrom.experiments.reproduce import reproduce, reproduce_config, summary_lines

    held = invariant_components(invariant) or ()
    cfg = reproduce_config(quick, seed=seed, engine=engine, max_terms=max_terms, only=only,
                           invariant=held)  # checked first
    check_writable(out, inside=True)  # a run directory is written into, in place
    runner = start_backend(backend, workers, address, local_default=2)
    cfg = reproduce_config(quick, seed=seed, engine=engine, max_terms=max_terms, workers=runner.workers,
                           backend=backend, address=getattr(runner, "address", None), invariant=held)
    with console.status("reproduce") as status:
        summary = reproduce(out, cfg, command=command_line(), say=status_say(status, "reproduce"), only=only)
        if not no_report:
            from symrom.report.html import build_report

            status.update("reproduce: report")
            build_report(out, out / "report.html", workers=runner.workers if backend == "local" else 2)
    for line in summary_lines(summary):
        typer.echo(line)
    if summary.get("sim2real", {}).get("targets"):
        from symrom.report.sim2real import sim2real_markdown

        typer.echo(sim2real_markdown(summary["sim2real"]["targets"]))
    typer.echo(f"summary: {out / 'summary.json'}" + ("" if no_report else f"\nreport: {out / 'report.html'}"))


@app.command("demo", cls=Command)
@guarded
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output directory.")] = Path("symrom-demo"),
    jumps: Annotated[int, typer.Option("--jumps", help="Go1 pronking jumps to simulate.")] = 12,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes for the simulation.")] = 2,
    force: Force = False,
) -> None:
    """Simulate a dozen Go1 jumps, train, evaluate, fit the aSLIP and write the report."""
    from symrom.experiments.demo import run_demo
    from symrom.report.html import build_report

    with console.status("demo") as status:
        demo = run_demo(out, jumps, workers=workers, force=force, command=command_line(),
                        say=status_say(status, "demo"))
        # The report is built where the run now is, so that it names that directory.
        status.update("demo: report")
        build_report(out, out / "report.html", workers=workers)
    typer.echo(demo.text())
    say(f"dataset: {demo.data}  ({demo.jumps} simulated jumps)\nmodel: {demo.model}\nreport: {out / 'report.html'}")


@app.command("report", cls=Command)
@guarded
def report_cmd(
    run_dir: Annotated[Path, typer.Argument(
        help="Run directory (symrom reproduce, demo) or model folder (symrom "
             "train; its evaluation's metrics.json in it or a subfolder).")],
    out: Annotated[Path | None, typer.Option(
        "--out", help="Output HTML file (default DIR/report.html); the "
                      "Markdown twin and its figures go next to it.")] = None,
    force: Force = False,
    workers: Annotated[int, typer.Option("--workers", help="Processes drawing the figures.")] = 2,
) -> None:
    """Build the self-contained HTML report (and its Markdown twin) of a run directory or a model folder."""
    from symrom.report.html import build_report

    with console.status("report") as status:
        html, md = build_report(run_dir, out, force=force, progress=lambda msg: status.update(f"report: {msg}"),
                                workers=workers)
    say(f"report: {html}\nmarkdown: {md}")
