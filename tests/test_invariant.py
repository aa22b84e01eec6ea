"""Dynamics held invariant to where the robot stands: the latent basis gives base x a latent of
its own, and no term or guard reads that latent's position, so a jump started 30 cm further on
is predicted the same, 30 cm further on (in the latent space; the decoder reads it back)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from _simdata import reference_file

from symrom.data.io import read_dataset
from symrom.experiments.select import SelectionConfig
from symrom.learn.encoders import reading_latents, translation_basis
from symrom.learn.training import TrainConfig, train
from symrom.model.autoencoder import LinearAutoencoder
from symrom.names import Q_NAMES

X = Q_NAMES.index("x")
SHIFT = 0.3  # m forward


def test_the_basis_gives_x_one_latent_and_keeps_the_reconstruction():
    rng = np.random.default_rng(0)
    W_e = rng.normal(size=(4, 18))
    ae = LinearAutoencoder(W_e, rng.normal(size=4), rng.normal(size=(18, 4)), rng.normal(size=18))
    out = translation_basis(ae, ("x", "y"))
    cols = out.W_e[:, [X, Q_NAMES.index("y")]]
    assert (cols != 0).sum(axis=0).tolist() == [1, 1]  # each moves exactly one latent
    assert np.flatnonzero(cols[:, 0]) != np.flatnonzero(cols[:, 1])
    q = rng.normal(size=(50, 18))
    np.testing.assert_allclose(out.reconstruct(q), ae.reconstruct(q), atol=1e-9)
    # the same latent space: each new row is a combination of the old ones
    coef, *_ = np.linalg.lstsq(ae.W_e.T, out.W_e.T, rcond=None)
    np.testing.assert_allclose(ae.W_e.T @ coef, out.W_e.T, atol=1e-10)
    assert reading_latents(out, ("x",)).sum() == 1


def test_a_component_no_latent_holds_is_dropped_not_given_a_latent():
    rng = np.random.default_rng(1)
    Y = Q_NAMES.index("y")
    W_e = rng.normal(size=(3, 18))
    W_e[:, Y] = 1e-3  # the data hardly move sideways: no latent is mostly y
    q = rng.normal(size=(200, 18))
    ae = LinearAutoencoder(W_e, np.zeros(3), np.zeros((18, 3)), np.zeros(18))
    with pytest.raises(ValueError, match="no latent holds y"):
        translation_basis(ae, ("x", "y"))
    out = translation_basis(ae, ("x", "y"), q)
    assert reading_latents(out, ("y",)).sum() == 0 and reading_latents(out, ("x",)).sum() == 1
    # the decoder is step (b)'s least squares for the new encoder
    xi = out.encode(q)
    X = np.c_[xi, np.ones(len(q))]
    np.testing.assert_allclose(X.T @ (q - out.decode(xi)), 0.0, atol=1e-8)


def _shifted(ds, dx: float):
    q = ds.q.copy()
    q[:, X] += dx
    return replace(ds, q=q)


@pytest.fixture(scope="module")
def froggy():
    return read_dataset(reference_file("froggy"))


@pytest.mark.parametrize("invariant", [(), ("x",)])
def test_a_model_held_invariant_predicts_a_shifted_jump_the_same(froggy, invariant):
    cfg = TrainConfig(latent_dim=2, encoder_components=("x", "y", "z"), poly_order=1, trig=True, threshold=1e-3,
                      measure="explained", collinearity=0.995, alpha=1e-6, decoded_weight=0.0, invariant=invariant)
    model = train(froggy, cfg)
    ae, moved = model.autoencoder, _shifted(froggy, SHIFT)
    acc = lambda d: model.latent_acceleration(ae.encode(d.q), ae.encode_derivative(d.dq),  # noqa: E731
                                              ae.encode_input(d.u), model.phase_index(d))
    change = np.abs(acc(moved) - acc(froggy)).max()
    if not invariant:  # the paper's model reads x on these jumps: the check below can fail
        assert change > 1e-3
        return
    assert change < 1e-9
    assert model.estimator["invariant"] == ["x"]
    k = int(np.flatnonzero(reading_latents(ae, ("x",)))[0])
    assert not any(f"xi{k + 1}" in g.terms for g in model.guards)
    reasons = {d["reason"] for r in (p.report for p in model.phase_info.values()) for d in r.get("dropped", [])}
    assert any("where the robot stands" in r for r in reasons)
    # a free prediction from a start 30 cm further on takes the same path, 30 cm further on
    a, b = froggy.jump_bounds()[0]
    paths = [model.predict_path(d.q[a], d.dq[a], d.u[a:b], froggy.dt) for d in (froggy, moved)]
    assert [s["k"] for s in paths[0].switches] == [s["k"] for s in paths[1].switches]
    assert [s["target"] for s in paths[0].switches] == ["partial", "flight", "contact"]
    np.testing.assert_allclose(paths[1].xi - paths[0].xi, np.broadcast_to(SHIFT * ae.W_e[:, X], paths[0].xi.shape),
                               atol=1e-9)
    np.testing.assert_allclose(paths[1].dxi, paths[0].dxi, atol=1e-9)


def test_invariant_names_a_horizontal_translation_and_leaves_a_latent():
    with pytest.raises(ValueError, match="z is no horizontal translation"):
        TrainConfig(latent_dim=3, invariant=("z",))
    with pytest.raises(ValueError, match="leaves no latent position"):
        TrainConfig(latent_dim=1, invariant=("x",))
    with pytest.raises(ValueError, match="must exceed"):
        SelectionConfig(latent_dims=(1, 2))
    assert SelectionConfig().train_config("all", 3, "poly1+inputs", 0.01).invariant == ("x",)


def test_train_holds_the_named_components_invariant_and_refuses_others(tmp_path):
    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.model.persistence import load_model

    data = reference_file("froggy")
    r = CliRunner().invoke(app, ["train", str(data), "--out", str(tmp_path / "z"), "--invariant", "z"])
    assert r.exit_code != 0 and "z is no horizontal translation" in r.output
    assert not (tmp_path / "z").exists()
    r = CliRunner().invoke(app, ["train", str(data), "--out", str(tmp_path / "m"), "--latent-dim", "2",
                                 "--encoder-components", "x,y,z", "--invariant", "x"])
    assert r.exit_code == 0, r.output
    model = load_model(tmp_path / "m" / "model.json")
    from symrom.learn.estimator import SymbolicROM

    assert SymbolicROM.load(tmp_path / "m" / "model.json").invariant == ("x",)  # refits hold it too
    moving = reading_latents(model.autoencoder, ("x",))
    assert moving.sum() == 1 and not (model.mask & model.library.terms_reading(moving)[None, :, None]).any()


def test_reproduce_keeps_the_papers_formulation_unless_asked():
    from symrom.experiments.reproduce.config import reproduce_config

    for quick in (False, True):
        cfg = reproduce_config(quick)
        assert all(cfg.selection_for(e).invariant == () for e in cfg.experiments)
        held = reproduce_config(quick, invariant=("x",))
        assert all(held.selection_for(e).invariant == ("x",) for e in held.experiments)
