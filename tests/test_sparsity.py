"""Sparsity that means something: collinearity audit and the scale-free measures."""

import numpy as np
import pytest

from symrom.learn.audit import audit_collinearity, correlations
from symrom.learn.regressors.stlsq import STLSQConfig, stlsq
from symrom.learn.training import TrainConfig, train
from symrom.model.library import Library
from symrom.testing import make_planted_dataset

# Stiff, damped latents driven by small inputs: each stays where sin(xi) ~ xi and
# cos(xi) ~ 1, the near-collinear candidates of the paper's library.
NEAR_COLLINEAR = {
    "contact": [{"1": 2.0, "xi1": -30.0, "dxi1": -3.0, "nu1": 5.0},
                {"1": -1.0, "xi2": -20.0, "dxi2": -2.0, "nu2": 4.0}],
    "flight": [{"xi1": -10.0, "dxi1": -1.0}, {"1": -9.8, "dxi2": -0.5}],
}


@pytest.fixture(scope="module")
def collinear():
    return make_planted_dataset(24, 400, embedding="axis", noise=1e-4, seed=4, equations=NEAR_COLLINEAR,
                                amplitude=(0.3, 0.3))


def _planted_mask(model, truth):
    """The planted support in the model's latent order (PCA may swap the axes)."""
    order = np.argmax(np.abs(model.autoencoder.W_e @ truth.E), axis=1)  # model latent i = planted order[i]
    Xi = truth.Xi[:, :, :]
    names = truth.library.feature_names
    perm_names = [n for n in names]
    for i, o in enumerate(order):  # rename features of planted latent o to model latent i
        perm_names = [n.replace(f"xi{o + 1}", f"@{i + 1}").replace(f"nu{o + 1}", f"&{i + 1}") for n in perm_names]
    perm_names = [n.replace("@", "xi").replace("&", "nu") for n in perm_names]
    feat = [perm_names.index(n) for n in names]  # planted feature index of each model feature
    return (Xi[:, feat][:, :, order] != 0)


def test_library_is_near_collinear_on_this_data(collinear):
    ds, truth = collinear
    lib = truth.library
    theta = lib.transform(ds.q[:, :2], ds.dq[:, :2], ds.u[:, :2])
    corr = correlations(theta)
    names = lib.feature_names
    pair = lambda a, b: corr[names.index(a), names.index(b)]  # noqa: E731
    assert pair("sin(xi1)", "xi1") > 0.999 and pair("cos(xi1)", "1") > 0.999


def test_paper_defaults_keep_cancelling_terms(collinear):
    ds, truth = collinear
    model = train(ds, TrainConfig())
    assert model.mask.sum() > 2 * (truth.Xi != 0).sum()


@pytest.mark.parametrize("measure, threshold", [("explained", 1e-3), ("contribution", 0.02)])
def test_audit_and_scale_free_threshold_recover_the_planted_support(collinear, measure, threshold):
    ds, truth = collinear
    model = train(ds, TrainConfig(measure=measure, threshold=threshold, collinearity=0.995, alpha=1e-6))
    np.testing.assert_array_equal(model.mask, _planted_mask(model, truth))
    # The audit's record says what it left out and which kept term it duplicates.
    dropped = model.phase_info["contact"].report["dropped"]
    assert {"term": "sin(xi1)", "reason": "near-collinear", "with": "xi1"}.items() <= \
        next(d for d in dropped if d["term"] == "sin(xi1)").items()


def test_no_two_active_terms_are_collinear(collinear):
    ds, _ = collinear
    model = train(ds, TrainConfig(measure="explained", threshold=1e-3, collinearity=0.995, alpha=1e-6))
    lib, ae = model.library, model.autoencoder
    for k, name in enumerate(model.phase_names):
        r = ds.rows_of("train") & (ds.phase == k)
        theta = lib.transform(ae.encode(ds.q[r]), ae.encode_derivative(ds.dq[r]), ae.encode_input(ds.u[r]))
        active = np.flatnonzero(model.mask[k].any(axis=1))
        c = correlations(theta[:, active])
        np.fill_diagonal(c, 0.0)
        assert c.max() <= 0.995, name


def test_audit_keeps_the_simpler_term():
    rng = np.random.default_rng(0)
    x = rng.uniform(-0.05, 0.05, 500)
    theta = np.column_stack([np.sin(x), x, np.ones(500), np.cos(x), rng.normal(size=500)])
    keep, dropped = audit_collinearity(theta, ["sin(x)", "x", "1", "cos(x)", "u"],
                                       np.array([4, 1, 0, 4, 2]), 0.995)
    np.testing.assert_array_equal(keep, [False, True, True, False, True])
    assert {(d["term"], d["with"]) for d in dropped} == {("sin(x)", "x"), ("cos(x)", "1")}


def test_explained_measure_drops_one_of_a_cancelling_pair_first():
    # y depends on x; x and x + tiny noise are both offered. Least squares splits the
    # effect into two huge cancelling coefficients; each explains nothing on its own.
    rng = np.random.default_rng(1)
    x = rng.normal(size=2000)
    theta = np.column_stack([x, x + 1e-4 * rng.normal(size=2000), rng.normal(size=2000)])
    y = (2.0 * x + 0.5 * theta[:, 2] + 1e-3 * rng.normal(size=2000))[:, None]
    zero = np.zeros((18, 1))
    spread = (float(y.std()),)
    Xi, mask = stlsq(theta, y, np.zeros((2000, 18)), zero,
                     STLSQConfig(threshold=1e-3, measure="explained", target_spread=spread))
    assert mask[:2, 0].sum() == 1 and mask[2, 0]
    assert Xi[:2, 0].sum() == pytest.approx(2.0, rel=1e-3) and Xi[2, 0] == pytest.approx(0.5, rel=1e-3)
    # The coefficient threshold keeps both halves of the cancelling pair.
    _, mask = stlsq(theta, y, np.zeros((2000, 18)), zero, STLSQConfig(threshold=0.01))
    assert mask[:2, 0].all()


def test_sparsity_path_goes_from_dense_to_sparse_with_validation_errors(collinear):
    ds, truth = collinear
    path = (0.0, 1e-4, 1e-3, 1e-2, 0.1)
    model = train(ds, TrainConfig(measure="explained", collinearity=0.995, alpha=1e-6, threshold=1e-3,
                                  path=path))
    for name in model.phase_names:
        steps = model.phase_info[name].report["path"]
        assert [s["threshold"] for s in steps] == list(path)
        terms = [s["active_terms"] for s in steps]
        assert terms == sorted(terms, reverse=True) and terms[0] > terms[-1]
        assert all(s["val_error"] is not None and s["val_error"] >= 0 for s in steps)
        # At the planted support the validation error is at its noise floor; far sparser, it is not.
        at_truth = next(s for s in steps
                        if s["active_terms"] == int((truth.Xi[model.phase_names.index(name)] != 0).sum()))
        assert at_truth["val_error"] < 0.01 and steps[-1]["val_error"] > 10 * at_truth["val_error"]


def test_library_blocks_give_names_columns_jacobian_and_sympy_from_one_place():
    import sympy

    from symrom.model.library import Custom, Inputs, Polynomial, Trigonometric, symbols

    lib = (Polynomial(2) + Trigonometric() + Inputs() + Custom(("xi1*nu2", "exp(-dxi2)"))).bind(2)
    rng = np.random.default_rng(2)
    xi, dxi, nu = rng.normal(size=(3, 6, 2))
    theta = lib.transform(xi, dxi, nu)
    s, n = symbols(2)
    fn = sympy.lambdify([*s, *n], lib.sympy_features(), "numpy")
    for i in range(6):
        np.testing.assert_allclose(theta[i], np.array(fn(*xi[i], *dxi[i], *nu[i]), float), rtol=1e-12)
    J = lib.jacobian(xi, dxi, nu)
    eps = 1e-6
    for d in range(4):
        st = np.c_[xi, dxi]
        st[:, d] += eps
        fd = (lib.transform(st[:, :2], st[:, 2:], nu) - theta) / eps
        np.testing.assert_allclose(J[:, :, d], fd, atol=1e-4)
    assert lib.feature_names[-2:] == ["nu2*xi1", "exp(-dxi2)"]
    assert Library.from_dict(lib.to_dict()) == lib
    with pytest.raises(ValueError, match="unknown name 'system'"):
        Custom(("system(1)",))
    with pytest.raises(ValueError, match="unknown name 'xi3'"):
        (Polynomial(1) + Custom(("xi3",))).bind(2)
