"""Each latent is named by its largest encoder loadings, in the text and the LaTeX of the equations."""

from dataclasses import replace

import numpy as np
import pytest

import symrom
from symrom.model.autoencoder import LinearAutoencoder
from symrom.names import Q_NAMES
from symrom.testing import make_planted_dataset


@pytest.fixture(scope="module")
def model():
    ds, _ = make_planted_dataset(n_jumps=8, n_samples=150)
    fitted = symrom.SymbolicROM(latent_dim=2, library=symrom.Polynomial(1) + symrom.Inputs(),
                                encoder=symrom.PCAEncoder(components=("x", "z"))).fit(ds).model
    W_e = np.zeros((2, len(Q_NAMES)))
    W_e[0, Q_NAMES.index("x")] = 1.0
    W_e[0, Q_NAMES.index("y")] = 0.05          # below a tenth of the row's largest: not named
    W_e[1, Q_NAMES.index("z")] = -0.8
    W_e[1, Q_NAMES.index("fr_kn")] = 0.6
    ae = fitted.autoencoder
    return replace(fitted, autoencoder=LinearAutoencoder(W_e, ae.B_e, ae.W_d, ae.B_d))


def test_each_latent_is_named_by_its_largest_loadings(model):
    assert model.latent_loadings() == [([("x", 1.0)], 0), ([("z", -0.8), ("fr_kn", 0.6)], 0)]
    text = model.equations().text()
    assert text.startswith("[contact]")
    assert text.splitlines()[-2:] == ["xi1 ~ 1.00 x", "xi2 ~ -0.80 z + 0.60 fr_kn"]


def test_a_latent_reading_many_components_names_the_largest_and_counts_the_rest(model):
    W_e = model.autoencoder.W_e.copy()
    W_e[1] = 0.0
    W_e[1, :6] = [0.5, -0.45, 0.4, 0.35, 0.3, 0.25]   # the six joints of the front legs
    ae = model.autoencoder
    wide = replace(model, autoencoder=LinearAutoencoder(W_e, ae.B_e, ae.W_d, ae.B_d))
    assert wide.equations().legend()[1] == "xi2 ~ 0.50 fr_hx - 0.45 fr_hy + 0.40 fr_kn + 0.35 fl_hx + ... (2 more)"


def test_latex_names_the_latents_in_latex_comments_only(model):
    lines = model.equations().latex().splitlines()
    assert r"% \xi_{2} \approx -0.80 z + 0.60 fr\_kn" in lines
    # equations, the guards' switching conditions (phase -> phase) and comments: LaTeX throughout
    assert all(l.startswith(("%", r"\ddot{\xi}", r"\mathrm{")) for l in lines)
    assert any(r"\to" in l for l in lines if l.startswith(r"\mathrm{"))
