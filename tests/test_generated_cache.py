"""The auto backend: the generated code once a build is at hand (this process or the disk cache)."""

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from symrom import compiled
from symrom.compiled import codegen
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import GENERATED_PAYS_STEPS, RolloutOptions, rollout


@pytest.fixture(scope="module")
def model_and_data(planted_block):
    # l = 1: the tests compile its generated code four times (two processes, cache on and off),
    # each build the cheaper for the smaller model
    ds, _ = planted_block
    return train(ds, TrainConfig(latent_dim=1, poly_order=1)), ds


def _q(model, ds, backend):
    return rollout(model, ds, ds.jumps_in("test"), RolloutOptions("rk4", backend=backend)).q_pred[0]


def _ran(model, ds, backend, monkeypatch) -> tuple[np.ndarray, list[str]]:
    """``_q``, and which integrators it ran ("table", "generated"): the rollout system's
    compiled integrator and generated-code factory, each wrapped to say when it is used."""
    ran: list[str] = []
    cls, build = type(model), type(model).rollout_system

    def counted(fn, name):
        def call(*args, **kwargs):
            ran.append(name)
            return fn(*args, **kwargs)
        return None if fn is None else call

    def system(self, *args, **kwargs):
        sysm = build(self, *args, **kwargs)
        return dataclasses.replace(sysm, compiled=counted(sysm.compiled, "table"),
                                   generated=counted(sysm.generated, "generated"))

    with monkeypatch.context() as m:
        m.setattr(cls, "rollout_system", system)
        return _q(model, ds, backend), ran


def test_auto_takes_the_generated_code_once_built_and_the_disk_cache_serves_a_new_process(
        model_and_data, tmp_path, monkeypatch):
    model, ds = model_and_data
    monkeypatch.setenv(compiled.CACHE_ENV, str(tmp_path / "cache"))
    codegen._CACHE.clear()
    assert not compiled.has_build(model.dynamics())
    table = _q(model, ds, "table")
    auto, ran = _ran(model, ds, "auto", monkeypatch)
    assert ran == ["table"]  # a small rollout: no compilation
    np.testing.assert_array_equal(auto, table)
    assert not compiled.has_build(model.dynamics())
    gen = _q(model, ds, "generated")
    np.testing.assert_allclose(gen, table, rtol=1e-9, atol=1e-12)  # the same equations, compiled
    assert compiled.has_build(model.dynamics())
    auto, ran = _ran(model, ds, "auto", monkeypatch)
    assert ran == ["generated"]  # once built, auto takes the generated code
    np.testing.assert_array_equal(auto, gen)
    (module,) = (tmp_path / "cache").glob("symrom_model_*.py")
    assert module.with_suffix(".built").is_file()
    # a new process finds the build on disk; a cached module that differs from the model's
    # source is written again before anything of it runs
    module.write_text(module.read_text() + "\nraise SystemExit('not ours')\n")
    from symrom.model.persistence import save_model

    save_model(model, tmp_path / "m.json")
    code = ("import sys; from symrom.model.persistence import load_model; from symrom import compiled; "
            f"m = load_model({str(tmp_path / 'm.json')!r}); print(compiled.has_build(m.dynamics())); "
            "compiled.generated(m.dynamics()); print(compiled.has_build(m.dynamics()))")
    env = {**os.environ, compiled.CACHE_ENV: str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(Path(compiled.__file__).parents[2]), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "True"]  # the tampered module was no build; rebuilt
    assert "not ours" not in module.read_text()


def test_auto_compiles_when_the_work_pays(model_and_data, monkeypatch):
    model, ds = model_and_data
    monkeypatch.setenv(compiled.CACHE_ENV, "off")
    codegen._CACHE.clear()
    assert compiled.cache_dir() is None and not compiled.has_build(model.dynamics())
    import importlib

    monkeypatch.setattr(importlib.import_module("symrom.rollout.integrate"), "GENERATED_PAYS_STEPS", 10)
    np.testing.assert_array_equal(_q(model, ds, "auto"), _q(model, ds, "generated"))
    assert GENERATED_PAYS_STEPS > 1e6


def test_without_a_term_table_auto_compiles_once_its_numpy_work_reaches_the_compile(planted_block, monkeypatch):
    """A custom block has no term table, so ``auto``'s alternative is NumPy: its steps are
    counted per model in the process, and the generated code is compiled once they would
    reach ``GENERATED_PAYS_NUMPY_STEPS``, not before."""
    import importlib

    from symrom.compiled.kernel import term_table
    from symrom.learn.estimator import SymbolicROM
    from symrom.model.library import Custom, Inputs, Polynomial

    integrate = importlib.import_module("symrom.rollout.integrate")
    ds, _ = planted_block
    monkeypatch.setenv(compiled.CACHE_ENV, "off")
    rom = SymbolicROM(1, Polynomial(1) + Inputs() + Custom(("exp(-xi1**2)",), ("bump",)))  # l = 1: a cheaper build
    model = rom.fit(ds).model
    assert term_table(model.library.terms) is None
    codegen._CACHE.clear()
    monkeypatch.setattr(integrate, "_NUMPY_STEPS", {})
    steps = (max(b - a for a, b in ds.jump_bounds()[ds.jumps_in("test")]) - 1) * RolloutOptions().substeps
    monkeypatch.setattr(integrate, "GENERATED_PAYS_NUMPY_STEPS", steps + steps // 2)
    numpy = _q(model, ds, "numpy")
    np.testing.assert_array_equal(_q(model, ds, "auto"), numpy)  # the first: below the price, NumPy
    assert not compiled.has_build(model.dynamics()) and integrate._NUMPY_STEPS == {model.dynamics().key: steps}
    second = _q(model, ds, "auto")  # with the first's steps it reaches the price: compiled by auto
    assert compiled.has_build(model.dynamics())
    np.testing.assert_array_equal(second, _q(model, ds, "generated"))
    np.testing.assert_allclose(second, numpy, rtol=0, atol=1e-9 * np.abs(numpy).max())


def test_the_first_rollout_after_the_build_compiles_nothing_more(model_and_data, tmp_path, monkeypatch):
    # The build compiles for the argument types the integrators pass (the bounds read-only, as
    # batch.rollout_jumps hands them over): a second build at the first rollout doubled its cost.
    model, ds = model_and_data
    monkeypatch.setenv(compiled.CACHE_ENV, str(tmp_path / "cache"))
    codegen._CACHE.clear()
    entry = codegen._compiled(model.dynamics())
    kernel = entry["rollout"]
    assert len(kernel.signatures) == 1
    for reset in (None, 0.1):
        rollout(model, ds, None, RolloutOptions("rk4", reset=reset, backend="generated"))
    assert len(kernel.signatures) == 1, kernel.signatures
    # SciPy's LSODA's right-hand side is not part of the build: compiled at its first call, once
    assert entry["rhs"].signatures == []
    jumps = ds.jumps_in("test")[:1]
    lsoda = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="generated", lsoda_solver="scipy"))
    assert len(entry["rhs"].signatures) == 1, entry["rhs"].signatures
    reference = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="numpy", lsoda_solver="scipy"))
    np.testing.assert_allclose(lsoda.q_pred[0], reference.q_pred[0], rtol=0, atol=1e-9)
