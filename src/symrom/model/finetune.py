"""Fine-tuning a trained model on a few jumps of another source (sim-to-real).

The encoder is kept: the latent coordinates, and so the meaning of every
learned term, stay those of the source model. On the new jumps:
- the decoder is refit by least squares pulled towards the source decoder,
  min ||q - W_d xi - B_d||^2 + r ||[W_d, B_d] - [W_d0, B_d0]||^2;
- each phase's Xi is refit by the ``FineTune`` regressor: sequential
  thresholding on the SINDy loss the source model was trained with (its
  ``decoded_weight``), pulled towards the source coefficients,
  + r ||Xi - Xi_0||^2, starting from the source support (terms may drop
  out, none are added). A phase the new jumps do not hold keeps the source
  coefficients.
Both are closed form. ``prior_weight`` sets r relative to the data's scale: 0
refits from the new jumps alone, large values keep the source model. Phases
are matched by name.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from symrom.data.dataset import Dataset
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.estimator import data_hash, phase_data
from symrom.model.hybrid import HybridModel, ModelDataError
from symrom.model.regressors.base import Coefficients, RegressionProblem
from symrom.model.regressors.prior import FineTune


@dataclass(frozen=True)
class FineTuneConfig:
    """prior_weight: pull towards the source model, relative to mean(diag ThetaᵀTheta)
    per phase (and to mean(xi²) for the decoder); threshold: as in training, in the
    source's sparsity measure (None: the source's own threshold)."""

    prior_weight: float = 0.01
    threshold: float | None = None
    refit_decoder: bool = True


def _decoder_towards(xi: np.ndarray, q: np.ndarray, W0: np.ndarray, b0: np.ndarray,
                     weight: float) -> tuple[np.ndarray, np.ndarray]:
    """Ridge-to-prior least squares for (W_d (18, l), B_d (18,)) from xi (N, l), q (N, 18)."""
    X = np.hstack([xi, np.ones((xi.shape[0], 1))])
    A = X.T @ X
    r = weight * np.mean(np.diag(A))
    prior = np.vstack([W0.T, b0[None]])  # (l+1, 18)
    coef = np.linalg.solve(A + r * np.eye(A.shape[0]), X.T @ q + r * prior)
    return coef[:-1].T.copy(), coef[-1].copy()


def finetune(model: HybridModel, ds: Dataset, rows: np.ndarray | None = None,
             config: FineTuneConfig = FineTuneConfig()) -> HybridModel:
    """A new model adapted to the ``train`` rows of ``ds`` (or boolean ``rows`` (N,))."""
    rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
    if not rows.any():
        raise ValueError("no fine-tuning rows (the dataset has no 'train' jumps)")
    model.check_data(ds)
    model.phase_index(ds, rows)  # every phase of the new rows must be one the model knows
    ae0 = model.autoencoder
    xi = ae0.encode(ds.q[rows])
    W_d, B_d = (_decoder_towards(xi, ds.q[rows], ae0.W_d, ae0.B_d, config.prior_weight)
                if config.refit_decoder else (ae0.W_d, ae0.B_d))
    ae = LinearAutoencoder(ae0.W_e.copy(), ae0.B_e.copy(), W_d, B_d)
    trained = model.info.get("training", {})
    weight = float(model.info.get("decoded_weight", trained.get("decoded_weight", 1.0)))
    phases = phase_data(ds, rows, ae, model.library, weight, model.phase_names)
    if all(p is None for p in phases):
        raise ModelDataError("no fine-tuning rows in any of the model's phases")
    all_ddxi = ae.encode_derivative(ds.ddq[rows])
    problem = RegressionProblem(model.library, list(model.phase_names), phases,
                                np.maximum(all_ddxi.std(axis=0), 1e-12), ds.dt)
    threshold = float(trained.get("threshold", 0.01)) if config.threshold is None else config.threshold
    regressor = FineTune(config.prior_weight, threshold, trained.get("measure", "coefficient"),
                         float(trained.get("alpha", 0.0)))
    fit = regressor.fit(problem, init=Coefficients(model.Xi, model.mask))
    info = dict(model.info)
    info["finetune"] = {"config": asdict(config), "data_sha256": data_hash(ds),
                        "source": ds.source, "n_rows": int(rows.sum()),
                        "base_data_sha256": model.info.get("data_sha256"),
                        "phases_refit": [n for n, p in zip(model.phase_names, phases) if p is not None]}
    return replace(model, autoencoder=ae, Xi=fit.Xi, mask=fit.mask, info=info)
