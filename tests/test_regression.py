import numpy as np

from symrom.learn.regressors.stlsq import STLSQConfig, solve_support, stlsq, weighted_loss, weighted_targets


def _problem(rng, n=300, p=6, l=2):
    theta = rng.normal(size=(n, p))
    W_d = rng.normal(size=(18, l))
    ddxi = rng.normal(size=(n, l))
    ddq = rng.normal(size=(n, 18))
    return theta, ddxi, ddq, W_d


def test_support_solve_is_the_constrained_least_squares_optimum():
    rng = np.random.default_rng(0)
    theta, ddxi, ddq, W_d = _problem(rng)
    mask = rng.random((6, 2)) < 0.6
    Zs, G = weighted_targets(ddxi, ddq, W_d)
    Xi = solve_support(theta.T @ theta, theta.T @ Zs @ G, G, mask)
    assert np.all(Xi[~mask] == 0)
    # Brute force: the paper's loss as one linear least-squares problem over the active entries.
    cols = []
    for i, j in zip(*np.nonzero(mask)):
        E = np.zeros((6, 2))
        E[i, j] = 1
        Z = theta @ E
        cols.append(np.concatenate([Z.ravel(), (Z @ W_d.T).ravel()]))
    A = np.stack(cols, 1)
    b = np.concatenate([ddxi.ravel(), ddq.ravel()])
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(Xi[mask], x, rtol=1e-8, atol=1e-10)
    best = weighted_loss(theta, Xi, ddxi, ddq, W_d)
    for _ in range(5):
        P = Xi + 1e-3 * rng.normal(size=Xi.shape) * mask
        assert weighted_loss(theta, P, ddxi, ddq, W_d) > best


def test_stlsq_recovers_sparse_coefficients():
    rng = np.random.default_rng(1)
    theta = rng.normal(size=(2000, 8))
    true = np.zeros((8, 2))
    true[[0, 3, 5], 0] = [1.5, -0.7, 0.05]
    true[[1, 6], 1] = [2.0, -0.3]
    W_d = rng.normal(size=(18, 2))
    ddxi = theta @ true
    Xi, mask = stlsq(theta, ddxi, ddxi @ W_d.T, W_d, STLSQConfig(threshold=0.01))
    np.testing.assert_array_equal(mask, true != 0)
    np.testing.assert_allclose(Xi, true, atol=1e-10)
    Xi, mask = stlsq(theta, ddxi, ddxi @ W_d.T, W_d, STLSQConfig(threshold=0.1))
    assert not mask[5, 0] and mask[3, 0]  # the 0.05 term falls below a 0.1 threshold


def test_a_feature_that_is_zero_up_to_rounding_gets_no_coefficient():
    # e.g. the latent ground force during flight: exactly zero in physics, 1e-17 after
    # the input map; it must not absorb a huge coefficient from the equilibration.
    rng = np.random.default_rng(2)
    theta = rng.normal(size=(500, 4))
    theta[:, 3] = 1e-17 * rng.normal(size=500)
    true = np.array([[1.0, 0.0], [0.0, -2.0], [0.5, 0.3], [0.0, 0.0]])
    ddxi = theta @ true + 1e-6 * rng.normal(size=(500, 2))
    W_d = rng.normal(size=(18, 2))
    Xi, mask = stlsq(theta, ddxi, ddxi @ W_d.T, W_d, STLSQConfig(threshold=0.01))
    assert np.all(Xi[3] == 0) and not mask[3].any()
    np.testing.assert_allclose(Xi, true, atol=1e-5)


def test_alpha_is_a_ridge_on_the_standardised_features():
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.1, 0.1, size=400)
    theta = np.column_stack([np.ones(400), x, np.sin(x), 50.0 * rng.normal(size=400)])  # x ~ sin x
    y = (0.3 + 2.0 * x + 0.01 * theta[:, 3] + 1e-3 * rng.normal(size=400))[:, None]
    A = theta.T @ theta  # with G = 1 (the latent term alone)
    for alpha in (1e-4, 1e-2):
        Xi = solve_support(A, theta.T @ y, np.eye(1), np.ones((4, 1), bool), alpha=alpha)
        expected = np.linalg.solve(A + alpha * np.diag(np.diag(A)), theta.T @ y)
        np.testing.assert_allclose(Xi, expected, rtol=1e-8)
        # ... and not a ridge of the same weight on the raw coefficients
        raw = np.linalg.solve(A + alpha * np.mean(np.diag(A)) * np.eye(4), theta.T @ y)
        assert np.abs(Xi - raw).max() > 1e-3
