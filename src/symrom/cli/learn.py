"""Learning commands: ``train`` (one model, or ``--select`` on the val split), ``finetune``,
``sweep``, ``equations`` and ``export``."""

from pathlib import Path
from typing import Annotated

import typer

from symrom.cli.common import (
    WORKERS_HELP,
    Address,
    BackendName,
    Command,
    Force,
    app,
    console,
    flag_text,
    guarded,
    invariant_components,
    progress_bar,
    say,
    start_backend,
    warn,
    warn_all,
)

# train's options that --select does not use (it chooses them on the val split)
SELECT_IGNORES = ("latent_dim", "poly_order", "solver", "threshold", "epochs", "seed", "encoder_components",
                  "decoded_weight", "alpha", "measure", "collinearity", "encoder_scaling", "encoder_base_latents",
                  "trig", "refine", "keep", "polish")


def _given(ctx: typer.Context, names: tuple[str, ...]) -> list[str]:
    """The options of ``names`` given on the command line (not left at their defaults)."""
    # typer's own click: by name
    return ["/".join(p.opts + p.secondary_opts) for p in ctx.command.params
            if p.name in names and getattr(ctx.get_parameter_source(p.name), "name", "DEFAULT") != "DEFAULT"]


def _refuse_ignored(ctx: typer.Context, names: tuple[str, ...], why: str) -> None:
    """One line naming the options of ``names`` given on the command line, which would be ignored."""
    given = _given(ctx, names)
    if given:
        raise ValueError(f"{', '.join(given)}: not used with --select ({why}); "
                         f"leave {'it' if len(given) == 1 else 'them'} out")


def _split_list(text: str | None) -> tuple[str, ...] | None:
    return None if text is None else tuple(c.strip() for c in text.split(",") if c.strip())


@app.command("train", cls=Command)
@guarded
def train_cmd(
    ctx: typer.Context,
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (model.json, equations.txt).")],
    latent_dim: Annotated[int, typer.Option("--latent-dim", help="Latent dimension l.")] = 2,
    poly_order: Annotated[int, typer.Option("--poly-order", help="Polynomial order p of the library.")] = 1,
    solver: Annotated[str, typer.Option("--solver", help="exact (closed form) or adam (gradient steps).")] = "exact",
    threshold: Annotated[float, typer.Option("--threshold", help="Sparsity threshold on |Xi|.")] = 0.01,
    epochs: Annotated[int | None, typer.Option("--epochs", help="adam: epochs (default 501).")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed (adam initialisation).")] = 0,
    encoder_components: Annotated[str | None, typer.Option(
        "--encoder-components", help="Comma-separated q components the encoder reads, e.g. x,y,z "
                                     "(default: all 18).")] = None,
    decoded_weight: Annotated[float, typer.Option(
        "--decoded-weight", help="Weight of the decoded-acceleration term of the SINDy loss "
                                 "(1 = the paper; 0 = latent accelerations only).")] = 1.0,
    alpha: Annotated[float, typer.Option(
        "--alpha", help="Ridge on the standardised library features (exact solver; 0 = none).")] = 0.0,
    measure: Annotated[str, typer.Option(
        "--measure", help="What --threshold applies to: coefficient (|Xi|, the paper), contribution "
                          "or explained (scale-free).")] = "coefficient",
    collinearity: Annotated[float | None, typer.Option(
        "--collinearity", help="Leave out terms whose |correlation| with a simpler one exceeds this "
                               "on a phase's rows, e.g. 0.995 (default: keep all).")] = None,
    encoder_scaling: Annotated[str, typer.Option(
        "--encoder-scaling", help="none, or spread: standardise components before step (a).")] = "none",
    encoder_base_latents: Annotated[int | None, typer.Option(
        "--encoder-base-latents", help="Latents taken from the base pose, the rest from the joints "
                                       "(--select's pose+joints; default: one PCA over all, the paper).")] = None,
    trig: Annotated[bool, typer.Option("--trig/--no-trig", help="Trigonometric terms in the library.")] = True,
    refine: Annotated[bool, typer.Option("--refine", help="Refine the coefficients on rollout error.")] = False,
    polish: Annotated[str | None, typer.Option(
        "--polish", help="With --refine: phases refined again, each alone, after the refinement and pruning, "
                         "e.g. flight (comma-separated; --select with --max-terms polishes flight).")] = None,
    keep: Annotated[str | None, typer.Option(
        "--keep", help="With --max-terms: phases the pruning leaves whole (their refined terms held while the "
                       "others are pruned), e.g. flight (comma-separated).")] = None,
    invariant: Annotated[str | None, typer.Option(
        "--invariant", help="Base components the dynamics are held invariant to, so that where the robot "
                            "stands is no clock or force: x, x,y or none (default: none for one model, "
                            "the paper; x with --select).")] = None,
    select: Annotated[bool, typer.Option(
        "--select", help="Choose encoder, latent dimension, library, sparsity and refinement on the val "
                         "split (it refuses the options above, which it would not use).")] = False,
    select_dims: Annotated[str, typer.Option(
        "--select-dims", help="Latent dimensions of --select: 2-4, 2,3,6 ...")] = "2-4",
    workers: Annotated[int | None, typer.Option("--workers", help="--select: " + WORKERS_HELP.format(local=1))] = None,
    max_terms: Annotated[int | None, typer.Option(
        "--max-terms", help="With --refine: prune the refined model to at most N active terms. --select: a "
                            "term budget; refinements pruned to at most N active terms, and only "
                            "candidates within it compete (default: none).")] = None,
    resume: Annotated[bool, typer.Option(
        "--resume", help="--select: continue an interrupted selection (its finished cells and refinements are in "
                     "OUT.parts).")] = False,
    backend: BackendName = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Train a hybrid symbolic model on the dataset's train split (or select it on val)."""
    if select:
        _refuse_ignored(ctx, SELECT_IGNORES, "--select chooses them on the val split")
        return _train_select(data, out, select_dims, workers, backend, address, resume, force, max_terms,
                             invariant_components(invariant))
    if backend != "local" or address is not None or resume:
        raise ValueError("--backend, --address and --resume apply to --select (training one model is one task)")
    from symrom.learn.training import AdamConfig, TrainConfig, train_into

    config = TrainConfig(latent_dim=latent_dim, poly_order=poly_order, trig=trig, solver=solver,
                         threshold=threshold, seed=seed,
                         adam=AdamConfig() if epochs is None else AdamConfig(epochs=epochs),
                         encoder_components=_split_list(encoder_components), decoded_weight=decoded_weight,
                         alpha=alpha, measure=measure, collinearity=collinearity, encoder_scaling=encoder_scaling,
                         encoder_base_latents=encoder_base_latents, refine=refine, max_terms=max_terms,
                         keep=_split_list(keep) or (), polish=_split_list(polish) or (),
                         invariant=invariant_components(invariant) or ())
    with progress_bar("training", total=1.0) as bar:
        model = train_into(out, data, config, force=force, progress=lambda stage, frac: bar.update(
            completed=frac, description=f"training: {stage}"))
    say(f"training rows: {model.training_rows()}")
    say(f"model: {out / 'model.json'}  ({model.summary()})")
    warn_all(model.warnings())


def _train_select(data: Path, out: Path, select_dims: str, workers: int | None, backend: str,
                  address: str | None, resume: bool, force: bool, max_terms: int | None = None,
                  invariant: tuple[str, ...] | None = None) -> None:
    """``train --select``: the validation selection, its table and the chosen model. Each
    finished cell of the grid is kept in ``OUT.parts`` until the outputs are written, so
    that ``--resume`` continues an interrupted selection."""
    from symrom.experiments import SELECT_WORKER_MODULES

    # Local workers: their fork server imports the selection beside this process's own imports
    # (a cluster is connected to only after the checks below).
    runner = start_backend(backend, workers, address) if backend == "local" else None
    if runner is not None:
        runner.prestart(SELECT_WORKER_MODULES)
    from symrom.experiments.select import SelectionConfig, check_parts, parts_done, select_into
    from symrom.experiments.sweep import parse_latent_dims

    cfg = SelectionConfig(latent_dims=parse_latent_dims(select_dims), workers=1 if workers is None else workers,
                          max_terms=max_terms, **({} if invariant is None else {"invariant": invariant}))
    parts = check_parts(out, resume, force, inputs=(data,))  # before connecting to a cluster
    if runner is None:
        runner = start_backend(backend, workers, address)
    try:
        with progress_bar("selection", total=len(cfg.cells()) + cfg.refine_top) as bar:
            sel = select_into(out, data, cfg, resume=resume, force=force, backend=runner,
                              progress=lambda done, total, what: bar.update(completed=done, total=total,
                                                                            description=f"selection: {what}"))
    except KeyboardInterrupt:
        cells, refined = parts_done(parts)
        say(f"interrupted: {cells} finished cell(s) and {refined} finished refinement(s) are kept in {parts}; "
            "run the same command with --resume to continue without redoing them")
        raise
    say(f"training rows: {sel.model.training_rows()}")
    say(sel.summary() + f"\nmodel: {out / 'model.json'}  table: {out / 'selection.json'}")
    refused = sel.refusals()
    say(f"refused for use: {refused['physics']} candidate(s) on physics, {refused['integrator']} by the integrator, "
        f"{refused['free']} in free prediction (each row's 'refused' in selection.json says why)")
    for note in sel.notes:
        say(note)
    warn_all(sel.model.warnings())


@app.command("finetune", cls=Command)
@guarded
def finetune_cmd(
    model_path: Annotated[Path, typer.Argument(help="Source model file (model.json), e.g. trained on simulation.")],
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5) of the new jumps: train to fit, val to check.")],
    out: Annotated[Path, typer.Option(
        "--out", help="Output directory (model.json, equations.txt, finetune.json, val_before/, val_after/).")],
    prior_weight: Annotated[float, typer.Option(
        "--prior-weight", help="Pull towards the source model (0: the new rows alone).")] = 0.01,
    keep_decoder: Annotated[bool, typer.Option(
        "--keep-decoder", help="Keep the source decoder; refit only the dynamics.")] = False,
    method: Annotated[str, typer.Option(
        "--method", help="calibrate_rollout (calibrate, then refine the non-flight phases on rollouts, "
                         "the flight phase held as calibrated), calibrate (per phase input gains, offsets "
                         "and damping; flight gravity kept unless the data contradict it), acceleration "
                         "(every coefficient, towards the source, --prior-weight) or rollout (the "
                         "rollout-aware refinement from the source coefficients).")] = "calibrate_rollout",
    tolerance: Annotated[float, typer.Option(
        "--tolerance", help="How much the val score may rise, as a fraction of the source's.")] = 0.05,
    threshold: Annotated[float | None, typer.Option(
        "--threshold", help="Sparsity threshold, --method acceleration only (default: the source's).")] = None,
    calibration_terms: Annotated[str, typer.Option(
        "--calibration-terms", help="--method calibrate[_rollout]: every (an offset and a damping in every non-flight "
                                    "equation) or support (only where the source has the term).")] = "every",
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda or rk4 (batch): the val rollouts.")] = "rk4",
    force: Force = False,
) -> None:
    """Fine-tune a model on new jumps (the phases they hold), checked on their val split."""
    from symrom.experiments.finetune import FineTuneCheck, finetune_into
    from symrom.learn.finetune import FineTuneConfig

    check = FineTuneCheck(FineTuneConfig(prior_weight=prior_weight, threshold=threshold,
                                         refit_decoder=not keep_decoder, method=method,
                                         calibration_terms=calibration_terms),
                          tolerance=tolerance, integrator=integrator)
    with console.status("fine-tuning") as status:
        result = finetune_into(out, model_path, data, check, force=force,
                               progress=lambda msg: status.update(f"fine-tuning: {msg}"))
    for is_warning, line in result.messages():
        (warn if is_warning else say)(flag_text(line))
    say(f"model: {out / 'model.json'}  val before: {out / 'val_before' / 'metrics.json'}  "
        f"after: {out / 'val_after' / 'metrics.json'}")


@app.command("sweep", cls=Command)
@guarded
def sweep_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (sweep.json, cells/ for resuming).")],
    latent_dims: Annotated[str, typer.Option("--latent-dims", help="Dimensions: 1-18, 1,2,4 or 1-3,6.")] = "1-18",
    seeds: Annotated[int, typer.Option("--seeds", help="Seeds per dimension (bootstrap resamples with exact).")] = 5,
    solver: Annotated[str, typer.Option("--solver", help="exact (closed form) or adam (gradient steps).")] = "exact",
    poly_order: Annotated[int, typer.Option("--poly-order", help="Polynomial order p of the library.")] = 1,
    lam: Annotated[float, typer.Option("--lambda", help="Complexity weight of L_mod.")] = 0.001,
    workers: Annotated[int | None, typer.Option("--workers", help=WORKERS_HELP.format(local=1))] = None,
    rmse_test: Annotated[bool, typer.Option(
        "--rmse-test/--no-rmse-test", help="Also roll out the test split (rk4) per cell.")] = True,
    backend: BackendName = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Accuracy vs complexity over latent dimensions and seeds; resumes from OUT/cells."""
    from symrom.atomic import check_output_file
    from symrom.data.io import read_dataset
    from symrom.execution import check_workers
    from symrom.experiments.sweep import SweepConfig, parse_latent_dims, run_sweep, sweep_lines

    check_workers(workers)
    dims = parse_latent_dims(latent_dims)
    config = SweepConfig(latent_dims=dims, seeds=seeds, poly_order=poly_order, solver=solver,
                         lam=lam, workers=1 if workers is None else workers, rmse_test=rmse_test)
    check_output_file(out / "sweep.json", force, inputs=(data,))
    ds = read_dataset(data)
    runner = start_backend(backend, workers, address)
    with progress_bar("sweep", total=len(dims) * len(config.seeds)) as bar:

        def tick(done, total, info):
            what = "reused" if info["reused"] else "done"
            bar.update(completed=done, description=f"sweep: l={info['latent_dim']} seed {info['seed']} {what}")

        result = run_sweep(ds, config, out, progress=tick, backend=runner)
    for line in sweep_lines(result, lam):
        say(line)
    say(f"results: {out / 'sweep.json'}")


@app.command("equations", cls=Command)
@guarded
def equations_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    latex: Annotated[bool, typer.Option("--latex", help="Print LaTeX.")] = False,
    digits: Annotated[int, typer.Option("--digits", help="Significant digits (2-3).")] = 3,
) -> None:
    """Print each phase's learned latent equations."""
    from symrom.model.persistence import load_model

    model = load_model(model_path)
    eq = model.equations(digits)
    typer.echo(eq.latex() if latex else eq.text())
    stability = model.stability_text(latex)
    if stability:
        typer.echo("\n" + stability)
    warn_all(model.warnings())


@app.command("export", cls=Command)
@guarded
def export_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    to: Annotated[str, typer.Option(
        "--to", help="c (C99 source and header), casadi (casadi.Function files) or python.")],
    out: Annotated[Path, typer.Option("--out", help="Output directory.")] = Path("export"),
    force: Force = False,
) -> None:
    """Write the model as standalone code: encoder, decoder, each phase's dynamics, an RK4 step."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.export import TARGETS, export
    from symrom.model.persistence import load_model, model_hash

    if to not in TARGETS:
        raise ValueError(f"--to must be one of {', '.join(TARGETS)}, got {to!r}")
    if to == "casadi":
        import importlib.util

        if importlib.util.find_spec("casadi") is None:
            raise ValueError("--to casadi needs CasADi, which is not installed: pip install 'symrom[export]'")
    check_output_file(out, force)
    model = load_model(model_path)
    with atomic_dir(out, force) as tmp:
        written = export(model, to, tmp)
    say(f"{to} export of {model_path} (sha256 {model_hash(model)[:12]}, phases "
        f"{', '.join(model.phase_names)}): " + ", ".join(str(out / p.name) for p in written))
