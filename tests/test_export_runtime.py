"""The exports' static runtime: strict C that computes the model's numbers, and the Python runtime
run on its own tables."""

import ctypes
import importlib.util
import shutil
import subprocess
from dataclasses import replace
from importlib.resources import files

import numpy as np
import pytest

from symrom.export import export
from symrom.learn.training import TrainConfig, train

CC = shutil.which("gcc") or shutil.which("cc")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror"]


@pytest.fixture(scope="module")
def models(planted_block):
    """A model with guards and the input map (read as a Go1 model), and one with neither, of one
    latent, whose flight phase has no term at all (its dynamics read neither s nor nu)."""
    ds, _ = planted_block
    full = train(ds, TrainConfig(latent_dim=2, poly_order=2))
    prov = full.provenance
    full = replace(full, provenance=replace(prov, data=replace(prov.data, robot="go1")))
    bare = train(ds, TrainConfig(latent_dim=1))
    flight = bare.phase_names.index("flight")
    Xi, mask = bare.Xi.copy(), bare.mask.copy()
    Xi[flight], mask[flight] = 0.0, False
    bare = replace(bare, Xi=Xi, mask=mask, guards=None)
    return ds, {"full": full, "bare": bare}


def _compile(files_, tmp_path, name):
    so = tmp_path / f"{name}.so"
    out = subprocess.run([CC, *STRICT, "-O2", "-shared", "-fPIC", "-o", str(so), str(files_[1]), "-lm"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr  # any warning is an error
    return ctypes.CDLL(str(so))


@pytest.mark.skipif(CC is None, reason="no C compiler")
@pytest.mark.parametrize("which", ["full", "bare"])
def test_c_export_compiles_clean_under_strict_flags_and_computes_the_models_numbers(models, which, tmp_path):
    ds, by_name = models
    model = by_name[which]
    lib = _compile(export(model, "c", tmp_path / which), tmp_path, which)
    D, I = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
    l = model.latent_dim
    rng = np.random.default_rng(1)
    for phase in range(len(model.phase_names)):  # the dynamics of every phase, at random states
        for _ in range(5):
            s, nu, dd = rng.normal(size=2 * l), rng.normal(size=l), np.zeros(l)
            assert lib.symrom_accel(ctypes.c_int(phase), s.ctypes.data_as(D), nu.ctypes.data_as(D),
                                    dd.ctypes.data_as(D)) == 0
            ref = model.latent_acceleration(s[None, :l], s[None, l:], nu[None], np.array([phase]))[0]
            np.testing.assert_allclose(dd, ref, rtol=1e-12, atol=1e-12)
    j = int(ds.jumps_in("test")[0])
    a, b = ds.jump_bounds()[j]
    n, u = b - a, np.ascontiguousarray(ds.u[a:b])
    sched = model.phase_index(ds)[a:b]
    modes = {"schedule": model.predict_path(ds.q[a], ds.dq[a], u, ds.dt, phases=sched)}
    if model.guards:
        modes["guards"] = model.predict_path(ds.q[a], ds.dq[a], u, ds.dt)
        assert modes["guards"].switches
    for mode, p in modes.items():
        q, dq = np.zeros((n, 18)), np.zeros((n, 18))
        ph = np.ascontiguousarray(sched if mode == "schedule" else np.zeros(n), dtype=np.int32)
        div = lib.symrom_predict_path(ctypes.c_int(n), ctypes.c_double(ds.dt), ctypes.c_int(2),
                                      np.ascontiguousarray(ds.q[a]).ctypes.data_as(D),
                                      np.ascontiguousarray(ds.dq[a]).ctypes.data_as(D), u.ctypes.data_as(D),
                                      ctypes.c_int(mode == "guards"), ctypes.c_int(0), ph.ctypes.data_as(I),
                                      q.ctypes.data_as(D), dq.ctypes.data_as(D))
        assert div == p.diverged_at == -1
        np.testing.assert_array_equal(ph, p.phase)
        np.testing.assert_allclose(q, p.q, atol=1e-9, rtol=0)
        np.testing.assert_allclose(dq, p.dq, atol=1e-9, rtol=0)
    if not model.guards:  # no guard: the phase never changes
        s, nu = np.zeros(2 * l), np.zeros(l)
        assert lib.symrom_guard_switch(ctypes.c_int(1), ctypes.c_int(10 ** 6), ctypes.c_double(ds.dt),
                                       s.ctypes.data_as(D), nu.ctypes.data_as(D)) == 1


def _runtime():
    path = files("symrom.export").joinpath("runtime", "symrom_runtime.py")
    spec = importlib.util.spec_from_file_location("symrom_runtime_under_test", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_python_runtime_integrates_and_switches_on_its_own_tables():
    """An oscillator ddxi = -w^2 xi read from q[0] (phase 0) until a guard xi >= 0.4 after
    0.05 s switches it to free fall ddxi = -g (phase 1): the runtime's path is the exact
    solution to RK4's error and the switch falls on the first sample past xi = 0.4."""
    rt, w, g, dt = _runtime(), 2.0, 9.81, 0.002
    W_E, W_D = np.zeros((1, 18)), np.zeros((18, 1))
    W_E[0, 0] = W_D[0, 0] = 1.0
    model = rt.Runtime(1, ["spring", "fall"], W_E, np.zeros(1), W_D, np.zeros(18), np.linalg.pinv(W_E),
                       [lambda s, nu: np.array([-w ** 2 * s[0]]), lambda s, nu: np.array([-g])],
                       np.full(2, 1e3), 1e-12, [(0, 1, 0.05, -0.4, [(0, 1.0)])])
    q0, dq0 = np.zeros(18), np.zeros(18)
    dq0[0] = 1.0  # xi(t) = sin(w t) / w, peaking at 0.5
    n = 400
    q, dq, phases = model.predict_path(q0, dq0, np.zeros((n, 18)), dt)
    t = np.arange(n) * dt
    k = int(np.flatnonzero(phases)[0])
    assert phases[k:].all() and not phases[:k].any()
    assert q[k, 0] >= 0.4 > q[k - 1, 0]  # the first sample the guard reads past 0.4
    np.testing.assert_allclose(q[:k + 1, 0], np.sin(w * t[:k + 1]) / w, atol=1e-10)
    # after the switch: free fall from the state at the switch
    x, v = q[k, 0], dq[k, 0]
    tt = t[k:] - t[k]
    np.testing.assert_allclose(q[k:, 0], x + v * tt - g * tt ** 2 / 2, atol=1e-9)
    np.testing.assert_allclose(q[:, 1:], 0.0)
    with pytest.raises(ValueError, match="unknown phase 2"):
        model.accel(2, np.zeros(2), np.zeros(1))
    with pytest.raises(ValueError, match="no input map"):
        model.input_from_torques(q0, np.zeros(12), np.ones(4))


def test_the_runtime_files_are_package_data():
    """Every file of the runtime ships with the package: pyproject's package-data globs cover it."""
    import tomllib
    from pathlib import Path

    import symrom

    root = Path(symrom.__file__).parent
    globs = tomllib.loads((root.parents[1] / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    shipped = {p for g in globs["symrom"] for p in root.glob(g)}
    runtime = {p for p in (root / "export" / "runtime").iterdir() if p.is_file()}
    assert {p.name for p in runtime} >= {"symrom_runtime.c", "symrom_runtime.h", "symrom_runtime.py"}
    assert runtime <= shipped, sorted(p.name for p in runtime - shipped)
