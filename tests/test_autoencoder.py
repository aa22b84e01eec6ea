import numpy as np

from symrom.learn.training import fit_decoder, principal_encoder, varimax
from symrom.model.autoencoder import LinearAutoencoder


def _random_ae(rng, l=3):
    W_e = rng.normal(size=(l, 18))
    return LinearAutoencoder(W_e, rng.normal(size=l), rng.normal(size=(18, l)), rng.normal(size=18))


def test_input_map_keeps_power_on_representable_motions():
    rng = np.random.default_rng(0)
    ae = _random_ae(rng)
    u = rng.normal(size=(50, 18))
    dq = rng.normal(size=(50, 3)) @ ae.W_e  # velocities in the row space of W_e
    nu, dxi = ae.encode_input(u), ae.encode_derivative(dq)
    np.testing.assert_allclose(np.sum(u * dq, 1), np.sum(nu * dxi, 1), rtol=1e-9)
    np.testing.assert_allclose(nu, u @ np.linalg.pinv(ae.W_e.T).T)


def test_derivatives_share_the_jacobian_and_bias_only_on_positions():
    rng = np.random.default_rng(1)
    ae = _random_ae(rng)
    q = rng.normal(size=(4, 18))
    np.testing.assert_allclose(ae.encode(q) - ae.encode(np.zeros((1, 18))), ae.encode_derivative(q))
    np.testing.assert_allclose(ae.decode(np.zeros((1, 3))), ae.B_d[None])


def test_principal_encoder_reaches_eckart_young_bound():
    rng = np.random.default_rng(2)
    q = rng.normal(size=(400, 18)) @ rng.normal(size=(18, 18)) + rng.normal(size=18)
    l = 4
    W_e = principal_encoder(q, l)
    np.testing.assert_allclose(W_e @ W_e.T, np.eye(l), atol=1e-10)
    W_d, B_d = fit_decoder(q @ W_e.T, q)
    err = np.sum((q @ W_e.T @ W_d.T + B_d - q) ** 2)
    s = np.linalg.svd(q - q.mean(0), compute_uv=False)
    np.testing.assert_allclose(err, np.sum(s[l:] ** 2), rtol=1e-8)
    for _ in range(5):  # no other orthonormal encoder does better
        R = np.linalg.qr(rng.normal(size=(18, l)))[0].T
        Wd, Bd = fit_decoder(q @ R.T, q)
        assert np.sum((q @ R.T @ Wd.T + Bd - q) ** 2) >= err


def test_varimax_recovers_a_hidden_simple_structure():
    rng = np.random.default_rng(3)
    W = np.zeros((2, 18))
    W[0, :9], W[1, 9:] = rng.uniform(0.5, 1.5, 9), rng.uniform(0.5, 1.5, 9)
    W /= np.linalg.norm(W, axis=1, keepdims=True)
    for angle in (0.2, 0.7, 2.0):
        R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        overlap = np.abs(varimax(R @ W) @ W.T)
        assert np.allclose(overlap, np.eye(2), atol=1e-6) or np.allclose(overlap, np.eye(2)[::-1], atol=1e-6)
