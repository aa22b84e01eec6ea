"""The compiled encoding and decoding of many jumps (model/codec.py) and the padded rollout path."""

from dataclasses import replace

import numpy as np
import pytest

from symrom.compiled import JumpViews, decode_jumps, encode_inputs, encode_states
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.rollout.system import Padded


class _Given:
    """A model whose rollout system is the one given."""

    def __init__(self, sysm, components):
        self.sysm, self.components = sysm, components

    def rollout_system(self, _ds, _jumps):
        return self.sysm


@pytest.fixture(scope="module")
def model_and_data(planted_block):
    ds, _ = planted_block
    return train(ds, TrainConfig()), ds


def test_read_only_inputs_take_the_writable_ones_build_and_give_their_numbers(model_and_data):
    # Ray's object store hands arrays over read-only: one build for both, not one more per process.
    from symrom.compiled.codec import _kernels

    model, ds = model_and_data
    ae, phase = model.autoencoder, model.phase_index(ds)
    bounds = np.array([[0, 57], [400, 700]])

    def frozen(a):
        a = a.copy()
        a.flags.writeable = False
        return a

    X = np.random.default_rng(0).normal(size=(2, 300, model.latent_dim))
    lens = np.array([57, 300])
    writable = (*encode_states(ae, ds.q, ds.dq, bounds), *encode_inputs(ae, ds.u, phase, bounds),
                *decode_jumps(ae, X, lens))
    read_only = (*encode_states(ae, frozen(ds.q), frozen(ds.dq), bounds),
                 *encode_inputs(ae, frozen(ds.u), frozen(phase), bounds), *decode_jumps(ae, frozen(X), lens))
    for a, b in zip(writable, read_only, strict=True):
        np.testing.assert_array_equal(a, b)
    assert {name: len(k.signatures) for name, k in _kernels().items()} == \
        {"encode_states": 1, "encode_inputs": 1, "decode": 1}


def test_jumps_of_unequal_length_encode_and_decode_as_the_autoencoder(model_and_data):
    model, ds = model_and_data
    ae, phase = model.autoencoder, model.phase_index(ds)
    bounds = np.array([[0, 57], [400, 401], [812, 1130], [60, 300]])  # lengths 57, 1, 318, 240
    x, v = encode_states(ae, ds.q, ds.dq, bounds)
    nu, ph = encode_inputs(ae, ds.u, phase, bounds)
    assert x.shape == v.shape == nu.shape == (4, 318, model.latent_dim) and ph.shape == (4, 318)
    for j, (a, b) in enumerate(bounds):
        n = b - a
        for got, want in ((x, ae.encode(ds.q[a:b])), (v, ae.encode_derivative(ds.dq[a:b])),
                          (nu, ae.encode_input(ds.u[a:b]))):
            np.testing.assert_allclose(got[j, :n], want, rtol=1e-12, atol=1e-13)
            np.testing.assert_array_equal(got[j, n:], np.broadcast_to(got[j, n - 1], got[j, n:].shape))
        np.testing.assert_array_equal(ph[j], np.r_[phase[a:b], np.repeat(phase[b - 1], 318 - n)])
    X = x.copy()
    X[2, 100:] = np.nan  # a diverged path decodes to NaN from there on
    lens = bounds[:, 1] - bounds[:, 0]
    q = decode_jumps(ae, X, lens)
    assert [p.shape for p in q] == [(n, 18) for n in lens]
    for j, n in enumerate(lens):
        np.testing.assert_allclose(q[j], ae.decode(X[j, :n]), rtol=1e-14, atol=1e-15)  # the same sums
    assert np.isnan(q[2][100:]).all() and np.isfinite(q[2][:100]).all()


@pytest.mark.parametrize("backend", ["table", "generated"])
def test_the_padded_path_gives_the_per_jump_paths(model_and_data, backend):
    """Stacked by the model (``RolloutSystem.padded``) or padded by the integrator from the
    per-jump lists, decoded at once or per jump: the same rollout, jumps of unequal length,
    some diverging (NaN after the divergence and past each jump's end)."""
    model, ds = model_and_data
    names = model.library.feature_names
    Xi = model.Xi.copy()
    Xi[0, names.index("dxi1"), 0] = 60.0  # a fast unstable mode
    bad = replace(model, Xi=Xi, mask=model.mask | (Xi != 0))
    cut = [50, 400, 133, 1, 399]
    opts = RolloutOptions("rk4", backend=backend)
    bounds = ds.jump_bounds()[:len(cut)]
    bounds[:, 1] = bounds[:, 0] + cut
    diverged = []
    for m in (model, bad):
        x, v = encode_states(m.autoencoder, ds.q, ds.dq, bounds)
        nu, ph = encode_inputs(m.autoencoder, ds.u, m.phase_index(ds), bounds)
        lists = [[a[j, :n] for j, n in enumerate(cut)] for a in (x, v, nu, ph)]
        scale = m.rollout_system(ds, np.arange(len(cut))).scale
        states = lambda rows: encode_states(m.autoencoder, ds.q, ds.dq, bounds, rows)  # noqa: E731
        stacked = m.latent_system(*lists, scale, Padded(states, {"nu": nu, "phase": ph}, np.array(cut)))
        listed = replace(m.latent_system(*lists, scale), observe_padded=None)  # padded by the integrator

        a = rollout(_Given(stacked, m.components), ds, np.arange(len(cut)), opts)
        b = rollout(_Given(listed, m.components), ds, np.arange(len(cut)), opts)
        assert [p.shape[0] for p in a.q_pred] == cut
        np.testing.assert_array_equal(a.diverged_at, b.diverged_at)
        for p, r in zip(a.xi + a.dxi, b.xi + b.dxi):
            np.testing.assert_array_equal(p, r)  # the same integration of the same numbers
        for p, r in zip(a.q_pred, b.q_pred):
            np.testing.assert_allclose(p, r, rtol=1e-14, atol=1e-15)  # decoded at once or by BLAS
        for p, k in zip(a.xi, a.diverged_at):
            stop = len(p) if k < 0 else k
            assert np.isfinite(p[:stop]).all() and np.isnan(p[stop:]).all()
        diverged.append(a.diverged)
    assert not diverged[0].any() and diverged[1].any() and not diverged[1].all()


def test_states_are_encoded_where_asked_and_the_lists_in_full_when_read(model_and_data):
    model, ds = model_and_data
    bounds = np.array([[0, 57], [812, 1130]])
    full = encode_states(model.autoencoder, ds.q, ds.dq, bounds)
    rows = np.zeros(318, dtype=bool)
    rows[[0, 50, 100, 317]] = True  # 100 and 317: past the first jump's end
    part = encode_states(model.autoencoder, ds.q, ds.dq, bounds, rows)
    for a, b in zip(full, part):
        np.testing.assert_array_equal(a[:, rows], b[:, rows])
        np.testing.assert_array_equal(a[0, 56:], np.broadcast_to(a[0, 56], a[0, 56:].shape))
    with pytest.raises(ValueError, match=r"rows: shape \(10,\), expected \(318,\)"):
        encode_states(model.autoencoder, ds.q, ds.dq, bounds, np.ones(10, bool))
    calls = []
    views = JumpViews(lambda: calls.append(1) or full[0], bounds[:, 1] - bounds[:, 0])
    assert len(views) == 2 and calls == []  # nothing computed until read
    assert [p.shape for p in views] == [(57, model.latent_dim), (318, model.latent_dim)] and calls == [1]
    np.testing.assert_array_equal(views[-1], full[0][1])
    sysm = model.rollout_system(ds, np.arange(3))
    a, b = ds.jump_bounds()[2]
    np.testing.assert_allclose(sysm.x[2], model.autoencoder.encode(ds.q[a:b]), rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(sysm.v[2], model.autoencoder.encode_derivative(ds.dq[a:b]), rtol=1e-12, atol=1e-13)
