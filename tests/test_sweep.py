"""Latent-dimension sweep on a planted 2-D system."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.experiments.sweep import SweepConfig, bootstrap_jumps, l_mod, parse_latent_dims, run_sweep, summarise
from symrom.names import TABLE2_COMPONENTS
from symrom.testing import make_planted_dataset

DIMS = (1, 2, 3, 4)
SEEDS = (0, 1, 2)
runner = CliRunner()


@pytest.fixture(scope="module")
def planted():
    ds, _ = make_planted_dataset(n_jumps=12, n_samples=200, embedding="block", seed=2)
    return ds


@pytest.fixture(scope="module")
def swept(planted, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "run"
    config = SweepConfig(latent_dims=DIMS, seeds=SEEDS)
    return run_sweep(planted, config, out), out, config


def test_layout(swept):
    result, out, _ = swept
    assert json.loads((out / "sweep.json").read_text()) == result
    assert result["latent_dims"] == list(DIMS) and result["seeds"] == list(SEEDS)
    for key in ("E_dec", "active_terms", "rmse_test"):
        assert np.shape(result[key]) == (len(DIMS), len(SEEDS)), key
    assert len(result["L_mod"]) == len(DIMS)
    assert result["lambda"] == 0.001 and result["solver"] == "exact" and result["poly_order"] == 1
    assert sorted(p.name for p in (out / "cells").iterdir()) == sorted(
        f"l{d:02d}_s{s}.json" for d in DIMS for s in SEEDS)


def test_reconstruction_error_falls_with_dimension(swept):
    result, _, _ = swept
    e = np.array(result["E_dec"])
    # Nested principal subspaces on the same bootstrap sample: never worse with more latents.
    assert np.all(np.diff(e, axis=0) <= 1e-12 + 1e-9 * e[:-1])
    assert e[0].min() > 1e3 * e[1].max()  # the planted system is 2-D: one latent misses a lot
    assert np.array(result["active_terms"])[-1].mean() > np.array(result["active_terms"])[1].mean()


def test_l_mod_formula(swept):
    result, _, _ = swept
    e, a = np.array(result["E_dec"]).mean(1), np.array(result["active_terms"]).mean(1)
    np.testing.assert_allclose(result["L_mod"], 2 * e + 2 * 0.001 * np.log(a), rtol=1e-12)
    assert l_mod(0.5, 0, 0.1) == pytest.approx(1.0)  # an empty model counts as |Xi| = 1


def test_best_dimension_is_the_planted_one(swept):
    # lambda = 0: E_dec keeps shrinking past l = 2 (extra latents fit the 1e-4 noise), so the
    # largest dimension "wins" -- complexity must carry weight for the right answer. With the
    # paper's lambda = 1e-3, going 1 -> 2 drops 2 E_dec by ~3e-2, far more than the
    # complexity cost 2 lambda log(|Xi|_2 / |Xi|_1) ~ 1e-3, while 2 -> 3 saves ~1e-9 in
    # 2 E_dec but costs 2 lambda log(|Xi|_3 / |Xi|_2) ~ 3e-3: the minimum sits at l = 2.
    result, out, config = swept
    cells = {(d, s): json.loads((out / "cells" / f"l{d:02d}_s{s}.json").read_text())
             for d in DIMS for s in SEEDS}
    assert result["best_latent_dim"] == 2
    config0 = SweepConfig(latent_dims=DIMS, seeds=SEEDS, lam=0.0)
    assert summarise(cells, config0)["best_latent_dim"] == max(DIMS)


def test_bootstrap_seeds_give_error_bars(swept, planted):
    result, _, _ = swept
    assert all(s > 0 for s in result["E_dec_std"])
    assert len({tuple(bootstrap_jumps(planted, s)) for s in SEEDS}) == len(SEEDS)
    draw = bootstrap_jumps(planted, 0)
    assert set(draw) <= set(planted.jumps_in("train")) and len(draw) == len(planted.jumps_in("train"))
    np.testing.assert_array_equal(draw, bootstrap_jumps(planted, 0))
    assert not SweepConfig(solver="adam").bootstrap  # adam: seeds set the initialisation


def test_accuracy_recorded(swept):
    result, _, _ = swept
    rmse = np.array(result["rmse_test"], dtype=float)
    assert np.isfinite(rmse).all()
    assert rmse[1].mean() < 0.1 * rmse[0].mean()  # l = 2 predicts far better than l = 1


def test_a_cell_fits_no_guard_and_gives_what_a_guarded_fit_gives(planted):
    # The cell's numbers follow the logged phases, so the cell skips the guards: same numbers.
    from symrom.evaluate.metrics import evaluate_model
    from symrom.experiments.sweep import run_cell
    from symrom.learn.training import TrainConfig, reconstruction_error, train
    from symrom.rollout.integrate import RolloutOptions

    cell = run_cell(planted, SweepConfig(latent_dims=(2,), seeds=1, solver="exact"), 2, 0)
    train_ds = planted.select_jumps(bootstrap_jumps(planted, 0))
    rows = np.ones(train_ds.n_samples, dtype=bool)
    guarded = train(train_ds, TrainConfig(latent_dim=2, threshold=0.01, seed=0), rows)
    assert guarded.guards, "the planted data's phases give the guarded fit its guards"
    bare = replace(TrainConfig(latent_dim=2, threshold=0.01, seed=0).estimator(), contact_guards=False).fit(
        train_ds, rows).model
    assert bare.guards is None and np.array_equal(bare.Xi, guarded.Xi)
    assert cell["E_dec"] == reconstruction_error(guarded, train_ds, rows)
    assert cell["active_terms"] == sum(guarded.active_terms().values())
    metrics, _ = evaluate_model(guarded, planted, "test", resets=(None,), options=RolloutOptions(method="rk4"))
    assert cell["rmse_test"] == float(np.mean([metrics.full.components[c].rmse for c in TABLE2_COMPONENTS]))


def test_same_cells_with_two_workers(swept, planted, tmp_path):
    result, out, _ = swept
    config = SweepConfig(latent_dims=(2, 3), seeds=(0, 1), workers=2)
    r2 = run_sweep(planted, config, tmp_path / "w2")
    for i, d in enumerate(config.latent_dims):
        for j, s in enumerate(config.seeds):
            one = json.loads((out / "cells" / f"l{d:02d}_s{s}.json").read_text())
            two = json.loads((tmp_path / "w2" / "cells" / f"l{d:02d}_s{s}.json").read_text())
            for k in ("E_dec", "active_terms", "active_terms_per_phase", "rmse_test", "key"):
                assert one[k] == two[k], (d, s, k)
            assert r2["E_dec"][i][j] == result["E_dec"][DIMS.index(d)][SEEDS.index(s)]


def test_resume_recomputes_only_missing_cells(swept, planted, tmp_path):
    result, out, config = swept
    copy = tmp_path / "resume"
    shutil.copytree(out, copy)
    (copy / "sweep.json").unlink()
    (copy / "cells" / "l03_s1.json").unlink()
    before = {p.name: p.stat().st_mtime_ns for p in (copy / "cells").iterdir()}
    events = []
    r = run_sweep(planted, config, copy, progress=lambda done, total, info: events.append(info))
    computed = [(e["latent_dim"], e["seed"]) for e in events if not e["reused"]]
    assert computed == [(3, 1)]
    assert sum(e["reused"] for e in events) == len(DIMS) * len(SEEDS) - 1
    after = {p.name: p.stat().st_mtime_ns for p in (copy / "cells").iterdir()}
    assert all(after[n] == t for n, t in before.items())
    assert r == result

    # A setting that changes the cells invalidates them.
    events.clear()
    run_sweep(planted, SweepConfig(latent_dims=(1,), seeds=(0,), threshold=0.02), copy,
              progress=lambda done, total, info: events.append(info))
    assert [e["reused"] for e in events] == [False]


def test_parse_latent_dims():
    assert parse_latent_dims("1-18") == tuple(range(1, 19))
    assert parse_latent_dims("1,2,4") == (1, 2, 4)
    assert parse_latent_dims("2-6") == (2, 3, 4, 5, 6)
    assert parse_latent_dims("1-3,6, 2") == (1, 2, 3, 6)
    for bad in ("", "1-", "a", "5-2", "0-3", "1-19", "1,,2", "1.5"):
        with pytest.raises(ValueError, match="latent dimensions"):
            parse_latent_dims(bad)


@pytest.fixture(scope="module")
def planted_file(planted, tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "planted.h5"
    write_dataset(planted, path)
    return path


def test_cli(planted_file, tmp_path):
    out = tmp_path / "sweep"
    args = ["sweep", str(planted_file), "--latent-dims", "1-2", "--seeds", "2", "--out", str(out),
            "--no-rmse-test"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    result = json.loads((out / "sweep.json").read_text())
    assert result["latent_dims"] == [1, 2] and result["best_latent_dim"] == 2
    assert "best latent dimension: 2" in r.output
    one_line_error(runner.invoke(app, args), "--force")
    r = runner.invoke(app, [*args, "--force"])
    assert r.exit_code == 0, r.output
    assert json.loads((out / "sweep.json").read_text()) == result


@pytest.mark.parametrize("dims", ["1-", "x", "4-2", "0-3", "1-19", "1;2"])
def test_cli_bad_latent_dims(planted_file, tmp_path, dims):
    out = tmp_path / "bad"
    one_line_error(runner.invoke(app, ["sweep", str(planted_file), "--latent-dims", dims,
                                        "--out", str(out)]), "latent dimensions")
    assert not out.exists()


def test_cli_bad_solver(planted_file, tmp_path):
    one_line_error(runner.invoke(app, ["sweep", str(planted_file), "--solver", "sgd",
                                        "--out", str(tmp_path / "o")]), "solver")
