"""Models outside Python: the C, CasADi and Python exports roll a test jump out like symrom."""

import ctypes
import importlib.util
import shutil
import subprocess

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.export import export
from symrom.learn.training import TrainConfig, train
from symrom.model.persistence import model_hash, save_model
from symrom.rollout.integrate import RolloutOptions, rollout

SUBSTEPS = 2


@pytest.fixture(scope="module")
def model_and_jump(planted_block):
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=2, poly_order=2))  # monomials, trig and inputs all active
    j = int(ds.jumps_in("test")[0])
    return model, ds, j


def _reference(model, ds, j):
    ro = rollout(model, ds, [j], RolloutOptions("rk4", substeps=SUBSTEPS, backend="numpy"))
    return ro.xi[0], ro.dxi[0]


def _roll(encode, encode_input, step, model, ds, j):
    """The latent path (n, l) of jump j with an exported encoder and RK4 step."""
    a, b = ds.jump_bounds()[j]
    phases = model.phase_index(ds)[a:b]
    s = encode(ds.q[a], ds.dq[a])
    out = []
    for k in range(b - a):
        out.append(s.copy())
        nu = encode_input(ds.u[a + k])
        for _ in range(SUBSTEPS):
            s = step(int(phases[k]), s, nu, ds.dt / SUBSTEPS)
    return np.array(out)


@pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None, reason="no C compiler")
def test_c_export_compiles_and_matches(model_and_jump, tmp_path):
    model, ds, j = model_and_jump
    files = export(model, "c", tmp_path)
    header = (tmp_path / "symrom_model.h").read_text()
    assert model_hash(model) in header and "0: contact" in header and "1: flight" in header
    so = tmp_path / "model.so"
    cc = shutil.which("gcc") or shutil.which("cc")
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Werror", "-shared", "-fPIC", "-o", str(so),
                    str(files[1]), "-lm"], check=True, capture_output=True)
    lib = ctypes.CDLL(str(so))
    D = ctypes.POINTER(ctypes.c_double)
    l = model.latent_dim

    def encode(q, dq):
        s = np.zeros(2 * l)
        lib.symrom_encode(np.ascontiguousarray(q).ctypes.data_as(D), np.ascontiguousarray(dq).ctypes.data_as(D),
                          s.ctypes.data_as(D))
        return s

    def encode_input(u):
        nu = np.zeros(l)
        lib.symrom_encode_input(np.ascontiguousarray(u).ctypes.data_as(D), nu.ctypes.data_as(D))
        return nu

    def step(phase, s, nu, h):
        s = s.copy()
        assert lib.symrom_rk4_step(ctypes.c_int(phase), s.ctypes.data_as(D), nu.ctypes.data_as(D),
                                   ctypes.c_double(h)) == 0
        return s

    path = _roll(encode, encode_input, step, model, ds, j)
    xi, dxi = _reference(model, ds, j)
    np.testing.assert_allclose(path[:, :l], xi, atol=1e-9)
    np.testing.assert_allclose(path[:, l:], dxi, atol=1e-9)
    q = np.zeros(18)
    lib.symrom_decode(path[5].ctypes.data_as(D), q.ctypes.data_as(D))
    np.testing.assert_allclose(q, model.autoencoder.decode(path[5, :l][None])[0], atol=1e-12)
    assert lib.symrom_accel(ctypes.c_int(7), path[0].ctypes.data_as(D), np.zeros(l).ctypes.data_as(D),
                            np.zeros(l).ctypes.data_as(D)) == -1  # an unknown phase is refused


def test_casadi_export_matches_and_has_jacobians(model_and_jump, tmp_path):
    ca = pytest.importorskip("casadi")
    model, ds, j = model_and_jump
    export(model, "casadi", tmp_path)
    f = {p.stem.removeprefix("symrom_model_"): ca.Function.load(str(p)) for p in tmp_path.glob("*.casadi")}
    l = model.latent_dim

    def encode(q, dq):
        return np.array(f["encode"](q, dq)).ravel()

    def step(phase, s, nu, h):
        return np.array(f[f"rk4_step_{model.phase_names[phase]}"](s, nu, h)).ravel()

    path = _roll(encode, lambda u: np.array(f["encode_input"](u)).ravel(), step, model, ds, j)
    xi, dxi = _reference(model, ds, j)
    np.testing.assert_allclose(path[:, :l], xi, atol=1e-9)
    np.testing.assert_allclose(path[:, l:], dxi, atol=1e-9)
    # The Jacobian of the contact dynamics is the model's linearisation.
    x0, v0, n0 = np.array([0.1, -0.2]), np.array([0.3, 0.05]), np.array([0.5, -1.0])
    d_state, d_nu = f["jac_contact"](np.r_[x0, v0], n0)
    A = model.linearisation(model.phase_names.index("contact"), x0, v0, n0)
    np.testing.assert_allclose(np.array(d_state), A[l:], atol=1e-9)
    dd = np.array(f["dynamics"](np.r_[x0, v0], n0, 1)).ravel()
    np.testing.assert_allclose(dd, model.latent_acceleration(x0[None], v0[None], n0[None], np.array([1]))[0],
                               atol=1e-12)
    assert np.array(d_nu).shape == (l, l)
    # one shape everywhere: the state s = [xi, dxi], the inputs nu
    s0 = np.r_[x0, v0]
    np.testing.assert_array_equal(np.array(f["accel_flight"](s0, n0)).ravel(), dd)
    np.testing.assert_allclose(np.array(f["rk4_step"](s0, n0, 1, 0.001)).ravel(),
                               np.array(f["rk4_step_flight"](s0, n0, 0.001)).ravel(), atol=1e-15)
    np.testing.assert_allclose(np.array(f["decode"](s0)).ravel(), model.autoencoder.decode(x0[None])[0],
                               atol=1e-12)


def test_python_export_matches(model_and_jump, tmp_path):
    model, ds, j = model_and_jump
    (path,) = export(model, "python", tmp_path)
    spec = importlib.util.spec_from_file_location("exported", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.PHASES == model.phase_names and model_hash(model) in path.read_text()
    out = _roll(mod.encode, mod.encode_input, mod.rk4_step, model, ds, j)
    xi, _ = _reference(model, ds, j)
    np.testing.assert_allclose(out[:, :model.latent_dim], xi, atol=1e-9)


def test_cli_export(model_and_jump, tmp_path):
    model, *_ = model_and_jump
    save_model(model, tmp_path / "m.json")
    r = CliRunner().invoke(app, ["export", str(tmp_path / "m.json"), "--to", "python", "--out", str(tmp_path / "x")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "x" / "symrom_model.py").is_file()
    one_line_error(CliRunner().invoke(app, ["export", str(tmp_path / "m.json"), "--to", "fortran",
                                            "--out", str(tmp_path / "y")]), "--to", "fortran")
    one_line_error(CliRunner().invoke(app, ["export", str(tmp_path / "m.json"), "--to", "c",
                                            "--out", str(tmp_path / "x")]), "--force")
