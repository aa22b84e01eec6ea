import time

import numpy as np
import pytest

from symrom.evaluate.metrics import evaluate_model
from symrom.evaluate.tables import table2
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout


@pytest.fixture(scope="module")
def model_and_data(planted_block):
    ds, _ = planted_block
    return train(ds, TrainConfig()), ds


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_exploding_model_is_flagged_not_hung(model_and_data, method):
    from dataclasses import replace

    model, ds = model_and_data
    bad = replace(model, Xi=model.Xi.copy())  # a copy of the module's fit, to be made unstable
    names = bad.library.feature_names
    bad.Xi[:, names.index("xi1"), 0] = 400.0  # strong positive feedback: exponential blow-up
    t0 = time.perf_counter()
    metrics, ros = evaluate_model(bad, ds, "test", options=RolloutOptions(method=method))
    assert time.perf_counter() - t0 < 60
    full = metrics.full
    assert full.diverged_jumps == len(ds.jumps_in("test"))
    assert all(d >= 0 for d in ros["full"].diverged_at)
    # Only the samples before each divergence are scored.
    assert full.scored_samples == int(ros["full"].diverged_at.sum()) < full.samples
    assert (full.components == {}) == (full.scored_samples == 0)
    assert "diverged" in table2(metrics)


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_reset_restarts_from_the_encoded_truth(model_and_data, method):
    model, ds = model_and_data
    j = int(ds.jumps_in("test")[0])
    ro = rollout(model, ds, [j], RolloutOptions(method=method, reset=0.1))
    a, b = ds.jump_bounds()[j]
    xi_true = model.autoencoder.encode(ds.q[a:b])
    every = int(round(0.1 / ds.dt))
    np.testing.assert_allclose(ro.xi[0][::every], xi_true[::every], atol=1e-12)
    assert not np.allclose(ro.xi[0][1:every], xi_true[1:every], atol=1e-12)


def test_shorter_horizon_is_more_accurate(model_and_data):
    model, ds = model_and_data
    model = train(ds, TrainConfig(latent_dim=1))  # an imperfect model drifts over the full horizon
    metrics, _ = evaluate_model(model, ds, "test", resets=(None, 0.1), options=RolloutOptions(method="rk4"))
    full = np.mean([c.rmse for c in metrics.full.components.values()])
    short = np.mean([c.rmse for c in metrics.horizons["0.1"].components.values()])
    assert short < full


@pytest.mark.parametrize("backend", ["table", "generated"])
@pytest.mark.parametrize("reset", [None, 0.1])
def test_compiled_rk4_matches_the_numpy_reference(model_and_data, reset, backend):
    from dataclasses import replace

    model, ds = model_and_data
    names = model.library.feature_names
    Xi = model.Xi.copy()
    Xi[0, names.index("dxi1"), 0] = 60.0  # a fast unstable mode, so some rollouts diverge
    bad = replace(model, Xi=Xi, mask=model.mask | (Xi != 0))
    for m in (model, bad):
        a = rollout(m, ds, None, RolloutOptions("rk4", reset=reset, backend=backend))
        b = rollout(m, ds, None, RolloutOptions("rk4", reset=reset, backend="numpy"))
        np.testing.assert_array_equal(a.diverged_at, b.diverged_at)
        for x, y in zip(a.q_pred, b.q_pred):
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)
    assert rollout(bad, ds, None, RolloutOptions("rk4", backend=backend)).diverged.any()


def test_lsoda_with_the_generated_right_hand_side_matches(model_and_data):
    model, ds = model_and_data
    jumps = ds.jumps_in("test")
    a = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="generated"))
    b = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="numpy"))
    for x, y in zip(a.xi + a.dxi, b.xi + b.dxi):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)


def _late_divergence(model_and_data):
    """A model whose rollouts of some training jumps diverge late (after 80 % of the jump)."""
    from dataclasses import replace

    model, ds = model_and_data
    Xi = model.Xi.copy()
    Xi[0, model.library.feature_names.index("dxi1"), 0] = 10.0  # a slow unstable mode
    return replace(model, Xi=Xi, mask=model.mask | (Xi != 0))


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_a_diverged_jump_is_scored_up_to_its_divergence(model_and_data, method):
    from symrom.names import Q_NAMES

    _, ds = model_and_data
    bad = _late_divergence(model_and_data)
    ds = ds.select_jumps([3, 4, 5, 6])  # training jumps, two of them diverge late: LSODA is slow per jump
    metrics, ros = evaluate_model(bad, ds, "train", resets=(None,), options=RolloutOptions(method))
    metrics = metrics.to_dict()  # the layout of metrics.json
    full, ro = metrics["horizons"]["full"], ros["full"]
    lengths = np.diff(ds.jump_bounds(), axis=1)[ro.jumps, 0]
    assert 0 < ro.diverged.sum() < ro.jumps.size
    assert np.all(ro.diverged_at[ro.diverged] > 0.8 * lengths[ro.diverged])  # the late ones of the issue
    assert metrics["format_version"] == 3 and full["diverged_jumps"] == int(ro.diverged.sum())
    assert full["diverged"] == [{"jump": int(j), "t": round(int(k) * ds.dt, 6)}
                                for j, k in zip(ro.jumps[ro.diverged], ro.diverged_at[ro.diverged])]
    # Expected: every sample of the jumps that stayed bounded, and those of each diverged jump
    # before it left its bound (finite predictions), none after.
    bounds, err = ds.jump_bounds(), []
    for i, j in enumerate(ro.jumps):
        n = int(ro.diverged_at[i]) if ro.diverged[i] else int(lengths[i])
        assert np.isfinite(ro.q_pred[i][:n]).all()
        err.append(ro.q_pred[i][:n] - ds.q[bounds[j, 0]:bounds[j, 0] + n])
    err = np.concatenate(err)
    assert full["samples"] == int(lengths.sum()) and full["scored_samples"] == err.shape[0]
    assert full["scored_samples"] > full["samples"] - (lengths[ro.diverged].sum() * 0.2)
    np.testing.assert_allclose([full["components"][c]["rmse"] for c in Q_NAMES],
                               np.sqrt(np.mean(err ** 2, axis=0)), rtol=1e-12)
    np.testing.assert_allclose([full["components"][c]["mean"] for c in Q_NAMES], err.mean(axis=0),
                               rtol=1e-9, atol=1e-15)
    text = table2(metrics)
    j, k = int(ro.jumps[ro.diverged][0]), int(ro.diverged_at[ro.diverged][0])
    assert f"jump {j} at {k * ds.dt:.3f} s" in text and "scored up to the divergence" in text


def test_divergence_is_reported_in_seconds_by_the_command_line(model_and_data, tmp_path):
    import json

    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.data.io import write_dataset
    from symrom.evaluate.records import Metrics
    from symrom.model.persistence import save_model

    _, ds = model_and_data
    bad = _late_divergence(model_and_data)
    data, path, out = tmp_path / "d.h5", tmp_path / "bad.json", tmp_path / "ev"
    write_dataset(ds, data)
    save_model(bad, path)
    r = CliRunner().invoke(app, ["evaluate", str(path), str(data), "--split", "train", "--integrator", "rk4",
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    full = m["horizons"]["full"]
    first = full["diverged"][0]
    said = " ".join(r.output.split())
    assert f"jump {first['jump']} at {first['t']:.3f} s" in said and "scored up to its divergence" in said
    assert f"jump {first['jump']} at {first['t']:.3f} s" in (out / "table.md").read_text()
    rec = Metrics.read(out / "metrics.json")
    assert rec.format_version == 3 and rec.horizons["full"].scored_samples == full["scored_samples"]
    assert rec.to_dict() == m


@pytest.mark.parametrize("latent_dim, poly_order", [(1, 1), (3, 1), (1, 2)])
def test_compiled_rk4_matches_numpy_for_other_sizes_and_libraries(planted_block, latent_dim, poly_order):
    """Term programs with powers and products (p = 2 on l = 1, whose fit keeps xi1^2, xi1 dxi1 and
    dxi1^2; on l = 2 it recovers the planted system, which has none) and the generated code for
    l = 1, 3."""
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=latent_dim, poly_order=poly_order))
    if poly_order == 2:
        assert any("**2" in str(e) for eqs in model.equations(3).values() for e in eqs)
    jumps = ds.jumps_in("test")
    ref = rollout(model, ds, jumps, RolloutOptions("rk4", reset=0.1, backend="numpy"))
    for backend in ("table", "generated"):
        ro = rollout(model, ds, jumps, RolloutOptions("rk4", reset=0.1, backend=backend))
        np.testing.assert_array_equal(ro.diverged_at, ref.diverged_at)
        for x, y in zip(ro.xi, ref.xi):
            np.testing.assert_allclose(x, y, rtol=1e-10, atol=1e-10)


@pytest.fixture(scope="module")
def c_library(model_and_data, tmp_path_factory):
    """The module's model exported as C and compiled with cc, once for every jump and reset."""
    import ctypes
    import shutil
    import subprocess

    from symrom.export import export

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler")
    tmp = tmp_path_factory.mktemp("c_export")
    files = export(model_and_data[0], "c", tmp)
    subprocess.run([cc, "-std=c99", "-O2", "-shared", "-fPIC", "-o", str(tmp / "m.so"), str(files[1]), "-lm"],
                   check=True, capture_output=True)
    return ctypes.CDLL(str(tmp / "m.so"))


def _c_rollout(lib, model, ds, j, reset, substeps=2):
    """The latent path (n, 2l) of jump j by the exported C's RK4 step (``lib``: ``c_library``)."""
    import ctypes

    from symrom.rollout.integrate import reset_mask

    D = ctypes.POINTER(ctypes.c_double)
    sysm = model.rollout_system(ds, np.array([j]))
    x, v, nu, ph = sysm.x[0], sysm.v[0], sysm.drive["nu"][0], sysm.drive["phase"][0]
    resets = reset_mask(len(x), reset, ds.dt)
    out = np.empty((len(x), 2 * model.latent_dim))
    for k in range(len(x)):
        if resets[k]:
            s = np.r_[x[k], v[k]]
        out[k] = s
        u = np.ascontiguousarray(nu[k])
        for _ in range(substeps):
            lib.symrom_rk4_step(ctypes.c_int(int(ph[k])), s.ctypes.data_as(D), u.ctypes.data_as(D),
                                ctypes.c_double(ds.dt / substeps))
    return out


@pytest.mark.parametrize("reset", [None, 0.1])
def test_compiled_and_exported_rollouts_agree_with_lsoda(model_and_data, c_library, reset):
    """The fixed-step paths against LSODA at tight tolerances (at odeint's default tolerance
    it is LSODA's own error, ~1e-6 over a jump, that shows)."""
    model, ds = model_and_data
    jumps = ds.jumps_in("test")
    ref = rollout(model, ds, jumps, RolloutOptions("lsoda", reset=reset, rtol=1e-10, atol=1e-10))
    for backend in ("table", "generated"):
        ro = rollout(model, ds, jumps, RolloutOptions("rk4", reset=reset, backend=backend))
        for x, y, vx, vy in zip(ro.xi, ref.xi, ro.dxi, ref.dxi):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-6)
            np.testing.assert_allclose(vx, vy, rtol=0, atol=1e-6)
    for i, j in enumerate(jumps):
        path = _c_rollout(c_library, model, ds, int(j), reset)
        np.testing.assert_allclose(path[:, :model.latent_dim], ref.xi[i], rtol=0, atol=1e-6)
        np.testing.assert_allclose(path[:, model.latent_dim:], ref.dxi[i], rtol=0, atol=1e-6)


def test_the_stage_shift_of_sines_and_cosines_is_exact_to_rounding():
    """The generated RK4 takes a later stage's sin and cos from the step's start by the angle
    sum formulas: equal to math.sin/cos to rounding on both sides of its polynomial's range."""
    import math

    import numba

    from symrom.compiled.codegen import SHIFT_MAX, SHIFT_SOURCE

    ns = {"math": math}
    exec(SHIFT_SOURCE, ns)  # noqa: S102 - the module's own source
    shift = numba.njit(ns["shift"])
    rng = np.random.default_rng(0)
    s = rng.uniform(-4, 4, 4000)
    d = np.r_[rng.uniform(-SHIFT_MAX, SHIFT_MAX, 3000), rng.uniform(-2, 2, 1000)]
    got = np.array([shift(si + di, si, math.sin(si), math.cos(si)) for si, di in zip(s, d)])
    want = np.c_[np.sin(s + d), np.cos(s + d)]
    np.testing.assert_allclose(got, want, rtol=0, atol=4e-16)
    assert np.abs(d).max() > SHIFT_MAX and np.abs(d[:3000]).max() > 0.9 * SHIFT_MAX


@pytest.mark.parametrize("reset", [None, 0.1])
def test_compiled_lsoda_matches_scipys(model_and_data, reset):
    """numbalsoda's LSODA run from compiled code with the generated right-hand side: the
    paths of SciPy's odeint with the NumPy right-hand side, to rounding (the generated one
    sums the terms in the same order), at odeint's default tolerances and at 1e-10; the
    same divergence sample for a model that blows up."""
    pytest.importorskip("numbalsoda")
    from dataclasses import replace

    model, ds = model_and_data
    jumps = ds.jumps_in("test")
    for tol in (1.49012e-8, 1e-10):
        o = {"reset": reset, "rtol": tol, "atol": tol}
        a = rollout(model, ds, jumps, RolloutOptions("lsoda", lsoda_solver="numbalsoda", **o))
        b = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="generated", **o))
        c = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="numpy", **o))
        for x, y, z in zip(a.xi + a.dxi, b.xi + b.dxi, c.xi + c.dxi):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)
            np.testing.assert_allclose(x, z, rtol=0, atol=1e-12)
    Xi = model.Xi.copy()
    Xi[0, model.library.feature_names.index("dxi1"), 0] = 60.0
    bad = replace(model, Xi=Xi, mask=model.mask | (Xi != 0))
    a = rollout(bad, ds, jumps, RolloutOptions("lsoda", reset=reset, lsoda_solver="numbalsoda"))
    b = rollout(bad, ds, jumps, RolloutOptions("lsoda", reset=reset))
    assert a.diverged.any()
    np.testing.assert_array_equal(a.diverged_at, b.diverged_at)


def test_compiled_lsoda_needs_generated_code():
    with pytest.raises(ValueError, match="numbalsoda.*generated code.*'table'"):
        RolloutOptions("lsoda", backend="table", lsoda_solver="numbalsoda")


def test_compiled_lsoda_without_numbalsoda_says_how_to_install_it(monkeypatch):
    from symrom.rollout import compiled_lsoda

    monkeypatch.setattr(compiled_lsoda, "available", lambda: False)
    with pytest.raises(ValueError, match=r"needs numbalsoda: pip install 'symrom\[lsoda\]'"):
        RolloutOptions("lsoda", lsoda_solver="numbalsoda")
    RolloutOptions("lsoda")  # SciPy's LSODA needs nothing more


@pytest.mark.parametrize("backend", ["table", "generated"])
def test_jumps_split_over_threads_give_the_same_paths_bit_for_bit(model_and_data, monkeypatch, backend):
    """The kernels' jumps run in threads (``symrom.compiled.batch``): any thread count gives the
    same rollout, divergences included, to the last bit."""
    from dataclasses import replace

    from symrom.compiled import batch
    from symrom.execution import limit_threads

    model, ds = model_and_data
    Xi = model.Xi.copy()
    Xi[0, model.library.feature_names.index("dxi1"), 0] = 60.0  # the jumps diverge, each at its own sample
    bad = replace(model, Xi=Xi, mask=model.mask | (Xi != 0))
    monkeypatch.setattr(batch, "MIN_SPLIT_WORK", 0)  # split even this small batch
    calls = []
    split = batch.split
    monkeypatch.setattr(batch, "split", lambda lens, parts: calls.append(parts) or split(lens, parts))
    for m in (model, bad):
        out = {}
        for threads in (1, 3):
            limit = limit_threads(threads)
            try:
                out[threads] = rollout(m, ds, None, RolloutOptions("rk4", reset=0.1, backend=backend))
            finally:
                limit.restore_original_limits()
        np.testing.assert_array_equal(out[1].diverged_at, out[3].diverged_at)
        for x, y in zip(out[1].q_pred, out[3].q_pred):
            np.testing.assert_array_equal(x, y)
    assert out[1].diverged.all() and len(set(out[1].diverged_at.tolist())) > 1  # each jump its own sample
    assert calls and set(calls) == {3}  # only the 3-thread runs split, and they did


def test_a_batch_splits_into_runs_of_about_equal_work():
    from symrom.compiled.batch import over_jumps, split
    from symrom.execution import limit_threads

    lens = np.array([5, 100, 3, 40, 40, 12, 1, 99])
    for parts in (1, 2, 3, 8, 20):
        runs = split(lens, parts)
        assert runs[0].start == 0 and runs[-1].stop == len(lens)
        assert all(a.stop == b.start and a.stop > a.start for a, b in zip(runs, runs[1:]))
        assert len(runs) <= min(parts, len(lens))
    work = [lens[r].sum() for r in split(lens, 2)]
    assert max(work) <= lens.sum() / 2 + lens.max()

    def fail(r):
        if r.start > 0:
            raise ValueError("jump run failed")

    limit = limit_threads(2)  # split even where the process keeps to one thread (pytest-xdist)
    try:
        with pytest.raises(ValueError, match="jump run failed"):
            over_jumps(fail, np.full(8, 10_000))
    finally:
        limit.restore_original_limits()
