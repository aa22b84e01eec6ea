"""The ``symrom`` command line (typer): each command parses its options, calls one library
function and prints that result's own summary.

Every command exits non-zero with one clear line on bad input (a traceback only with
``--debug``; the library's parameters named as the command's flags), writes its outputs
atomically and never overwrites an existing output without ``--force``. One module per group
of commands: ``data`` (generate, import, show, forces), ``learn`` (train, finetune, sweep,
equations, export), ``evaluate`` (evaluate, aslip, newton), ``run`` (reproduce, demo, report),
``plan`` (jump), ``robot`` (robot init, robot show); ``common`` holds what they share.

The entry point is ``main`` (pyproject: ``symrom.cli:main``). Importing this package loads
nothing but the standard library: ``symrom --version`` answers without building the command
tree, ``app`` (the typer application, every command registered) and ``console`` are made on
first use, and no module imports a numerical library at import time, so that ``symrom --help``
stays fast too.
"""

import sys

__all__ = ["app", "console", "main"]


def main() -> None:  # pragma: no cover - entry point
    args = sys.argv[1:]
    if args == ["--version"]:  # the same line as the application's eager option, without typer
        from symrom import __version__

        print(f"symrom {__version__}")
        return
    if "--help" not in args:  # a help page loads no NumPy
        from symrom.execution import pin_blas_kernel

        pin_blas_kernel()  # before NumPy loads: the same arithmetic on every machine that runs it
    if next((a for a in args if not a.startswith("-")), None) != "show":  # the one command that draws
        import os

        # so MuJoCo's import does not look for an OpenGL library this command never uses
        os.environ.setdefault("MUJOCO_GL", "disable")
    try:
        __getattr__("app")(args)
    finally:
        # What the command leaves lives until the process ends: out of the collector's reach, so
        # that Python's exit does not sweep it for cycles (a generation leaves some 150,000
        # objects, most of them numba's); nothing of it needs a finaliser run.
        import gc

        gc.freeze()


def __getattr__(name: str):
    if name in ("app", "console"):
        from symrom.cli import data, evaluate, learn, plan, robot, run  # noqa: F401 - registers the commands
        from symrom.cli.common import app, console

        globals().update(app=app, console=console)
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
