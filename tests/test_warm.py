"""The learning's kernels made ready ahead (``symrom.experiments.warm``): after ``warm()`` a run's
work compiles nothing more, so a run that waits for the helper has its selection's workers load
every kernel instead of compiling it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from tests._simdata import reference_file

SRC = Path(__file__).resolve().parents[1] / "src"

# warm(), then what a run does with real data: a selection with its refinement, the evaluation
# of its model with each integrator, every baseline fitted and evaluated. Prints the compiled
# specialisations of every routine after warm() and at the end.
CODE = """
import json, sys
from symrom.baselines import BASELINES, fit_baseline
from symrom.data.io import read_dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.experiments.select import SelectionConfig, select
from symrom.experiments.warm import cold, routines, warm
from symrom.rollout.integrate import RolloutOptions

def signatures():
    return {d.py_func.__qualname__: sorted(map(str, d.signatures)) for d in routines()}

warm()
after_warm = signatures()
ds = read_dataset(sys.argv[1])
sel = select(ds, SelectionConfig(encoders=("base_position",), latent_dims=(3,), libraries=("poly1+trig+inputs",),
                                 thresholds=(3e-3,), refine_top=1, checks=()))
assert sel.model is not None, sel.notes
for method in ("rk4", "lsoda"):
    evaluate_model(sel.model, ds, "test", (None, 0.1), RolloutOptions(method))
for name in BASELINES:
    evaluate_model(fit_baseline(name, ds), ds, "test", (None, 0.1), RolloutOptions("rk4"))
print(json.dumps({"cold": cold(), "after_warm": after_warm, "after_run": signatures()}))
"""


def test_after_warm_a_run_compiles_no_kernel_again():
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), *filter(None, [os.environ.get("PYTHONPATH")])]))
    r = subprocess.run([sys.executable, "-c", CODE, str(reference_file("pronk"))], capture_output=True, text=True,
                       timeout=900, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["cold"] is False  # every routine is in numba's disk cache
    assert all(out["after_warm"].values()), out["after_warm"]  # warm() made each one
    assert out["after_run"] == out["after_warm"]  # and the run needed no other specialisation
