"""The command line starts light: ``symrom --version``, ``--help`` and a command's ``--help``
load no numerical library (each command imports what it needs when it runs)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("numpy", "scipy", "sympy", "numba", "pybullet", "mujoco", "h5py", "matplotlib", "casadi", "torch")

# Runs the command as the console script does (symrom.cli:main), or through the typer application
# itself (``app``), then lists the heavy modules loaded.
CODE = """
import json, sys
sys.argv = ["symrom", *json.loads(sys.argv[1])]
from symrom.cli import {entry}
try:
    {entry}()
except SystemExit:
    pass
sys.stdout.flush()
print("\\nLOADED " + json.dumps(sorted(m for m in {heavy} if m in sys.modules)))
"""


def _loaded(*args: str, entry: str = "main", heavy: tuple[str, ...] = HEAVY) -> tuple[str, list[str]]:
    r = subprocess.run([sys.executable, "-c", CODE.format(heavy=heavy, entry=entry), json.dumps(args)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    out, _, tail = r.stdout.rpartition("\nLOADED ")
    return out, json.loads(tail)


@pytest.mark.parametrize("args", [("--version",), ("--help",), ("train", "--help"), ("import", "--help")])
def test_version_and_help_import_no_numerical_library(args):
    out, loaded = _loaded(*args)
    assert out.strip(), "the command printed nothing"
    assert loaded == [], f"symrom {' '.join(args)} imported {loaded}"


def test_version_answers_without_the_command_tree():
    """``symrom --version`` (the console script's ``main``) prints what the application's own
    ``--version`` prints, without loading typer, click or rich; the probe sees typer loaded where
    the application answers."""
    light, loaded = _loaded("--version", heavy=("typer", "rich"))
    full, loaded_app = _loaded("--version", entry="app", heavy=("typer", "rich"))
    assert light == full and light.startswith("symrom ") and loaded == [], (light, full, loaded)
    assert loaded_app == ["typer"]


def test_python_m_symrom_is_the_command():
    """``python -m symrom`` runs the console script's ``main``: the same version line, and a
    command's errors leave with the command's exit status."""
    version = subprocess.run([sys.executable, "-m", "symrom", "--version"], capture_output=True, text=True, timeout=120)
    assert version.returncode == 0 and version.stdout == _loaded("--version")[0], version
    bad = subprocess.run([sys.executable, "-m", "symrom", "train", "--help", "--no-such-flag"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "no-such-flag" in bad.stderr, bad


@pytest.mark.parametrize("args", [("--help",), ("train", "--help"), ("robot", "show", "--help")])
def test_help_pages_load_neither_rich_nor_pydantic(args):
    """Help pages are click's plain text: rich (and the Markdown parser typer's rich help pulls
    in) and pydantic (which typer reaches for to coerce an absent help flag) are most of a help
    page's time. The probe sees rich where a command prints through its console."""
    out, loaded = _loaded(*args, heavy=("rich", "pydantic", "markdown_it"))
    assert "Usage: symrom" in out and loaded == [], (args, loaded)
    _, loaded = _loaded("equations", "/nonexistent/model.json", heavy=("rich",))
    assert loaded == ["rich"]


def test_plain_options_are_parsed_without_pydantic():
    """A command whose options are text, integers and paths parses them without pydantic (the
    import typer 0.29 makes to coerce any value), and a value that is not an integer still gets
    typer's own message."""
    out, loaded = _loaded("generate", "--robot", "nosuchrobot", "--jumps", "3", "--out", "/nonexistent/d/x.h5",
                          heavy=("pydantic",))
    assert loaded == [], out
    r = subprocess.run([sys.executable, "-c", "from symrom.cli import main; main()", "generate", "--jumps", "abc",
                        "--out", "x.h5"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Invalid value for '--jumps'" in r.stderr, r.stderr


def test_a_command_that_works_does_load_them():
    """The probe sees a heavy import when there is one (so the test above can fail)."""
    _, loaded = _loaded("equations", "/nonexistent/model.json")
    assert "numpy" in loaded


def test_import_symrom_is_light_and_names_load_on_use():
    code = ("import sys, symrom; light = 'numpy' not in sys.modules; symrom.SymbolicROM; "
            "print(light, 'numpy' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.split() == ["True", "True"], r.stderr


# SciPy's packages below take 0.3-0.6 s each to import (their array-API layer loads numpy.f2py and
# numpy.testing): each is imported in the function that runs it, not by the modules around it.
SCIPY_SLOW = ("scipy.integrate", "scipy.interpolate", "scipy.optimize", "scipy.special", "scipy.stats")
LIBRARY = ("symrom.rollout.integrate", "symrom.rollout.fitting", "symrom.evaluate.metrics", "symrom.baselines.aslip",
           "symrom.data.importers", "symrom.data.repair", "symrom.data.timebase", "symrom.learn.training",
           "symrom.learn.finetune", "symrom.experiments.select", "symrom.experiments.reproduce",
           "symrom.report.figures", "symrom.plan.jump")


def test_scipys_slow_packages_load_where_they_run(tmp_path):
    """Importing the library's modules loads none of SciPy's slow packages, and neither does a
    CSV import (no repair) that checks the log against physics; an LSODA rollout loads
    scipy.integrate (so the probe can see one)."""
    from _logs import jump, write_plain
    from _simdata import reference_file

    from symrom.data.io import read_dataset

    code = ("import importlib, json, sys\n"
            "for name in json.loads(sys.argv[1]):\n"
            "    importlib.import_module(name)\n"
            "print(json.dumps(sorted(m for m in json.loads(sys.argv[2]) if m in sys.modules)))\n")
    r = subprocess.run([sys.executable, "-c", code, json.dumps(LIBRARY), json.dumps(SCIPY_SLOW)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and json.loads(r.stdout) == [], (r.stdout, r.stderr)

    ds = read_dataset(reference_file("pronk"))
    log = write_plain(tmp_path / "log.csv", [jump(ds, j) for j in range(2)], accelerations=False)
    out, loaded = _loaded("import", str(log), "--robot", ds.robot, "--out", str(tmp_path / "x.h5"),
                          heavy=SCIPY_SLOW + ("numpy",))
    assert (tmp_path / "x.h5").is_file() and loaded == ["numpy"], (out, loaded)

    probe = ("import sys, numpy as np\n"
             "from symrom.rollout.integrate import integrate_lsoda\n"
             "x = np.zeros((3, 1))\n"
             "integrate_lsoda(lambda y, t: np.r_[y[1:], -y[:1]], lambda k: (), x, x, np.zeros(3, bool),\n"
             "                np.full(2, 10.0), 0.01, 500)\n"
             "print('scipy.integrate' in sys.modules)\n")
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert r.stdout.split() == ["True"], r.stderr
