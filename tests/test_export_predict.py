"""The exports given torques: their input map and free prediction reproduce symrom's to 1e-9."""

import ctypes
import importlib.util
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from symrom.data.preprocess import input_from_torques
from symrom.export import export
from symrom.learn.training import TrainConfig, train
from symrom.model.guards import Guard


@pytest.fixture(scope="module", params=["state", "clock"])
def case(planted_block, request):
    """A planted model read as a Go1 model (the input map needs a robot), one test jump with
    torques, and symrom's paths from them: guards deciding, and the logged schedule. ``clock``:
    its lift-off guard replaced by a clock (``Guard.clock``) at the jump's logged lift-off."""
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=2, poly_order=2))
    model = replace(model, provenance=replace(model.provenance, data=replace(model.provenance.data, robot="go1")))
    j = int(ds.jumps_in("test")[0])
    a, b = ds.jump_bounds()[j]
    if request.param == "clock":
        lift = int(np.flatnonzero(np.diff(model.phase_index(ds)[a:b]))[0]) + 1
        model = replace(model, guards=[Guard("contact", "flight", [], [], 0.0, lift * ds.dt) if g.target == "flight"
                                       else g for g in model.guards])
        assert sum(g.clock for g in model.guards) == 1
    rng = np.random.default_rng(0)
    q = ds.q[a:b].copy()
    q[:, :12] = np.tile([0.0, 0.8, -1.6] * 4, (b - a, 1)) + 0.1 * np.sin(q[:, :12])  # a standing leg shape
    tau = 0.05 * rng.standard_normal((b - a, 12))
    contact = ds.contact[a:b]
    u = input_from_torques("go1", q, tau, contact)
    sched = model.phase_index(ds)[a:b]
    paths = {"guards": model.predict_path(ds.q[a], ds.dq[a], u, ds.dt),
             "schedule": model.predict_path(ds.q[a], ds.dq[a], u, ds.dt, phases=sched)}
    assert paths["guards"].switches and not paths["guards"].diverged
    if request.param == "clock":
        assert paths["guards"].switches[0]["k"] == lift
    return model, ds, (a, b), q, tau, contact, u, sched, paths


@pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None, reason="no C compiler")
def test_c_export_given_torques_reproduces_predict_path(case, tmp_path):
    model, ds, (a, b), q, tau, contact, u, sched, paths = case
    files = export(model, "c", tmp_path)
    header = files[0].read_text()
    assert "#define SYMROM_HAS_INPUT_MAP 1" in header and "#define SYMROM_N_GUARDS 2" in header
    so = tmp_path / "model.so"
    cc = shutil.which("gcc") or shutil.which("cc")
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Werror", "-shared", "-fPIC", "-o", str(so),
                    str(files[1]), "-lm"], check=True, capture_output=True)
    lib = ctypes.CDLL(str(so))
    D, I = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
    n = b - a
    uc = np.zeros((n, 18))
    flags = np.ascontiguousarray(contact, dtype=np.int32)
    for k in range(n):
        row = np.zeros(18)
        assert lib.symrom_input(np.ascontiguousarray(q[k]).ctypes.data_as(D),
                                np.ascontiguousarray(tau[k]).ctypes.data_as(D), flags[k].ctypes.data_as(I),
                                None, row.ctypes.data_as(D)) == 0
        uc[k] = row
    np.testing.assert_allclose(uc, u, atol=1e-9, rtol=0)
    feet = np.ascontiguousarray(ds.q[a:a + 1, 12:15].repeat(4, 0) + [0.2, 0.1, -0.3])  # given feet
    row = np.zeros(18)
    lib.symrom_input(np.ascontiguousarray(q[0]).ctypes.data_as(D), np.ascontiguousarray(tau[0]).ctypes.data_as(D),
                     np.ones(4, np.int32).ctypes.data_as(I), feet.ctypes.data_as(D), row.ctypes.data_as(D))
    np.testing.assert_allclose(row, input_from_torques("go1", q[:1], tau[:1], np.ones((1, 4)), feet[None])[0],
                               atol=1e-9, rtol=0)
    for mode, p in paths.items():
        qo, dqo = np.zeros((n, 18)), np.zeros((n, 18))
        ph = np.ascontiguousarray(sched if mode == "schedule" else np.zeros(n), dtype=np.int32)
        ret = lib.symrom_predict_path(ctypes.c_int(n), ctypes.c_double(ds.dt), ctypes.c_int(2),
                                      np.ascontiguousarray(ds.q[a]).ctypes.data_as(D),
                                      np.ascontiguousarray(ds.dq[a]).ctypes.data_as(D), uc.ctypes.data_as(D),
                                      ctypes.c_int(mode == "guards"), ctypes.c_int(0), ph.ctypes.data_as(I),
                                      qo.ctypes.data_as(D), dqo.ctypes.data_as(D))
        assert ret == -1
        np.testing.assert_array_equal(ph, p.phase)
        np.testing.assert_allclose(qo, p.q, atol=1e-9, rtol=0)
        np.testing.assert_allclose(dqo, p.dq, atol=1e-9, rtol=0)


def test_casadi_export_given_torques_reproduces_predict_path(case, tmp_path):
    ca = pytest.importorskip("casadi")
    model, ds, (a, b), q, tau, contact, u, sched, paths = case
    export(model, "casadi", tmp_path)
    f = {p.stem.removeprefix("symrom_model_"): ca.Function.load(str(p)) for p in tmp_path.glob("*.casadi")}
    n = b - a
    uc = np.array([np.array(f["input_kinematics"](q[k], tau[k], contact[k])).ravel() for k in range(n)])
    np.testing.assert_allclose(uc, u, atol=1e-9, rtol=0)
    seq = model.phase_sequence()
    assert seq == (0, 1, 0)  # the planted jumps are pronks: contact, flight, contact
    for mode, p in paths.items():
        s, phase, k_enter, out, ph = np.array(f["encode"](ds.q[a], ds.dq[a])).ravel(), 0, 0, [], []
        stage = 0
        for k in range(n):
            out.append(np.array(f["decode"](s)).ravel())
            nu = np.array(f["encode_input"](uc[k])).ravel()
            if mode == "guards":
                nxt, stage = (int(v) for v in f["guard_switch_staged"](s, nu, phase, k - k_enter, ds.dt, stage))
                if nxt != phase:
                    phase, k_enter = nxt, k
            else:
                phase = int(sched[k])
            ph.append(phase)
            for _ in range(2):
                s = np.array(f["rk4_step"](s, nu, phase, ds.dt / 2)).ravel()
        np.testing.assert_array_equal(ph, p.phase)
        np.testing.assert_allclose(np.array(out), p.q, atol=1e-9, rtol=0)


def test_python_export_given_torques_reproduces_predict_path(case, tmp_path):
    model, ds, (a, b), q, tau, contact, u, sched, paths = case
    (path,) = export(model, "python", tmp_path)
    spec = importlib.util.spec_from_file_location("exported_io", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    uc = np.array([mod.input_from_torques(q[k], tau[k], contact[k]) for k in range(b - a)])
    np.testing.assert_allclose(uc, u, atol=1e-9, rtol=0)
    for mode, p in paths.items():
        qo, dqo, ph = mod.predict_path(ds.q[a], ds.dq[a], uc, ds.dt, phases=None if mode == "guards" else sched)
        np.testing.assert_array_equal(ph, p.phase)
        np.testing.assert_allclose(qo, p.q, atol=1e-9, rtol=0)
        np.testing.assert_allclose(dqo, p.dq, atol=1e-9, rtol=0)


def test_a_model_without_a_robot_is_exported_without_the_input_map(planted_block, tmp_path):
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=2))
    files = export(model, "c", tmp_path)
    assert "#define SYMROM_HAS_INPUT_MAP 0" in files[0].read_text()
    assert "symrom_input(" not in files[1].read_text()
