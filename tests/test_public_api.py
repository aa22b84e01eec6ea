"""One public vocabulary: every public name loads, none shadows a subpackage, every submodule
imports after ``import symrom`` and is reached as an attribute; ``SymbolicROM`` is the entry
point (fit, from_config, load, save, simulate, equations), ``evaluate_model`` scores any model,
every baseline is made by ``Baseline.fit(ds)``."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import numpy as np
import pytest

import symrom

# Extras a module may need (pyproject's optional dependencies): a module that cannot import
# because one is missing is skipped, any other failure is one.
OPTIONAL = ("ray", "numbalsoda", "casadi", "pysindy")

WALK = """
import functools, importlib, json, pkgutil, sys
import symrom
public = {n: type(getattr(symrom, n)).__name__ for n in symrom.__all__}  # every public name, loaded first
failed, skipped, shadowed, seen = {}, {}, [], []
for info in pkgutil.walk_packages(symrom.__path__, "symrom."):
    if info.name.endswith(".__main__"):
        continue  # runs the command line
    try:
        importlib.import_module(info.name)
    except ModuleNotFoundError as e:
        (skipped if e.name.split(".")[0] in OPTIONAL else failed)[info.name] = repr(e)
        continue
    except Exception as e:
        failed[info.name] = repr(e)
        continue
    seen.append(info.name)
    try:
        reached = functools.reduce(getattr, info.name.split(".")[1:], symrom)
    except AttributeError as e:
        reached = e
    if reached is not sys.modules[info.name]:
        shadowed.append(f"symrom.{'.'.join(info.name.split('.')[1:])} is {reached!r}")
print(json.dumps({"public": public, "failed": failed, "skipped": skipped, "shadowed": shadowed, "seen": seen}))
"""


def test_every_submodule_imports_after_import_symrom_and_none_is_shadowed():
    r = subprocess.run([sys.executable, "-c", f"OPTIONAL = {OPTIONAL!r}\n" + WALK], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["failed"] == {}, out["failed"]
    assert out["shadowed"] == [], out["shadowed"]
    assert (len(out["seen"]) > 100 and "symrom.rollout.system" in out["seen"]
            and "symrom.evaluate.metrics" in out["seen"])
    subpackages = {m.split(".")[1] for m in out["seen"] if m.count(".") >= 1}
    assert not (set(out["public"]) - {"names"}) & subpackages, "a public name is also a subpackage"


def test_the_walk_would_see_a_shadowing_name(monkeypatch):
    """What the walk checks fails when a public name is a function named like a subpackage."""
    import functools
    import importlib

    importlib.import_module("symrom.rollout.system")
    monkeypatch.setattr(symrom, "rollout", lambda *a: None, raising=False)
    with pytest.raises(AttributeError):
        functools.reduce(getattr, ["rollout", "system"], symrom)


def test_the_public_names():
    assert set(symrom.__all__) == {
        "SymbolicROM", "TrainConfig", "Dataset", "read_dataset", "write_dataset", "Library", "Polynomial",
        "Trigonometric", "Inputs", "Custom", "PCAEncoder", "STLSQ", "FineTune", "Refine", "HybridModel", "Provenance",
        "Equations", "evaluate_model", "Metrics", "RolloutOptions", "ASlip", "ASlipParams", "Newton", "AffineForce",
        "names"}
    for gone in ("train", "load_model", "save_model"):
        with pytest.raises(AttributeError):
            getattr(symrom, gone)
    importlib.import_module("symrom.evaluate.metrics")
    importlib.import_module("symrom.rollout.integrate")
    assert type(symrom.rollout).__name__ == type(symrom.evaluate).__name__ == "module"  # the packages


def test_one_entry_point_from_fit_to_file_and_back(planted_axis, tmp_path):
    ds, _ = planted_axis
    config = symrom.TrainConfig(trig=False, threshold=0.02)
    rom = symrom.SymbolicROM.from_config(config).fit(ds)
    # the same model as the settings' estimator fitted by hand, and the settings recorded
    by_hand = symrom.SymbolicROM(2, symrom.Polynomial(1) + symrom.Inputs(), regressor=symrom.STLSQ(0.02)).fit(ds)
    np.testing.assert_array_equal(rom.model.Xi, by_hand.model.Xi)
    assert symrom.TrainConfig.from_provenance(rom.model.provenance) == config
    assert by_hand.model.provenance.training.settings is None
    eq = rom.equations()
    assert isinstance(eq, symrom.Equations) and list(eq) == rom.model.phase_names
    assert str(eq).startswith("[contact]") and "ddxi1 =" in str(eq) and r"\ddot{\xi}_{1}" in eq.latex()
    assert all(len(eq[p]) == rom.model.latent_dim for p in eq)
    rom.save(tmp_path / "m.json")
    back = symrom.SymbolicROM.load(tmp_path / "m.json")
    assert back.model.provenance == rom.model.provenance and str(back.equations()) == str(eq)
    np.testing.assert_array_equal(back.simulate(ds, [0]).q_pred[0], rom.simulate(ds, [0]).q_pred[0])
    metrics, rollouts = symrom.evaluate_model(back, ds, "test")
    assert isinstance(metrics, symrom.Metrics) and set(rollouts) == {"full", "0.1"}
    assert metrics.full.diverged_jumps == 0 and metrics.rmse("x") < 0.05


def test_an_old_model_file_loads_through_the_entry_point(planted_axis, tmp_path):
    """A format 1 file records no plug-ins: SymbolicROM.load gives its model, and fit asks for them."""
    from conftest import as_format

    from symrom.model.persistence import model_to_dict

    ds, _ = planted_axis
    rom = symrom.SymbolicROM(2, symrom.Polynomial(1) + symrom.Inputs()).fit(ds)
    d = as_format(model_to_dict(rom.model), 2)
    d.pop("estimator")
    (tmp_path / "v2.json").write_text(json.dumps(d))
    old = symrom.SymbolicROM.load(tmp_path / "v2.json")
    np.testing.assert_array_equal(old.model.Xi, rom.model.Xi)
    assert old.encoder is None and old.regressor is None
    with pytest.raises(ValueError, match="records no plug-ins"):
        old.fit(ds)


def test_every_baseline_is_made_by_fit():
    """One idiom: ``Baseline.fit(ds)`` on the train split, its ``to_dict`` the params.json that
    reads it back."""
    from symrom.baselines import from_params
    from symrom.testing import make_slip_dataset

    ds, truth = make_slip_dataset(n_jumps=6, n_samples=300, seed=3)  # a robot without a description
    with pytest.raises(ValueError, match="give the mass explicitly"):
        symrom.Newton.fit(ds)
    for kind in (symrom.Newton, symrom.AffineForce, symrom.ASlip):
        b = kind.fit(ds, m=truth["m"])
        d = json.loads(json.dumps(b.to_dict()))
        assert d["model"] == kind.kind and d["source"] and d["format_version"] == 2
        assert from_params(d).to_dict() == b.to_dict()
        metrics, _ = symrom.evaluate_model(b, ds, "test", resets=(None,), options=symrom.RolloutOptions("rk4"))
        assert set(metrics.full.components) == {"x", "y", "z"}
    assert symrom.ASlip.fit(ds, m=truth["m"]).params.k_s == pytest.approx(truth["k_s"], rel=0.05)
    rolled = symrom.ASlip.fit(ds, m=truth["m"], objective="rollout")
    assert rolled.stages and "rollout" in rolled.source
