from math import comb

import numpy as np
import pytest
import sympy

from symrom.model.library import Library


@pytest.mark.parametrize("l,p,expected", [(2, 1, 15), (4, 1, 29)])
def test_counts_match_paper_table1(l, p, expected):
    lib = Library.standard(l, p)
    assert lib.n_features == expected
    assert len(lib.feature_names) == expected


@pytest.mark.parametrize("l,p", [(1, 0), (1, 3), (3, 2), (6, 1)])
def test_counts_follow_formula(l, p):
    lib = Library.standard(l, p)
    formula = sum(comb(2 * l + k - 1, k) for k in range(p + 1)) + 2 * (2 * l) + l
    assert lib.n_features == formula == len(lib.feature_names)
    assert lib.transform(np.zeros((3, l)), np.zeros((3, l)), np.zeros((3, l))).shape == (3, formula)


def test_names_and_columns_agree():
    lib = Library.standard(2, 2)
    rng = np.random.default_rng(0)
    xi, dxi, nu = rng.normal(size=(5, 2)), rng.normal(size=(5, 2)), rng.normal(size=(5, 2))
    theta = lib.transform(xi, dxi, nu)
    syms = sympy.symbols("xi1 xi2 dxi1 dxi2 nu1 nu2")
    fn = sympy.lambdify(syms, lib.sympy_features(), "numpy")
    for i in range(5):
        vals = np.array(fn(*xi[i], *dxi[i], *nu[i]), dtype=float)
        np.testing.assert_allclose(theta[i], vals, rtol=1e-12)
    names = lib.feature_names
    assert names[:5] == ["1", "xi1", "xi2", "dxi1", "dxi2"]
    assert "sin(xi1)" in names and "cos(dxi2)" in names and names[-2:] == ["nu1", "nu2"]
    assert theta[:, names.index("xi1*dxi2")] == pytest.approx(xi[:, 0] * dxi[:, 1])


def test_round_trip_and_bad_spec():
    lib = Library.standard(3, 2, trig=False)
    assert Library.from_dict(lib.to_dict()) == lib
    d = lib.to_dict()
    d["feature_names"] = d["feature_names"][::-1]
    with pytest.raises(ValueError):
        Library.from_dict(d)
    with pytest.raises(ValueError):
        Library.standard(0, 1)
