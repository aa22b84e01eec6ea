"""What every command shares: the typer application, the consoles, the error boundary (library
errors as one line, their parameters named as flags), progress bars and the common options.

Nothing heavy is imported here: ``symrom --help`` and ``symrom --version`` load no numerical
library (each command imports what it needs when it runs).
"""

from __future__ import annotations

import functools
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperCommand, TyperGroup


def _flags_without_type(params: list) -> list:
    """Boolean flags take no value: show no type (typer's help would say ``<bool>``)."""
    for p in params:
        if getattr(p, "is_flag", False) and p.metavar is None:
            p.metavar = ""
    return params


def _help_off_by_default(option):
    """A help option absent from the command line reads False, not None: typer coerces a flag's
    non-bool value through pydantic, whose import would double a command's ``--help`` time."""
    if option is not None and option.default is None:
        option.default = False
    return option


try:  # typer's coercion seam (``_plain_values``); another typer keeps its own coercion throughout
    from typer._coercion import RuntimeParam, build_runtime_param
    from typer._param_types import coerce_cli_path
except ImportError:  # pragma: no cover - depends on the installed typer
    RuntimeParam = None

_PLAIN_INT = re.compile(r"[+-]?(0|[1-9][0-9]*)")

if RuntimeParam is not None:
    class _Plain(RuntimeParam):
        """A text, integer or path option's coercion without pydantic (``_plain_values``)."""

        def _coerce_value(self, value, param, ctx):
            kind = self.annotation
            if kind is str and isinstance(value, str):
                return value
            if kind is int and (type(value) is int or isinstance(value, str) and _PLAIN_INT.fullmatch(value)):
                return int(value)
            if kind is Path and isinstance(value, (str, Path)):
                return coerce_cli_path(Path(value), self.parameter_info, path_type=Path, param=param, ctx=ctx)
            return build_runtime_param(param.type_descriptor)._coerce_value(value, param=param, ctx=ctx)


def _plain_values(params: list) -> list:
    """typer coerces every option's value through pydantic, whose import would be a large part
    of a command's start-up: a text, integer or path option (one value, no parser, range or
    choices) is coerced here instead, as pydantic does for its plain values (a text as it is,
    digits as their integer, a path as ``Path`` with typer's own checks); any other value goes
    to typer's coercion, with its messages."""
    if RuntimeParam is None:
        return params
    for p in params:
        desc = getattr(p, "type_descriptor", None)
        if (desc is None or getattr(p, "_runtime_param", 0) is not None or desc.annotation not in (str, int, Path)
                or p.nargs != 1 or p.multiple or desc.file_annotation is not None or desc.is_ranged
                or desc.choices is not None or desc.parameter_info.parser is not None
                or getattr(desc.parameter_info, "path_type", None) is not None):
            continue
        p._runtime_param = _Plain(parameter_info=desc.parameter_info, annotation=desc.annotation)
    return params


class Group(TyperGroup):
    def get_params(self, ctx):
        return _plain_values(_flags_without_type(super().get_params(ctx)))

    def get_help_option(self, ctx):
        return _help_off_by_default(super().get_help_option(ctx))


class Command(TyperCommand):
    def get_params(self, ctx):
        return _plain_values(_flags_without_type(super().get_params(ctx)))

    def get_help_option(self, ctx):
        return _help_off_by_default(super().get_help_option(ctx))


class _Console:
    """A rich console made on first use: help pages and ``--version`` never load rich. Its
    methods are the console's; ``real()`` is the console itself, for what rich holds on to."""

    def __init__(self, **options) -> None:
        self._options, self._console = options, None

    def real(self):
        if self._console is None:
            from rich.console import Console

            self._console = Console(**self._options)
        return self._console

    def __getattr__(self, name: str):
        return getattr(self.real(), name)


# Help pages in click's plain text: typer's rich help loads rich and a Markdown parser, which
# would be most of ``symrom --help``'s time.
app = typer.Typer(cls=Group, add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Symbolic reduced-order models of legged-robot jumping, learned from data.")
console = _Console(stderr=True, log_path=False)  # log lines: time and message, no cli.py:NNN
out_console = _Console()

STATE = {"debug": False}

Force = Annotated[bool, typer.Option("--force", help="Overwrite an existing output.")]
BackendName = Annotated[str, typer.Option(
    "--backend", help="Where the tasks run: local (processes on this machine) or ray (a Ray cluster; "
                      "pip install 'symrom[ray]').")]
Address = Annotated[str | None, typer.Option(
    "--address", help="Ray cluster address (host:port, ray://host:10001, auto or local); default "
                      "$RAY_ADDRESS, else a cluster started on this machine with ray start, else a new Ray "
                      "instance on this machine.")]
ENGINE_HELP = "Physics engine: pybullet or mujoco (docs/engines.md)."
WORKERS_HELP = ("Worker processes (local back end; default {local}), or the most tasks at once on Ray "
                "(default: the cluster's CPUs).")


# ------------------------------------------------------------------ library parameters as flags
# Library errors name their parameters as Python keywords (``split='x'``, ``force=True``); the
# command line names the flag that sets each. A value-specific spelling first, then the name.
FLAG_VALUES: dict[str, str] = {
    "force=True": "--force", "resume=True": "--resume", "lenient=True": "--lenient",
    "resample=False": "--no-resample", "refit_decoder=False": "--keep-decoder", "physics=None": "--no-physics",
    "retime=True": "--retime-stale", "fixed=True": "--fixed", "refine=True": "--refine", "select=True": "--select",
    "proxy=True": "--proxy", "randomize=True": "--randomize", "trig=False": "--no-trig", "closest=True": "--closest",
}
FLAGS: dict[str, str] = {
    "out": "--out", "split": "--split", "threshold": "--threshold", "max_terms": "--max-terms",
    "workers": "--workers", "resets": "--reset", "integrator": "--integrator", "phases": "--phases",
    "plot_jumps": "--plot-jump", "diff_window": "--diff-window", "diff_method": "--diff", "torques": "--torques",
    "positions": "--positions", "segment": "--segment", "dt": "--dt", "max_gap": "--max-gap", "topics": "--topics",
    "method": "--method", "engine": "--engine", "address": "--address", "backend": "--backend",
    "target_x": "--target-x", "target_z": "--target-z", "mass": "--mass", "m": "--mass", "polish": "--polish",
    "keep": "--keep",
    "latent_dims": "--latent-dims", "select_dims": "--select-dims", "to": "--to", "planner": "--planner",
    "guards": "--guards", "only": "--only", "n_jumps": "--jumps", "fit": "--fit", "k_s": "--k-s", "l_0": "--l0",
    "latent_dim": "--latent-dim", "poly_order": "--poly-order", "solver": "--solver", "measure": "--measure",
    "collinearity": "--collinearity", "alpha": "--alpha", "decoded_weight": "--decoded-weight",
    "encoder_components": "--encoder-components", "encoder_scaling": "--encoder-scaling",
    "encoder_base_latents": "--encoder-base-latents", "epochs": "--epochs", "seed": "--seed",
    "prior_weight": "--prior-weight", "tolerance": "--tolerance", "calibration_terms": "--calibration-terms",
    "mpc_solver": "--mpc-solver", "motion": "--motion", "robot": "--robot", "jump": "--jump", "frames": "--frames",
    "seeds": "--seeds", "lam": "--lambda", "control": "--control", "payload": "--payload", "friction": "--friction",
    "motor_scale": "--motor-scale", "period": "--period", "repair": "--repair", "log_faults": "--log-faults",
    "invariant": "--invariant",
}
_PARAMETER = re.compile(r"(?<![\w./-])([a-z][a-z0-9_]*)=(?:(True|False|None)|'([\w.,/+-]+)')?")


def flag_text(message: str, flags: dict[str, str] | None = None) -> str:
    """``message`` with each library parameter it names (``name=value``) as the flag that sets
    it: ``split='1,2'`` -> ``--split 1,2``, ``force=True`` -> ``--force``; ``flags``: a
    command's own names beyond ``FLAGS``. Names no flag sets stay as they are."""
    table = {**FLAGS, **(flags or {})}

    def repl(m: re.Match) -> str:
        name, const, word = m.group(1), m.group(2), m.group(3)
        if const is not None and f"{name}={const}" in FLAG_VALUES:
            return FLAG_VALUES[f"{name}={const}"]
        if name in table:
            if const is not None or word is not None:  # a simple value needs no quotes on a command line
                return f"{table[name]} {const if const is not None else word}"
            rest = m.string[m.end():m.end() + 1]
            return table[name] if not rest or rest.isspace() or rest in ",;:)" else f"{table[name]} "
        return m.group(0)

    return _PARAMETER.sub(repl, message)


# ------------------------------------------------------------------ the error boundary
def show_version(value: bool) -> None:
    if value:
        from symrom import __version__

        typer.echo(f"symrom {__version__}")
        raise typer.Exit()


@app.callback()
def _main(debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks on errors.")] = False,
          version: Annotated[bool, typer.Option("--version", callback=show_version, is_eager=True,
                                                help="Print the version and exit.")] = False) -> None:
    STATE["debug"] = debug


def guarded(fn: Callable) -> Callable:
    """Turn library errors into one red line and exit code 1 (tracebacks with --debug); the
    parameters the message names become the command's flags (``flag_text``)."""

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
            quiet_stdout()
            raise typer.Exit(141) from None  # as a shell reports a process ended by SIGPIPE
        except Exception as e:  # noqa: BLE001 - the CLI boundary
            if STATE["debug"]:
                raise
            msg = str(e).strip().splitlines()[0] if str(e).strip() else e.__class__.__name__
            from rich.markup import escape

            console.print(f"[red]error:[/red] {escape(flag_text(msg))}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None

    return wrapper


def quiet_stdout() -> None:
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


# ------------------------------------------------------------------ printing
def say(text: str) -> None:
    """A result line on stdout (no markup, no highlighting)."""
    out_console.print(text, highlight=False, soft_wrap=True, markup=False)


def note(text: str) -> None:
    """A note on stderr (no markup)."""
    console.print(text, highlight=False, soft_wrap=True, markup=False)


def warn(text: str) -> None:
    """A warning line on stderr."""
    from rich.markup import escape

    console.print(f"[yellow]warning:[/yellow] {escape(text)}", highlight=False, soft_wrap=True)


def warn_all(lines) -> None:
    for line in lines:
        warn(line)


class progress_bar:
    """A progress bar drawn on its first update, so that a command refused before any work
    shows only its error line. ``update(completed=, total=, description=)``; ``count`` is a
    ``(done, total)`` callback; used as a context manager."""

    def __init__(self, description: str = "", total: float | None = None) -> None:
        self.description, self.total = description, total
        self._bar = self._task = None

    def __enter__(self) -> progress_bar:
        return self

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.stop()

    def update(self, completed: float | None = None, total: float | None = None,
               description: str | None = None) -> None:
        if self._bar is None:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self._bar = Progress(TextColumn("{task.description}"), BarColumn(),
                                 TextColumn("{task.percentage:>3.0f}%"), TimeElapsedColumn(), console=console.real(),
                                 transient=False)
            self._task = self._bar.add_task(self.description, total=self.total)
            self._bar.start()
        changes = {k: v for k, v in (("completed", completed), ("total", total), ("description", description))
                   if v is not None}
        self._bar.update(self._task, **changes)

    def count(self, done: int, total: int) -> None:
        """A ``(done, total)`` progress callback."""
        self.update(completed=done, total=total)


def status_say(status, label: str) -> Callable[..., None]:
    """A ``say(message, transient=False)`` callback: the status line shows every message, the
    log keeps those that are not transient (counts)."""
    def say_(msg: str, transient: bool = False) -> None:
        status.update(f"{label}: {msg}")
        if not transient:
            console.log(msg)

    return say_


def invariant_components(text: str | None) -> tuple[str, ...] | None:
    """``--invariant``: None when not given, () for ``none``, else the comma-separated components
    (the library checks them)."""
    if text is None:
        return None
    return () if text.strip().lower() == "none" else tuple(c.strip() for c in text.split(",") if c.strip())


def command_line() -> str:
    """The command as typed (for a run's record)."""
    import shlex

    return "symrom " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def start_backend(name: str, workers: int | None, address: str | None, local_default: int = 1):
    """The execution back end of the options, started (a Ray back end connects here, so a bad
    address fails before any work)."""
    from symrom.execution import make_backend

    backend = make_backend(name, local_default if workers is None and name == "local" else workers, address)
    if name == "ray":
        with console.status("connecting to Ray"):
            backend.start()
        info = backend.describe()
        console.print(f"ray: {info['nodes']} node(s), {info['cpus']} CPUs, {backend.workers} tasks at once",
                      highlight=False)
    return backend
