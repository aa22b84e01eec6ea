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
from typer.core import TyperCommand, TyperGroup
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

def _flags_without_type(params: list) -> list:
    """Boolean flags take no value: show no type (typer's help would say ``<bool>``)."""
    for p in params:
        if getattr(p, "is_flag", False) and p.metavar is None:
            p.metavar = ""
    return params


class _Group(TyperGroup):
    def get_params(self, ctx):
        return _flags_without_type(super().get_params(ctx))


class _Command(TyperCommand):
    def get_params(self, ctx):
        return _flags_without_type(super().get_params(ctx))


app = typer.Typer(cls=_Group, add_completion=False, no_args_is_help=True,
                  help="Symbolic reduced-order models of legged-robot jumping, learned from data.")
console = Console(stderr=True, log_path=False)  # log lines: time and message, no cli.py:NNN
out_console = Console()

_STATE = {"debug": False}

Force = Annotated[bool, typer.Option("--force", help="Overwrite an existing output.")]
BackendName = Annotated[str, typer.Option(
    "--backend", help="Where the tasks run: local (processes on this machine) or ray (a Ray cluster; "
                      "pip install 'symrom\\[ray]').")]
Address = Annotated[Optional[str], typer.Option(
    "--address", help="Ray cluster address (host:port, ray://host:10001, auto or local); default "
                      "$RAY_ADDRESS, else a cluster started on this machine with ray start, else a new Ray "
                      "instance on this machine.")]
ENGINE_HELP = "Physics engine: pybullet or mujoco (docs/engines.md)."
WORKERS_HELP = ("Worker processes (local back end; default {local}), or the most tasks at once on Ray "
                "(default: the cluster's CPUs).")


def _start_backend(name: str, workers: int | None, address: str | None, local_default: int = 1):
    """The execution back end of the options, started (a Ray back end connects here, so a bad
    address fails before any work)."""
    from symrom.execution import make_backend

    _check_workers(workers)
    backend = make_backend(name, local_default if workers is None and name == "local" else workers, address)
    if name == "ray":
        with console.status("connecting to Ray"):
            backend.start()
        info = backend.describe()
        console.print(f"ray: {info['nodes']} node(s), {info['cpus']} CPUs, {backend.workers} tasks at once",
                      highlight=False)
    return backend


def _check_workers(workers: int | None) -> None:
    """--workers: at least 1 (checked before any work)."""
    if workers is not None and workers < 1:
        raise ValueError(f"--workers {workers}: the number of workers must be at least 1")


def _show_version(value: bool) -> None:
    if value:
        from symrom import __version__

        typer.echo(f"symrom {__version__}")
        raise typer.Exit()


@app.callback()
def _main(debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks on errors.")] = False,
          version: Annotated[bool, typer.Option("--version", callback=_show_version, is_eager=True,
                                                help="Print the version and exit.")] = False) -> None:
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
        except BrokenPipeError:
            _quiet_stdout()
            raise typer.Exit(141) from None  # as a shell reports a process ended by SIGPIPE
        except Exception as e:  # noqa: BLE001 - the CLI boundary
            if _STATE["debug"]:
                raise
            msg = str(e).strip().splitlines()[0] if str(e).strip() else e.__class__.__name__
            console.print(f"[red]error:[/red] {escape(msg)}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None

    return wrapper


def _quiet_stdout() -> None:
    """The reader of stdout has gone (``symrom equations m.json | head``): send what is
    left to /dev/null so that neither the command nor Python's exit reports it."""
    import os

    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout is not a real file (a test runner's capture)
        pass
    finally:
        os.close(devnull)


def progress_bar() -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                    TimeElapsedColumn(), console=console, transient=False)


def _ticker(bar: Progress, task) -> Callable[[int, int], None]:
    """A progress callback ``(done, total)`` that moves ``task`` of ``bar``."""
    return lambda done, total: bar.update(task, completed=done, total=total)


def _parse_resets(reset: list[float] | None) -> tuple[float | None, ...]:
    """The horizons: the full jump, then each ``--reset`` period (default 0.1 s); checked
    here, before any work starts."""
    import math

    for r in reset or []:
        if not (math.isfinite(r) and r > 0):
            raise ValueError(f"--reset {r:g}: a reset period must be a positive number of seconds")
    return (None, *sorted(set(reset or [0.1])))


_IMPORT_HELP = """Import robot logs into a checked dataset file.

LOGS: CSV files (Go1 hardware or plain layout), ROS 1 bags, ROS 2 bag
folders (sqlite3 or mcap storage) or MCAP files; the kind is read from
the content. Several files are consecutive jumps.

\b
CSV plain layout, SI units: jump (optional), t (s), fr_hx ... rl_kn,
  x y z (m), roll pitch yaw (rad, ZYX), d_<name>, dd_<name> (optional),
  tau_<joint> (N m), c_fr c_fl c_rr c_rl (0/1).
CSV hardware layout: Time; <leg>.<joint> Position|Velocity|
  Acceleration|Torque; Body linear|angular Position|Velocity|
  Acceleration x|y|z; <leg> Foot.
Bags (--topics or --mapping change the topics):
  joints=/joint_states: sensor_msgs/msg/JointState, matched by the
    URDF joint names, URDF sign convention;
  base=/odom: nav_msgs/msg/Odometry, pose in the world frame,
    twist in the base frame (ROS convention);
  contacts=/foot_contacts (optional): 4 values FR FL RR RL in data;
    without it, from the legs' vertical forces and foot heights.

Every log is checked against the robot (ranges; torque limits by
--torques) and against physics (velocities vs positions, stale rows,
vertical momentum vs weight, stance feet on the ground). A recording
holding several flights is cut into one jump per flight. --repair
first repairs what physics determines per jump: a wrong clock or
wrong velocities (the flight falls at g), a contact lag, a torque
gain (the weight), a base-height offset (the feet in contact).
Details: docs/import.md."""


@app.command("import", cls=_Command, help=_IMPORT_HELP)
@guarded
def import_cmd(
    logs: Annotated[list[Path], typer.Argument(help="Log files: CSV, ROS 1 bag, ROS 2 bag folder or MCAP; several are concatenated as consecutive jumps.")],
    robot: Annotated[str, typer.Option("--robot", help="Robot of the logs: go1, a1 or a robot description file (.toml); its URDF gives the wrench.")],
    out: Annotated[Path, typer.Option("--out", help="Output dataset file (HDF5).")],
    motion: Annotated[str, typer.Option("--motion", help="Motion (pronk, froggy): its registry entry sets the phase rule.")] = "pronk",
    source: Annotated[str, typer.Option("--source", help="Source attribute of the dataset.")] = "hardware",
    split: Annotated[Optional[str], typer.Option("--split", help="train,val,test counts (12,2,1) or fractions (0.8,0.1,0.1) of the jumps after segmentation; default all train.")] = None,
    diff: Annotated[str, typer.Option("--diff", help="savgol or central: differentiation where a log has no accelerations.")] = "savgol",
    diff_window: Annotated[float, typer.Option("--diff-window", help="Differentiation (savgol) window, s: 0.018 is 9 samples at 500 Hz, 19 at 1 kHz.")] = 0.018,
    lenient: Annotated[bool, typer.Option("--lenient", help="Report implausible values and failed physical checks per file instead of refusing the import.")] = False,
    torques: Annotated[str, typer.Option("--torques", help="measured or commanded: what the torque columns hold (commanded ones must stay within the motor limit; measured ones within 1.25 x it); stored in the dataset.")] = "measured",
    physics: Annotated[bool, typer.Option("--physics/--no-physics", help="Check the logs against physics (time scale, vertical momentum, stance foot height).")] = True,
    segment: Annotated[str, typer.Option("--segment", help="auto: cut a jump holding several flights into one jump per flight; off: keep jumps as logged.")] = "auto",
    retime_stale: Annotated[bool, typer.Option("--retime-stale", help="Replace stale (repeated) rows by interpolation between the fresh rows, each kept at its own time.")] = False,
    topics: Annotated[Optional[str], typer.Option("--topics", help="Bag topics: joints=/joint_states,base=/odom,contacts=/foot_contacts (any subset).")] = None,
    mapping: Annotated[Optional[Path], typer.Option("--mapping", help="TOML file with a \\[topics] table (joints, base, contacts); --topics overrides it.")] = None,
    dt: Annotated[Optional[float], typer.Option("--dt", help="Sample period of the dataset, s (default: the coarsest jump's period); other jumps are resampled.")] = None,
    max_gap: Annotated[float, typer.Option("--max-gap", help="Longest gap (missing samples) bridged by interpolation, s; longer ones are refused.")] = 0.01,
    no_resample: Annotated[bool, typer.Option("--no-resample", help="Refuse jumps off the dataset's time grid instead of resampling them.")] = False,
    positions: Annotated[str, typer.Option("--positions", help="auto, absolute or rebased: base positions that start at 0 in each jump get their height back from the feet.")] = "auto",
    repair: Annotated[bool, typer.Option("--repair", help="Repair each jump from physics before the checks: clock or velocities (by the flight), contact lag, torque gain (by the weight), height offset (by the feet); a fault the data cannot determine is refused.")] = False,
    force: Force = False,
) -> None:
    from symrom.atomic import check_output_file
    from symrom.data.bags import load_mapping, parse_topics
    from symrom.data.checks import PlausibilityLimits
    from symrom.data.consistency import ConsistencyLimits
    from symrom.data.importers import import_logs
    from symrom.data.io import write_dataset
    from symrom.data.repair import RepairLimits
    from symrom.data.timebase import TimeBase

    check_output_file(out, force, inputs=tuple(logs))
    time_base = TimeBase(dt=dt, max_gap=max_gap, resample=not no_resample)
    by_role = {**(load_mapping(mapping) if mapping else {}), **parse_topics(topics)}
    with console.status(f"importing {len(logs)} log file(s)"):
        ds = import_logs([str(p) for p in logs], robot=robot, motion=motion, source=source,
                         split=split, diff_method=diff, lenient=lenient, time_base=time_base,
                         positions=positions, limits=PlausibilityLimits(torques=torques),
                         physics=ConsistencyLimits() if physics else None, segment=segment,
                         retime=retime_stale, diff_window=diff_window, topics=by_role or None,
                         repair=RepairLimits() if repair else None)
        write_dataset(ds, out)
    _import_report(ds)
    counts = ", ".join(f"{s} {int((ds.split == s).sum())}" for s in ("train", "val", "test"))
    out_console.print(f"dataset: {out}  ({ds.n_jumps} jumps, {ds.n_samples} samples, dt {ds.dt:g} s; "
                      f"phases: {_phase_rows(ds)}; {counts})", highlight=False, soft_wrap=True)


def _phase_rows(ds, rows=None) -> str:
    """'contact 1200 rows, flight 400 rows, partial none' for the rows of ``ds`` (all by default)."""
    import numpy as np

    phase = ds.phase if rows is None else ds.phase[rows]
    counts = np.bincount(phase, minlength=len(ds.phase_names))
    return ", ".join(f"{n} {c} rows" if c else f"{n} none" for n, c in zip(ds.phase_names, counts))


def _import_report(ds) -> None:
    """What the import found and did: implausible values kept (--lenient), rebased jumps, the
    time base (jumps resampled, jitter, gaps)."""
    g = ds.generator
    warn = "[yellow]warning:[/yellow]"
    for f in g.get("files", []):
        probs = f.get("checks") or []
        if probs:
            console.print(f"{warn} {f['name']}: {len(probs)} column(s) fail the plausibility checks; kept as "
                          "logged (--lenient):", highlight=False, soft_wrap=True)
            for pr in probs:
                console.print(f"  column {pr['header']!r} (first at jump {pr['jump']}, row {pr['row']}, line "
                              f"{pr['line']}): {pr['rows']} rows outside [{pr['low']}, {pr['high']}] {pr['unit']} "
                              f"({pr['limit']}), worst {pr['worst']:.6g}"
                              + (f"; it looks like {pr['hint']}" if pr["hint"] else ""),
                              highlight=False, soft_wrap=True)
    for f in g.get("files", []):
        if f.get("topics"):
            tp = f["topics"]
            console.print(f"{f['name']}: {f['layout']}, joints {tp['joints']}, base {tp['base']}, contacts "
                          f"{tp['contacts']}", highlight=False, soft_wrap=True)
        for pr in f.get("consistency") or []:
            console.print(f"{warn} kept as logged (--lenient): {pr['message']}", highlight=False, soft_wrap=True)
        for st in f.get("stale") or []:
            done = (f"; {st['retimed']} re-timed by interpolation between the fresh rows" if "retimed" in st
                    else "; --retime-stale interpolates them between the fresh rows")
            console.print(f"{warn} stale rows: {st['message']}{done}", highlight=False, soft_wrap=True)
    for sg in g.get("segments") or []:
        console.print(f"segments: {sg['file']} jump {sg['jump']} holds {len(sg['segments'])} flights, cut into "
                      f"{len(sg['segments'])} jumps: " + ", ".join(
                          f"t {x['t'][0]:.3f}-{x['t'][1]:.3f} s (flight {x['flight'][0]:.3f}-{x['flight'][1]:.3f} s)"
                          for x in sg["segments"]), highlight=False, soft_wrap=True)
    if g.get("torques"):
        console.print(f"torques: {g['torques']}", highlight=False, soft_wrap=True)
    for rp in (g.get("repairs") or {}).get("jumps", []):
        console.print(f"repair: {rp['line']}", highlight=False, soft_wrap=True)
    rebased = g.get("rebased") or []
    if rebased:
        offsets = [r["z_offset"] for r in rebased]
        how = sorted({r["from"] for r in rebased})
        console.print(f"positions: {len(rebased)} jump(s) start at z = 0 (rebased); z raised by "
                      f"{min(offsets):.4g}..{max(offsets):.4g} m so that " + "; ".join(how),
                      highlight=False, soft_wrap=True)
    tb = g.get("time_base")
    if tb:
        jumps = tb["jumps"]
        moved = [j for j in jumps if j["stored"] == "resampled"]
        jitter = [j for j in jumps if j["jitter_steps"]]
        gaps = [(j, x) for j in jumps for x in j["gaps"]]
        line = f"time base: dt {tb['dt']:g} s ({tb['rule']}); "
        line += (f"{len(moved)} of {len(jumps)} jumps resampled to it (modified Akima; contact flags by the "
                 f"nearest sample): " + ", ".join(f"{Path(j['file']).name} jump {j['jump']} "
                                                  f"(logged every {1e3 * j['median_dt']:.4g} ms)" for j in moved[:6])
                 + (" ..." if len(moved) > 6 else "") if moved else "every jump is on it, stored as logged")
        console.print(line, highlight=False, soft_wrap=True)
        if jitter:
            console.print(f"{warn} jitter: {len(jitter)} jump(s) have steps more than 10 % off their median "
                          f"(up to {100 * max(j['max_deviation'] for j in jitter):.3g} %)",
                          highlight=False, soft_wrap=True)
        if gaps:
            console.print(f"{warn} gaps bridged by interpolation: " + ", ".join(
                f"{Path(j['file']).name} jump {j['jump']}: {1e3 * x['length']:.3g} ms after t = {x['t']:.3f} s"
                for j, x in gaps[:6]) + (" ..." if len(gaps) > 6 else ""), highlight=False, soft_wrap=True)


# train's options that --select does not use (it chooses them on the val split)
SELECT_IGNORES = ("latent_dim", "poly_order", "solver", "threshold", "epochs", "seed", "encoder_components",
                  "decoded_weight", "alpha", "measure", "collinearity", "encoder_scaling", "encoder_base_latents",
                  "trig", "refine", "polish")


def _refuse_ignored(ctx: typer.Context, names: tuple[str, ...], why: str) -> None:
    """One line naming the options of ``names`` given on the command line, which would be ignored."""
    given = ["/".join(p.opts + p.secondary_opts) for p in ctx.command.params  # typer's own click: by name
             if p.name in names and getattr(ctx.get_parameter_source(p.name), "name", "DEFAULT") != "DEFAULT"]
    if given:
        raise ValueError(f"{', '.join(given)}: not used with --select ({why}); leave {'it' if len(given) == 1 else 'them'} out")


@app.command("train", cls=_Command)
@guarded
def train_cmd(
    ctx: typer.Context,
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (model.json, equations.txt).")],
    latent_dim: Annotated[int, typer.Option("--latent-dim", help="Latent dimension l.")] = 2,
    poly_order: Annotated[int, typer.Option("--poly-order", help="Polynomial order p of the library.")] = 1,
    solver: Annotated[str, typer.Option("--solver", help="exact (closed form) or adam (torch).")] = "exact",
    threshold: Annotated[float, typer.Option("--threshold", help="Sparsity threshold on |Xi|.")] = 0.01,
    epochs: Annotated[Optional[int], typer.Option("--epochs", help="adam: epochs (default 501).")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed (adam initialisation).")] = 0,
    encoder_components: Annotated[Optional[str], typer.Option(
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
    collinearity: Annotated[Optional[float], typer.Option(
        "--collinearity", help="Leave out terms whose |correlation| with a simpler one exceeds this "
                               "on a phase's rows, e.g. 0.995 (default: keep all).")] = None,
    encoder_scaling: Annotated[str, typer.Option(
        "--encoder-scaling", help="none, or spread: standardise components before step (a).")] = "none",
    encoder_base_latents: Annotated[Optional[int], typer.Option(
        "--encoder-base-latents", help="Latents taken from the base pose, the rest from the joints "
                                       "(--select's pose+joints; default: one PCA over all, the paper).")] = None,
    trig: Annotated[bool, typer.Option("--trig/--no-trig", help="Trigonometric terms in the library.")] = True,
    refine: Annotated[bool, typer.Option("--refine", help="Refine the coefficients on rollout error.")] = False,
    polish: Annotated[Optional[str], typer.Option(
        "--polish", help="With --refine: phases refined again, each alone, after the refinement and pruning, "
                         "e.g. flight (comma-separated; --select with --max-terms polishes flight).")] = None,
    select: Annotated[bool, typer.Option(
        "--select", help="Choose encoder, latent dimension, library, sparsity and refinement on the val "
                         "split (it refuses the options above, which it would not use).")] = False,
    select_dims: Annotated[str, typer.Option("--select-dims", help="Latent dimensions of --select: 2-4, 2,3,6 ...")] = "2-4",
    workers: Annotated[Optional[int], typer.Option("--workers", help="--select: " + WORKERS_HELP.format(local=1))] = None,
    max_terms: Annotated[Optional[int], typer.Option(
        "--max-terms", help="With --refine: prune the refined model to at most N active terms. --select: a "
                            "term budget; refinements pruned to at most N active terms, and only "
                            "candidates within it compete (default: none).")] = None,
    resume: Annotated[bool, typer.Option(
        "--resume", help="--select: continue an interrupted selection (its finished cells are in OUT.parts).")] = False,
    backend: BackendName = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Train a hybrid symbolic model on the dataset's train split (or select it on val)."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.data.io import read_dataset
    from symrom.learn.training import AdamConfig, TrainConfig, train
    from symrom.model.persistence import write_model_files

    if select:
        _refuse_ignored(ctx, SELECT_IGNORES, "--select chooses them on the val split")
    check_output_file(out, force, inputs=(data,))
    _check_workers(workers)
    adam = AdamConfig() if epochs is None else AdamConfig(epochs=epochs)
    comps = None if encoder_components is None else tuple(
        c.strip() for c in encoder_components.split(",") if c.strip())
    if max_terms is not None and max_terms < 1:
        raise ValueError(f"--max-terms must be a positive number of terms, got {max_terms}")
    if select:
        return _train_select(data, out, select_dims, workers, backend, address, resume, force, max_terms)
    if backend != "local" or address is not None or resume:
        raise ValueError("--backend, --address and --resume apply to --select (training one model is one task)")
    if max_terms is not None and not refine:
        raise ValueError("--max-terms is a budget of the refinement: give it with --refine (one model) or "
                         "--select (the budget of its refinements)")
    config = TrainConfig(latent_dim=latent_dim, poly_order=poly_order, trig=trig, solver=solver,
                         threshold=threshold, seed=seed, adam=adam, encoder_components=comps,
                         decoded_weight=decoded_weight, alpha=alpha, measure=measure,
                         collinearity=collinearity, encoder_scaling=encoder_scaling,
                         encoder_base_latents=encoder_base_latents, refine=refine, max_terms=max_terms,
                         polish=() if polish is None else tuple(p.strip() for p in polish.split(",") if p.strip()))
    ds = read_dataset(data)
    unknown = [p for p in config.polish if p not in ds.phase_names]
    if unknown:
        raise ValueError(f"--polish: no phase named {unknown} in {data} (its phases are {list(ds.phase_names)})")
    out_console.print(f"training rows: {_phase_rows(ds, ds.rows_of('train'))}", highlight=False, soft_wrap=True)
    with progress_bar() as bar:
        task = bar.add_task("training", total=1.0)
        model = train(ds, config, progress=lambda stage, frac: bar.update(
            task, completed=frac, description=f"training: {stage}"))
    model.info["data_path"] = str(data)
    with atomic_dir(out, force) as tmp:
        write_model_files(model, tmp)
    terms = ", ".join(f"{k} {v}" for k, v in model.active_terms().items())
    out_console.print(f"model: {out / 'model.json'}  (l={latent_dim}, p={poly_order}, "
                      f"{model.library.n_features} library terms; active terms: {terms})",
                      highlight=False, soft_wrap=True)
    _model_warnings(model)


def _train_select(data: Path, out: Path, select_dims: str, workers: int | None, backend: str,
                  address: str | None, resume: bool, force: bool, max_terms: int | None = None) -> None:
    """``train --select``: the validation selection, its table and the chosen model. Each
    finished cell of the grid is kept in ``OUT.parts`` until the outputs are written, so
    that ``--resume`` continues an interrupted selection."""
    from symrom.data.io import read_dataset
    from symrom.experiments.select import SelectionConfig, check_parts, check_splits, select_into
    from symrom.experiments.sweep import parse_latent_dims

    cfg = SelectionConfig(latent_dims=parse_latent_dims(select_dims), workers=1 if workers is None else workers,
                          max_terms=max_terms)
    check_parts(out, resume, force)
    ds = read_dataset(data)
    check_splits(ds)
    runner = _start_backend(backend, workers, address)
    out_console.print(f"training rows: {_phase_rows(ds, ds.rows_of('train'))}", highlight=False, soft_wrap=True)
    with progress_bar() as bar:
        task = bar.add_task("selection", total=len(cfg.cells()) + cfg.refine_top)
        sel = select_into(out, ds, cfg, resume=resume, force=force, progress=lambda done, total, what: bar.update(
            task, completed=done, total=total, description=f"selection: {what}"), backend=runner,
                          info={"data_path": str(data)})
    if sel.model is None:
        raise ValueError(f"every one of the {len(sel.rows)} candidate models diverged on a validation jump; "
                         f"the table is in {out / 'selection.json'}")
    r = sel.rows[sel.chosen]
    out_console.print(f"chosen of {len(sel.rows)} candidate models: encoder {r['encoder']}, l={r['latent_dim']}, "
                      f"{r['library']}, threshold {r['threshold']:g}, refined {'yes' if r['refine'] else 'no'}; "
                      f"{r['active_terms']} active terms, val score {r['score']:.3g} ({sel.seconds:.0f} s)\n"
                      f"model: {out / 'model.json'}  table: {out / 'selection.json'}", highlight=False, soft_wrap=True)
    _model_warnings(sel.model)


def _model_warnings(model) -> None:
    """Which phases the model could fit, one warning line per phase it could not (and if the
    encoder did not see the contact phase), and per phase with a fast unstable mode."""
    untrained = model.info.get("untrained_phases", [])
    if untrained:
        console.print(f"[yellow]warning:[/yellow] can fit: {', '.join(model.trained_phases())}; cannot fit: "
                      f"{', '.join(untrained)} (no training rows: its equations stay zero and rollouts "
                      "through it are refused)", highlight=False, soft_wrap=True)
    rows = model.info.get("encoder_rows", "")
    if rows.startswith("all"):
        console.print(f"[yellow]warning:[/yellow] the encoder (step a) is fitted on {rows}",
                      highlight=False, soft_wrap=True)
    for st in model.stability():
        if st.warning():
            console.print(f"[yellow]warning:[/yellow] {st.warning()}", highlight=False, soft_wrap=True)


@app.command("evaluate", cls=_Command)
@guarded
def evaluate_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory.")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    reset: Annotated[Optional[list[float]], typer.Option("--reset", help="Reset period(s) in s (repeatable).")] = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda (the paper's) or rk4 (batch).")] = "lsoda",
    plot_jump: Annotated[Optional[list[int]], typer.Option("--plot-jump", help="K-th jump of the evaluated split to plot, from 0 (repeatable; default 0).")] = None,
    phases: Annotated[str, typer.Option("--phases", help="logged (the data's phase sequence) or predicted (the model's contact guards; rk4; adds the switching-time errors).")] = "logged",
    force: Force = False,
) -> None:
    """Roll the model out on a split (full horizon and periodic resets); write metrics, table, plots."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.data.io import read_dataset
    from symrom.evaluate.metrics import evaluate
    from symrom.evaluate.outputs import write_evaluation
    from symrom.evaluate.tables import table2
    from symrom.model.persistence import load_model
    from symrom.rollout.integrate import RolloutOptions

    check_output_file(out, force, inputs=(model_path, data))
    _check_split_and_integrator(split, integrator)
    from symrom.evaluate.switching import PHASE_SOURCES

    if phases not in PHASE_SOURCES:
        raise ValueError(f"--phases must be {' or '.join(PHASE_SOURCES)}, got {phases!r}")
    if phases == "predicted" and integrator != "rk4":
        raise ValueError("--phases predicted rolls out with rk4: add --integrator rk4")
    resets = _parse_resets(reset)
    model = load_model(model_path)
    if phases == "predicted" and model.guards is None:
        raise ValueError(f"{model_path}: this model has no contact guards (model file format "
                         "3 or older): train it again with this symrom, or use --phases logged")
    ds = read_dataset(data)
    if ds.jumps_in(split).size == 0:
        raise ValueError(f"{data} has no {split!r} jumps")
    model.check_data(ds)  # robot, layout and phases: refused before any work starts
    model.phase_index(ds, ds.rows_of(split))
    split_jumps = ds.jumps_in(split)
    bad = [k for k in plot_jump or [] if not 0 <= k < split_jumps.size]
    if bad:
        raise ValueError(f"--plot-jump {bad[0]}: counts the jumps of the {split} split, which has "
                         f"{split_jumps.size} (0..{split_jumps.size - 1})")
    plots = [int(split_jumps[k]) for k in plot_jump or [0]]  # dataset jump indices
    with progress_bar() as bar:
        task = bar.add_task("rollouts", total=len(resets) * ds.jumps_in(split).size)
        tick = _ticker(bar, task)

        metrics, rollouts = evaluate(model, ds, split, resets, RolloutOptions(method=integrator),
                                     model_name=str(model_path), data_name=str(data), progress=tick,
                                     phases=phases)
    with atomic_dir(out, force) as tmp:
        written = write_evaluation(tmp, metrics, rollouts, ds, plots, title=f"{ds.robot} {ds.motion} ({split})")
    typer.echo(table2(metrics))
    if phases == "predicted":
        from symrom.evaluate.switching import switching_table

        typer.echo("switching times, predicted phases (full horizon):\n" + switching_table(metrics["switching"]))
    _divergence_warnings(metrics)
    out_console.print(f"metrics: {out / 'metrics.json'}", highlight=False, soft_wrap=True)
    for k, (j, p) in enumerate(zip(plots, written[2:])):
        out_console.print(f"plot: {out / p.name}  ({split} jump {(plot_jump or [0])[k]}, dataset jump {j})",
                          highlight=False, soft_wrap=True)


def _divergence_warnings(metrics: dict) -> None:
    """One warning per horizon with diverged jumps: which, when (s), and what was scored; one
    per horizon with drifted jumps: which, when (s) and the limit passed."""
    from symrom.evaluate.tables import drift_text

    for key, h in metrics["horizons"].items():
        if h.get("drifted_jumps"):
            console.print(f"[yellow]warning:[/yellow] {h['drifted_jumps']} of {metrics['n_jumps']} jumps "
                          f"drifted at horizon {key} ({drift_text(h['drifted'])}): the predicted base left the "
                          "physically possible (below the ground by more than a leg length, or beyond the "
                          "jump's range); they are scored", highlight=False, soft_wrap=True)
        if h["diverged_jumps"]:
            when = ", ".join(f"jump {d['jump']} at {d['t']:.3f} s" for d in h["diverged"])
            share = f" ({100 * h['scored_samples'] / h['samples']:.1f} % of the split's samples)" \
                if h.get("samples") else ""
            console.print(f"[yellow]warning:[/yellow] {h['diverged_jumps']} of {metrics['n_jumps']} "
                          f"jumps diverged at horizon {key} ({when}); each is scored up to its "
                          f"divergence{share}", highlight=False, soft_wrap=True)


@app.command("finetune", cls=_Command)
@guarded
def finetune_cmd(
    model_path: Annotated[Path, typer.Argument(help="Source model file (model.json), e.g. trained on simulation.")],
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5) of the new jumps: train to fit, val to check.")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (model.json, equations.txt, finetune.json, val_before/, val_after/).")],
    prior_weight: Annotated[float, typer.Option("--prior-weight", help="Pull towards the source model (0: the new rows alone).")] = 0.01,
    keep_decoder: Annotated[bool, typer.Option("--keep-decoder", help="Keep the source decoder; refit only the dynamics.")] = False,
    method: Annotated[str, typer.Option("--method", help="calibrate_rollout (calibrate, then refine the non-flight phases "
                                                         "on rollouts, the flight phase held as calibrated), calibrate (per "
                                                         "phase input gains, offsets and damping; flight gravity kept unless "
                                                         "the data contradict it), acceleration (every coefficient, towards "
                                                         "the source, --prior-weight) or rollout (the rollout-aware "
                                                         "refinement from the source coefficients).")] = "calibrate_rollout",
    tolerance: Annotated[float, typer.Option("--tolerance", help="How much the val score may rise, as a fraction of the source's.")] = 0.05,
    threshold: Annotated[Optional[float], typer.Option("--threshold", help="Sparsity threshold, --method acceleration only (default: the source's).")] = None,
    calibration_terms: Annotated[str, typer.Option("--calibration-terms", help="--method calibrate[_rollout]: every (an offset and a "
                                                                               "damping in every non-flight equation) or support "
                                                                               "(only where the source has the term).")] = "every",
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda or rk4 (batch): the val rollouts.")] = "rk4",
    force: Force = False,
) -> None:
    """Fine-tune a model on new jumps (the phases they hold), checked on their val split."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.data.io import read_dataset
    from symrom.experiments.finetune import FineTuneCheck, check_data, run_finetune, write_finetune
    from symrom.learn.finetune import FineTuneConfig
    from symrom.model.persistence import load_model

    check_output_file(out, force, inputs=(model_path, data))
    _check_split_and_integrator("val", integrator)
    check = FineTuneCheck(FineTuneConfig(prior_weight=prior_weight, threshold=threshold,
                                         refit_decoder=not keep_decoder, method=method,
                                         calibration_terms=calibration_terms),
                          tolerance=tolerance,
                          integrator=integrator)
    model = load_model(model_path)
    ds = read_dataset(data)
    check_data(model, ds, check.config)  # refused before any work
    with console.status("fine-tuning") as status:
        result = run_finetune(model, ds, check, progress=lambda msg: status.update(f"fine-tuning: {msg}"))
    tuned = result.model
    tuned.info["data_path"] = str(data)
    tuned.info["finetune"]["source_model"] = str(model_path)
    record = result.to_dict()
    with atomic_dir(out, force) as tmp:
        write_finetune(tmp, result)
    out_console.print(f"fine-tuning rows (train): {_phase_rows(ds, ds.rows_of('train'))}",
                      highlight=False, soft_wrap=True)
    for name in record["phases_kept"]:
        console.print(f"[yellow]warning:[/yellow] phase {name!r}: no rows in the train split of {data}: its "
                      "source coefficients are kept", highlight=False, soft_wrap=True)
    dec = record["decoder"]
    out_console.print(("decoder: refit towards the source" if dec["refit"] else "decoder: the source's (kept)")
                      + f"; the rows vary by at least {100 * dec['excitation']:.3g} % of the source's latent spread "
                      f"in every direction; max |W_d| {dec['max_abs_W_d_source']:.3g} -> {dec['max_abs_W_d']:.3g}",
                      highlight=False, soft_wrap=True)
    raised = "" if len(result.attempts) == 1 else (
        f" (prior weight raised to {record['prior_weight']:g}: at " + ", ".join(
            f"{a['prior_weight']:g} the score was {a['score']:.4g}" for a in result.attempts[:-1]) + ")")
    out_console.print(f"refit phases: {', '.join(record['phases_refit'])}; val ({ds.jumps_in('val').size} jumps): score "
                      f"{record['score_before']:.4g} -> {record['score_after']:.4g} (mean RMSE / spread, both "
                      f"horizons; at most +{100 * tolerance:g} % allowed), diverged {record['diverged_before']} -> "
                      f"{record['diverged_after']}{raised}", highlight=False, soft_wrap=True)
    _calibration_lines(record)
    _divergence_warnings(result.after)
    out_console.print(f"model: {out / 'model.json'}  val before: {out / 'val_before' / 'metrics.json'}  "
                      f"after: {out / 'val_after' / 'metrics.json'}", highlight=False, soft_wrap=True)


def _calibration_lines(record: dict) -> None:
    """The calibrated gains per phase, the flight test and the fine-tuned flight gravity."""
    cal = record.get("calibration")
    for name, p in (cal or {}).get("phases", {}).items():
        if p["calibrated"]:
            def values(kind: str, added: list[bool]) -> str:  # "*": a calibration term the source lacked
                return ", ".join("-" if x is None else f"{x:+.3g}" + ("*" if new else "")
                                 for x, new in zip(p[kind], added))

            n = len(p["gain"])
            g = ", ".join("-" if x is None else f"{x:.3g}" for x in p["gain"])
            o = values("offset", p.get("offset_added", [False] * n))
            d = values("damping", p.get("damping_added", [False] * n))
            added = any(p.get("offset_added", [])) or any(p.get("damping_added", []))
            out_console.print(f"calibrated {name}: input gains [{g}], offsets [{o}] latent units/s², damping [{d}] 1/s"
                              + (" (*: a calibration term the source's equation lacked)" if added else ""),
                              highlight=False, soft_wrap=True)
    rolled = record.get("phases_rolled_out") or []
    if cal and rolled:
        out_console.print(f"then refined on rollouts of the train jumps: {', '.join(rolled)} (from the calibrated "
                          "coefficients; the other phases as calibrated)", highlight=False, soft_wrap=True)
    test = (cal or {}).get("flight_test")
    if test:
        se = "-" if test["se"] is None else f"{test['se']:.2g}"  # None: a single jump
        out_console.print(f"flight test: decoded z acceleration residual {test['mean']:+.3g} ± {se} m/s² "
                          f"over {test['jumps']} jumps (contradicts the source above {test['limit']:.2g} and "
                          f"{test['t_limit']:g} standard errors): gravity "
                          + ("calibrated" if test["contradicted"] else "kept"), highlight=False, soft_wrap=True)
    fg = record.get("flight_gravity")
    if fg:
        out_console.print(f"flight gravity: {fg['model']:.3g} m/s² ({100 * fg['ratio']:.1f} % of g; the data "
                          f"{fg['data']:.3g})", highlight=False, soft_wrap=True)
        if abs(fg["ratio"] - 1.0) > 0.05:
            console.print(f"[yellow]warning:[/yellow] the fine-tuned flight equations fall at {-fg['model']:.3g} "
                          f"m/s², more than 5 % from g (the data's flight rows: {-fg['data']:.3g} m/s²)",
                          highlight=False, soft_wrap=True)


@app.command("equations", cls=_Command)
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
    stab = model.stability()
    if stab:
        typer.echo("\n% linearised at each phase's training mean: eigenvalues (1/s)" if latex
                   else "\nlinearised at each phase's training mean: eigenvalues (1/s)")
        for st in stab:
            zs = sorted(st.eigenvalues, key=lambda z: (-z.real, z.imag))
            if latex:
                eig = ",\\ ".join(f"{z.real:.3g} {'+' if z.imag >= 0 else '-'} {abs(z.imag):.3g}i"
                                   if abs(z.imag) > 1e-12 else f"{z.real:.3g}" for z in zs)
                growth = "" if st.growth is None else (rf" \quad \text{{(fastest mode $\times${st.growth:.3g} "
                                                       rf"over {st.duration_s:.3g} s)}}")
                name = st.phase.replace("_", r"\_")
                typer.echo(rf"\lambda_{{\mathrm{{{name}}}}} \in \{{{eig}\}}{growth}")
                continue
            eig = ", ".join(f"{z.real:.3g}{z.imag:+.3g}j" if abs(z.imag) > 1e-12 else f"{z.real:.3g}" for z in zs)
            growth = "" if st.growth is None else f"  (fastest mode x{st.growth:.3g} over {st.duration_s:.3g} s)"
            typer.echo(f"[{st.phase}] {eig}{growth}")
    _model_warnings(model)


@app.command("export", cls=_Command)
@guarded
def export_cmd(
    model_path: Annotated[Path, typer.Argument(help="Model file (model.json).")],
    to: Annotated[str, typer.Option("--to", help="c (C99 source and header), casadi (casadi.Function files) or python.")],
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
    out_console.print(f"{to} export of {model_path} (sha256 {model_hash(model)[:12]}, phases "
                      f"{', '.join(model.phase_names)}): " + ", ".join(str(out / p.name) for p in written),
                      highlight=False, soft_wrap=True)


@app.command("reproduce", cls=_Command)
@guarded
def reproduce_cmd(
    out: Annotated[Path, typer.Option("--out", help="Run directory; existing datasets and results are reused.")],
    quick: Annotated[bool, typer.Option("--quick", help="A reduced run that takes a few minutes.")] = False,
    workers: Annotated[Optional[int], typer.Option(
        "--workers", help="Generation, selection and sweep: " + WORKERS_HELP.format(local=2))] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of every dataset and training run.")] = 0,
    no_report: Annotated[bool, typer.Option("--no-report", help="Skip the HTML/Markdown report.")] = False,
    backend: BackendName = "local",
    address: Address = None,
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    only: Annotated[Optional[str], typer.Option(
        "--only", help="Run one part only: sim2real (with the SIM Go1 selection it needs).")] = None,
    max_terms: Annotated[Optional[int], typer.Option(
        "--max-terms", help="Term budget of the SIM selections: refinements pruned to at most N active terms "
                            "(compact models; e.g. 60). Default: none.")] = None,
) -> None:
    """Run the paper's experiments end to end into one directory (resumable)."""
    import shlex
    from dataclasses import replace

    from symrom.atomic import check_writable
    from symrom.experiments.reproduce import PARTS, ReproduceConfig, reproduce

    if only is not None and only not in PARTS:
        raise ValueError(f"--only {only!r}: not a part of the run; one of: {', '.join(PARTS)}")
    if max_terms is not None and max_terms < 1:
        raise ValueError(f"--max-terms must be a positive number of terms, got {max_terms}")
    check_writable(out, inside=True)  # a run directory is written into, in place
    runner = _start_backend(backend, workers, address, local_default=2)
    from symrom.sim.engines.registry import check_engine

    cfg = replace(ReproduceConfig.quick() if quick else ReproduceConfig(), workers=runner.workers, seed=seed,
                  backend=backend, address=getattr(runner, "address", None), engine=check_engine(engine))
    if max_terms is not None:
        cfg = replace(cfg, selection=replace(cfg.selection, max_terms=max_terms))
    command = "symrom " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    with console.status("reproduce") as status:
        def say(msg: str, transient: bool = False) -> None:
            status.update(f"reproduce: {msg}")
            if not transient:
                console.log(msg)

        summary = reproduce(out, cfg, command=command, say=say, only=only)
        if not no_report:
            from symrom.report.html import build_report

            status.update("reproduce: report")
            html, _ = build_report(out, out / "report.html")
    for name, exp in summary["experiments"].items():
        full = exp["metrics"]["horizons"]["full"]
        typer.echo(f"{name}: l={exp['latent_dim']}, {exp['n_candidates']} library terms, active terms "
                   f"{exp['active_terms']}, diverged {full['diverged_jumps']}/{exp['metrics']['n_jumps']}")
    if summary.get("sim2real", {}).get("targets"):
        from symrom.report.sim2real import sim2real_markdown

        typer.echo(sim2real_markdown(summary["sim2real"]["targets"]))
    if "sweep" in summary:
        typer.echo(f"best latent dimension (L_mod): {summary['sweep']['best_latent_dim']}")
    typer.echo(f"summary: {out / 'summary.json'}" + ("" if no_report else f"\nreport: {out / 'report.html'}"))


@app.command("demo", cls=_Command)
@guarded
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output directory.")] = Path("symrom-demo"),
    jumps: Annotated[int, typer.Option("--jumps", help="Go1 pronking jumps to simulate.")] = 12,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes for the simulation.")] = 2,
    force: Force = False,
) -> None:
    """Simulate a dozen Go1 jumps, train, evaluate, fit the aSLIP and write the report."""
    import shlex

    from symrom.atomic import atomic_dir, check_output_file
    from symrom.evaluate.tables import table2
    from symrom.experiments.demo import demo_config
    from symrom.experiments.reproduce import reproduce
    from symrom.report.html import build_report

    check_output_file(out, force)
    _check_workers(workers)
    cfg = demo_config(jumps, workers=workers)
    command = "symrom " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    with atomic_dir(out, force) as tmp:
        with console.status("demo") as status:
            def say(msg: str, transient: bool = False) -> None:
                status.update(f"demo: {msg}")
                if not transient:
                    console.log(msg)

            summary = reproduce(tmp, cfg, command=command, say=say)
        go1 = summary["experiments"]["go1_sim"]
        text = (tmp / "go1_sim" / "equations.txt").read_text().rstrip("\n")
    # The report is built where the run now is, so that it names that directory.
    with console.status("demo: report"):
        build_report(out, out / "report.html")
    typer.echo(text)
    typer.echo(table2(go1["metrics"], title="SIM Go1, test split"))
    typer.echo(f"best latent dimension (L_mod): {summary['sweep']['best_latent_dim']}")
    out_console.print(f"dataset: {out / go1['data']}  ({cfg.datasets[0].jumps} simulated jumps)\n"
                      f"model: {out / go1['model']}\nreport: {out / 'report.html'}", highlight=False,
                      soft_wrap=True)


@app.command("aslip", cls=_Command)
@guarded
def aslip_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (metrics.json, params.json, table.md).")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    fit: Annotated[str, typer.Option("--fit", help="residual (acceleration residual) or rollout (CoM rollout error, from the residual fit).")] = "residual",
    fixed: Annotated[bool, typer.Option("--fixed", help="Use the paper's k_s=250 N/m, l_0=0.32 m, m=12.01 kg (overridable) instead of fitting.")] = False,
    k_s: Annotated[Optional[float], typer.Option("--k-s", help="Spring constant, N/m (with --fixed).")] = None,
    l0: Annotated[Optional[float], typer.Option("--l0", help="Rest length, m (with --fixed).")] = None,
    mass: Annotated[Optional[float], typer.Option("--mass", help="Body mass, kg (default: URDF total; paper's with --fixed).")] = None,
    reset: Annotated[Optional[list[float]], typer.Option("--reset", help="Reset period(s) in s (repeatable).")] = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda (the paper's) or rk4 (batch).")] = "lsoda",
    force: Force = False,
) -> None:
    """Fit (train split) or fix the aSLIP baseline and evaluate its CoM prediction on a split."""
    from dataclasses import asdict

    from symrom.atomic import check_output_file
    from symrom.baselines.aslip import PAPER_PARAMS, ASlip, ASlipParams, fit_aslip, fit_aslip_rollout, robot_mass

    check_output_file(out, force, inputs=(data,))
    _check_split_and_integrator(split, integrator)
    resets = _parse_resets(reset)
    if fit not in ("residual", "rollout"):
        raise ValueError(f"--fit must be residual or rollout, got {fit!r}")
    if not fixed and (k_s is not None or l0 is not None):
        raise ValueError("--k-s/--l0 set a fixed model: add --fixed (without it both are fitted)")
    ds = _read_with_split(data, split)
    extra = {}
    if fixed:
        params = ASlipParams(k_s=PAPER_PARAMS.k_s if k_s is None else k_s,
                             l_0=PAPER_PARAMS.l_0 if l0 is None else l0,
                             m=PAPER_PARAMS.m if mass is None else mass)
        how = "fixed"
    else:
        m = robot_mass(ds.robot) if mass is None else mass
        with console.status(f"fitting k_s, l_0 on the train split ({fit})"):
            params = fit_aslip(ds, ds.rows_of("train"), m)
            if fit == "rollout":
                params, record = fit_aslip_rollout(ds, m=m, start=params)
                extra["stages"] = record.stages
        how = (f"fitted on the train split ({fit} error)"
               + ("" if mass is not None else f" (mass from the {ds.robot} URDF)"))
    params_text = json.dumps({**asdict(params), "units": {"k_s": "N/m", "l_0": "m", "m": "kg"},
                              "source": how, **extra}, indent=1) + "\n"
    _evaluate_baseline(ASlip(params), ds, data, split, resets, integrator, out, force, "aSLIP",
                       {"params.json": params_text})
    out_console.print(f"aSLIP ({how}): k_s {params.k_s:.4g} N/m, l_0 {params.l_0:.4g} m, m {params.m:.4g} kg; "
                      f"metrics: {out / 'metrics.json'}", highlight=False, soft_wrap=True)


@app.command("newton", cls=_Command)
@guarded
def newton_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (metrics.json, table.md).")],
    split: Annotated[str, typer.Option("--split", help="train, val or test.")] = "test",
    mass: Annotated[Optional[float], typer.Option("--mass", help="Body mass, kg (default: the robot's total).")] = None,
    reset: Annotated[Optional[list[float]], typer.Option("--reset", help="Reset period(s) in s (repeatable).")] = None,
    integrator: Annotated[str, typer.Option("--integrator", help="lsoda or rk4 (batch).")] = "lsoda",
    fit: Annotated[bool, typer.Option("--fit", help="Fit b'' = c + A F/m (contact), c_f (flight) on the train split.")] = False,
    force: Force = False,
) -> None:
    """Evaluate Newton's law on the measured ground force, b'' = g + F/m, on a split (--fit: its
    gains and offsets fitted on the train split)."""
    from symrom.atomic import check_output_file
    from symrom.baselines.newton import AffineForce, Newton

    check_output_file(out, force, inputs=(data,))
    _check_split_and_integrator(split, integrator)
    resets = _parse_resets(reset)
    ds = _read_with_split(data, split)
    if fit:
        model, title = AffineForce.fit(ds, m=mass), "Newton (fitted)"
        files = {"params.json": json.dumps({**model.to_dict(), "source": "fitted on the train split "
                                            "(least squares on the base accelerations)"}, indent=1) + "\n"}
    else:
        model, title, files = Newton.of(ds, mass), "Newton", {}
    _evaluate_baseline(model, ds, data, split, resets, integrator, out, force, title, files)
    out_console.print(f"{title} (m {model.m:.4g} kg): metrics: {out / 'metrics.json'}", highlight=False,
                      soft_wrap=True)


def _check_split_and_integrator(split: str, integrator: str) -> None:
    if split not in ("train", "val", "test"):
        raise ValueError(f"--split must be train, val or test, got {split!r}")
    if integrator not in ("lsoda", "rk4"):
        raise ValueError(f"--integrator must be lsoda or rk4, got {integrator!r}")


def _read_with_split(data: Path, split: str):
    from symrom.data.io import read_dataset

    ds = read_dataset(data)
    if ds.jumps_in(split).size == 0:
        raise ValueError(f"{data} has no {split!r} jumps")
    return ds


def _evaluate_baseline(model, ds, data: Path, split: str, resets: tuple[float | None, ...], integrator: str,
                       out: Path, force: bool, title: str, files: dict[str, str]) -> None:
    """Roll a CoM baseline out on ``split``, print its table and write metrics, table and ``files``."""
    from symrom.atomic import atomic_dir
    from symrom.evaluate.metrics import evaluate
    from symrom.evaluate.outputs import write_baseline
    from symrom.evaluate.tables import table2
    from symrom.rollout.integrate import RolloutOptions

    with progress_bar() as bar:
        task = bar.add_task(f"{title} rollouts", total=len(resets) * ds.jumps_in(split).size)
        metrics, _ = evaluate(model, ds, split, resets, RolloutOptions(method=integrator),
                              model_name=title, data_name=str(data), progress=_ticker(bar, task))
    title = f"{title}, {ds.robot} {ds.motion} ({split})"
    with atomic_dir(out, force) as tmp:
        write_baseline(tmp, metrics, tuple(model.components), title, files)
    typer.echo(table2(metrics, components=tuple(model.components), title=title))
    _divergence_warnings(metrics)


@app.command("jump", cls=_Command)
@guarded
def jump_cmd(
    target_x: Annotated[float, typer.Option("--target-x", help="Forward landing distance from the start of the push, m.")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (landing.json, trajectory.json).")],
    model_path: Annotated[Optional[Path], typer.Argument(
        help="The planner's model: model.json (learned) or an aSLIP params.json (aslip, from symrom aslip); "
             "point-mass needs none.")] = None,
    robot: Annotated[Optional[str], typer.Option("--robot", help="Robot: go1, a1, laikago or a description PATH.toml "
                                                 "(default: the learned model's robot, else go1).")] = None,
    target_z: Annotated[Optional[float], typer.Option("--target-z", help="Apex height of the base, m (default: at least the pronk's nominal apex).")] = None,
    planner: Annotated[str, typer.Option("--planner", help="learned, point-mass or aslip.")] = "learned",
    guards: Annotated[str, typer.Option("--guards", help="height (lift-off and touchdown at the take-off height) "
                                        "or learned (the model's own contact switches; learned planner).")] = "height",
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    trajectory: Annotated[bool, typer.Option("--trajectory/--no-trajectory", help="Also write trajectory.json.")] = True,
    force: Force = False,
) -> None:
    """Plan a pronk to a target with a model (CasADi/IPOPT) and execute it in simulation."""
    import importlib.util

    from symrom.atomic import check_output_file
    from symrom.sim.engines.registry import ENGINES

    if importlib.util.find_spec("casadi") is None:
        raise ValueError("symrom jump plans with CasADi and IPOPT, which are not installed: pip install 'symrom[export]'")
    from symrom.plan.jump import GUARDS, PLANNERS, jump, make_planner, read_aslip_params, write_landing

    if planner not in PLANNERS:
        raise ValueError(f"--planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
    if engine not in ENGINES:
        raise ValueError(f"--engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if guards not in GUARDS or (guards == "learned" and planner != "learned"):
        raise ValueError(f"--guards must be height or (with --planner learned) learned, got {guards!r}")
    if planner != "point-mass" and model_path is None:
        raise ValueError(f"the {planner} planner needs its model: "
                         + ("model.json" if planner == "learned" else "an aSLIP params.json (symrom aslip)"))
    check_output_file(out, force, inputs=() if model_path is None else (model_path,))
    model = aslip = None
    if planner == "learned":
        from symrom.model.persistence import load_model

        model = load_model(model_path)
    elif planner == "aslip":
        aslip = read_aslip_params(model_path)
    robot = robot or (model.info.get("robot") if model is not None else None) or "go1"
    with console.status(f"building the {planner} planner"):
        built = make_planner(planner, robot, model=model, aslip=aslip, guards=guards)
    with console.status(f"planning and simulating a jump to x = {target_x} m ({engine})"):
        result = jump(built, target_x, target_z, engine=engine)
    write_landing(out, result, trajectory=trajectory, force=force)
    ex = result.execution
    if result.apex_rule == "at least reachable" and result.apex_floor is not None:
        console.print(f"warning: no plan holds the apex at the pronk's nominal {built.nominal_apex:.3f} m within the "
                      f"torque limits; held at or above {result.apex_floor:.3f} m instead (--target-z sets it)",
                      highlight=False)
    if not result.reachable:
        console.print(f"warning: x = {target_x} m is out of the {planner} model's reach under the force, friction "
                      f"and stance bounds; the closest plan lands at {ex.plan.landing_x:.3f} m", highlight=False)
    out_console.print(f"{planner} plan ({1e3 * ex.plan.solve_time_s:.1f} ms): landed at x = {ex.landing_x:.3f} m "
                      f"for a target of {target_x:.3f} m (error {100 * result.error_x:+.1f} cm), apex "
                      f"{ex.apex_z:.3f} m; {out / 'landing.json'}", highlight=False, soft_wrap=True)


@app.command("report", cls=_Command)
@guarded
def report_cmd(
    run_dir: Annotated[Path, typer.Argument(help="Run directory (symrom reproduce, demo) or model folder (symrom train; "
                                                 "its evaluation's metrics.json in it or a subfolder).")],
    out: Annotated[Optional[Path], typer.Option("--out", help="Output HTML file (default DIR/report.html); the Markdown twin and its figures go next to it.")] = None,
    force: Force = False,
) -> None:
    """Build the self-contained HTML report (and its Markdown twin) of a run directory or a model folder."""
    from symrom.atomic import check_writable
    from symrom.report.html import build_report

    if not run_dir.is_dir():
        raise ValueError(f"{run_dir}: no such run directory")
    out = run_dir / "report.html" if out is None else out
    if out.suffix.lower() not in (".html", ".htm"):
        raise ValueError(f"--out {out}: expected an .html file")
    check_writable(out)
    with console.status("report") as status:
        html, md = build_report(run_dir, out, force=force,
                                progress=lambda msg: status.update(f"report: {msg}"))
    out_console.print(f"report: {html}\nmarkdown: {md}", highlight=False, soft_wrap=True)


@app.command("generate", cls=_Command)
@guarded
def generate_cmd(
    robot: Annotated[str, typer.Option("--robot", help="go1, a1 or the path of a robot description file (.toml).")],
    motion: Annotated[str, typer.Option("--motion", help="pronk (convex MPC) or froggy (Cartesian PD); both scale to any robot.")],
    jumps: Annotated[int, typer.Option("--jumps", help="Number of jumps.")],
    out: Annotated[Path, typer.Option("--out", help="Output dataset file (HDF5).")],
    noise: Annotated[bool, typer.Option("--noise", help="Noisy variant: start pose, readings, CoM pushes.")] = False,
    proxy: Annotated[bool, typer.Option("--proxy", help="Hardware-like robot (source=proxy; pronk).")] = False,
    randomize: Annotated[bool, typer.Option("--randomize", help="Domain-randomised source jumps: motion, "
                                            "masses, latency, friction, contact, joint damping, armature, "
                                            "friction loss and torque sensing drawn per jump (pronk).")] = False,
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    mpc_solver: Annotated[Optional[str], typer.Option("--mpc-solver", help="QP solver of pronk's MPC: osqp (ADMM, "
                                                      "to 1e-3) or daqp (active set, exact, a third of the time); "
                                                      "default: the engine's (osqp in PyBullet, daqp in MuJoCo).")] = None,
    workers: Annotated[Optional[int], typer.Option("--workers", help=WORKERS_HELP.format(local=1))] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed.")] = 0,
    resume: Annotated[bool, typer.Option("--resume", help="Continue an interrupted run (OUT.parts).")] = False,
    backend: BackendName = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Simulate jumps (PyBullet or MuJoCo), check them and write a dataset file."""
    from symrom.atomic import check_writable
    from symrom.robots import get_robot
    from symrom.sim.generation.generate import (GenerateConfig, NoiseConfig, check_config, check_output, generate,
                                     run_record_path)

    check_output(out, resume, force)  # fail before connecting or drawing the progress bar
    check_writable(out)
    _check_workers(workers)
    config = check_config(GenerateConfig(robot, motion, jumps, seed=seed, proxy=proxy, randomize=randomize,
                                         noise=NoiseConfig() if noise else None, engine=engine,
                                         mpc_solver=mpc_solver))
    runner = _start_backend(backend, workers, address)
    label = f"{get_robot(config.robot).name} {motion} ({engine})"
    with progress_bar() as bar:
        task = bar.add_task(label, total=jumps)
        retries, lost = [0], [0]

        def _progress(done: int, total: int, info: dict) -> None:
            retries[0] += int(info.get("retries", 0))
            lost[0] += int(info.get("worker_retries", 0))
            note = f" ({info['resumed']} resumed)" if info.get("resumed") else ""
            note += f", {lost[0]} lost to dying workers" if lost[0] else ""
            bar.update(task, completed=done, total=total,
                       description=f"{label}: jump {done}/{total}, {retries[0]} retries{note}")

        ds = generate(config, out, resume=resume, force=force, progress_callback=_progress, backend=runner)
    counts = {s: int((ds.split == s).sum()) for s in ("train", "val", "test")}
    record = json.loads(run_record_path(out).read_text())
    lost_note = (f"; {record['worker_retries']} attempt(s) lost to dying workers, run again"
                 if record["worker_retries"] else "")
    out_console.print(f"data: {out}  ({ds.n_jumps} jumps, {ds.n_samples} samples, "
                      f"{ds.generator['retries']} retries; split {counts}){lost_note}\n"
                      f"run record: {run_record_path(out)}", highlight=False)


@app.command("show", cls=_Command)
@guarded
def show_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory for the PNG frames.")],
    jump: Annotated[int, typer.Option("--jump", help="Jump index.")] = 0,
    frames: Annotated[int, typer.Option("--frames", help="Number of frames.")] = 8,
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP + " MuJoCo needs OpenGL (EGL).")] = "pybullet",
    force: Force = False,
) -> None:
    """Render frames of one logged jump (replayed in PyBullet or MuJoCo) as PNG files."""
    from symrom.atomic import check_writable
    from symrom.data.io import read_dataset
    from symrom.sim.engines.registry import check_engine
    from symrom.sim.diagnostics.render import render_jump

    check_engine(engine)
    if out.exists() and any(out.glob(f"jump_{jump:04d}_t*.png")) and not force:
        raise FileExistsError(f"{out} already holds frames of jump {jump}; use --force to overwrite them")
    check_writable(out, inside=True)
    ds = read_dataset(data)
    with console.status(f"rendering jump {jump}"):
        paths = render_jump(ds, jump, out, n_frames=frames, engine=engine)
    out_console.print(f"frames: {len(paths)} PNG in {out}", highlight=False)


@app.command("forces", cls=_Command)
@guarded
def forces_cmd(
    data: Annotated[list[Path], typer.Argument(help="Simulated dataset files (HDF5) with contact_force.")],
) -> None:
    """The torque-derived ground force (the input u's) against the engine's own contact force."""
    from symrom.data.io import read_dataset
    from symrom.robots import get_robot
    from symrom.sim.diagnostics.forces import AXES, force_error

    for path in data:
        r = force_error(read_dataset(path))
        out_console.print(f"{path}: {get_robot(r.robot).name}, {r.engine}, {r.samples} samples, "
                          f"weight {r.weight:.1f} N", highlight=False, soft_wrap=True)
        for name in AXES:
            a = r.axes[name]
            out_console.print(f"  F{name}: RMS error {a.rms:7.2f} N, peak error {a.peak:7.2f} N, "
                              f"correlation {a.corr:5.3f}, peak torque-derived {a.peak_torque:7.1f} N "
                              f"vs engine {a.peak_engine:7.1f} N", highlight=False)


@app.command("sweep", cls=_Command)
@guarded
def sweep_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (sweep.json, cells/ for resuming).")],
    latent_dims: Annotated[str, typer.Option("--latent-dims", help="Dimensions: 1-18, 1,2,4 or 1-3,6.")] = "1-18",
    seeds: Annotated[int, typer.Option("--seeds", help="Seeds per dimension (bootstrap resamples with exact).")] = 5,
    solver: Annotated[str, typer.Option("--solver", help="exact (closed form) or adam (torch).")] = "exact",
    poly_order: Annotated[int, typer.Option("--poly-order", help="Polynomial order p of the library.")] = 1,
    lam: Annotated[float, typer.Option("--lambda", help="Complexity weight of L_mod.")] = 0.001,
    workers: Annotated[Optional[int], typer.Option("--workers", help=WORKERS_HELP.format(local=1))] = None,
    rmse_test: Annotated[bool, typer.Option("--rmse-test/--no-rmse-test", help="Also roll out the test split (rk4) per cell.")] = True,
    backend: BackendName = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Accuracy vs complexity over latent dimensions and seeds; resumes from OUT/cells."""
    from symrom.atomic import check_output_file
    from symrom.data.io import read_dataset
    from symrom.experiments.sweep import SweepConfig, parse_latent_dims, run_sweep

    _check_workers(workers)
    dims = parse_latent_dims(latent_dims)
    config = SweepConfig(latent_dims=dims, seeds=seeds, poly_order=poly_order, solver=solver,
                         lam=lam, workers=1 if workers is None else workers, rmse_test=rmse_test)
    check_output_file(out / "sweep.json", force, inputs=(data,))
    ds = read_dataset(data)
    runner = _start_backend(backend, workers, address)
    with progress_bar() as bar:
        task = bar.add_task("sweep", total=len(dims) * len(config.seeds))

        def tick(done, total, info):
            what = "reused" if info["reused"] else "done"
            bar.update(task, completed=done,
                       description=f"sweep: l={info['latent_dim']} seed {info['seed']} {what}")

        result = run_sweep(ds, config, out, progress=tick, backend=runner)
    for d, e, a, lm in zip(result["latent_dims"], result["E_dec_mean"], result["active_terms_mean"],
                           result["L_mod"]):
        out_console.print(f"l={d:2d}  E_dec {e:.3e}  |Xi| {a:7.1f}  L_mod {lm:.4e}", highlight=False)
    out_console.print(f"best latent dimension: {result['best_latent_dim']} (lambda {lam:g}); "
                      f"results: {out / 'sweep.json'}", highlight=False, soft_wrap=True)


# ------------------------------------------------------------------ robot descriptions
robot_app = typer.Typer(cls=_Group, add_completion=False, no_args_is_help=True,
                        help="Robot descriptions: write one from a robot model, show one as symrom reads it.")
app.add_typer(robot_app, name="robot")


def _parse_sets(items: list[str] | None) -> dict:
    """--set KEY=VALUE (VALUE in TOML: 0.3, [23.7, 23.7, 35.55], "go1") -> {KEY: value}."""
    import tomllib

    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        try:
            if not sep:
                raise tomllib.TOMLDecodeError("no '='")
            out[key.strip()] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE with a TOML value, e.g. "
                             f"stance.knee=[-2.8, -0.3]") from None
    return out


@robot_app.command("init", cls=_Command)
@guarded
def robot_init_cmd(
    model: Annotated[Path, typer.Argument(help="Robot model: an MJCF (.xml; e.g. a MuJoCo Menagerie model) or a URDF (.urdf).")],
    out: Annotated[Path, typer.Option("--out", help="Robot description to write (.toml).")],
    name: Annotated[Optional[str], typer.Option("--name", help="The robot's name (default: the model's).")] = None,
    sets: Annotated[Optional[list[str]], typer.Option(
        "--set", help="KEY=VALUE: a description key the model cannot give (stance.knee, stance.height, "
                      "stance.joints, limits.torque, actuators.*, name), VALUE in TOML; repeatable.")] = None,
    force: Force = False,
) -> None:
    """Write a checked robot description from a robot model alone."""
    from symrom.robots.init import RobotInitError, init_robot

    try:
        r = init_robot(model, out, name=name, overrides=_parse_sets(sets), force=force)
    except RobotInitError as e:
        if e.key is None:
            raise
        raise RobotInitError(f"{e} (--set {e.key}=VALUE)", e.key) from None
    d = r.description
    out_console.print(f"wrote {r.path}: {d.name}, {d.mass:.3f} kg, feet {d.feet.kind if d.feet else 'link'}, "
                      f"kinematics within {r.kinematics_error:.1e} m of MuJoCo's"
                      + (f"; given: {', '.join(r.given)}" if r.given else ""), highlight=False, soft_wrap=True)


@robot_app.command("show", cls=_Command)
@guarded
def robot_show_cmd(
    robot: Annotated[str, typer.Argument(help="A built-in robot (go1, a1, laikago) or a robot description file (.toml).")],
) -> None:
    """Print a robot description as symrom reads it: legs, joints, feet, masses, limits, stance."""
    from rich.table import Table

    from symrom.robots.show import robot_summary

    s = robot_summary(robot)
    model = f"{s.model}" + (f" (URDF derived: {s.urdf})" if s.urdf_derived else "")
    for line in (f"{s.name}: {s.source} (format {s.format})", f"model: {model}",
                 f"base {s.base_link!r}; mass {s.mass:.3f} kg (base {s.base_mass:.3f} kg, legs "
                 f"{', '.join(f'{leg.mass:.3f}' for leg in s.legs)}); foot radius {s.foot_radius:g} m; "
                 f"leg length {s.leg_length:.4f} m; standing height {s.start_height:g} m"):
        out_console.print(line, highlight=False, soft_wrap=True)
    table = Table("leg", "joint", "name", "sign", "range (rad)", "torque (N m)", "stance (rad)", "damping",
                  "armature", "friction")
    a = s.actuators
    for k, leg in enumerate(s.legs):
        for r, role in enumerate(("hx", "hy", "kn")):
            i = 3 * k + r
            table.add_row(leg.leg if r == 0 else "", role, leg.joints[r], f"{leg.signs[r]:+d}",
                          f"[{leg.lower[r]:.3g}, {leg.upper[r]:.3g}]", f"{leg.torque[r]:g}", f"{leg.stance[r]:+.4f}",
                          f"{a.damping[i]:g}", f"{a.armature[i]:g}", f"{a.friction_loss[i]:g}")
    out_console.print(table)
    legs = Table("leg", "foot", "hip (m, base frame)", "thigh (m)", "calf (m)", "knee range (rad)")
    for leg in s.legs:
        legs.add_row(leg.leg, leg.foot, "(" + ", ".join(f"{x:+.4f}" for x in leg.hip) + ")", f"{leg.thigh:.4f}",
                     f"{leg.calf:.4f}", f"[{leg.knee_range[0]:g}, {leg.knee_range[1]:g}]")
    out_console.print(legs)


def main() -> None:  # pragma: no cover - entry point
    app(sys.argv[1:])
