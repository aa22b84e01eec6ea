"""Fine-tuning a trained model on a few jumps of another source (sim-to-real).

The encoder is kept: the latent coordinates, and so the meaning of every
learned term, stay those of the source model. On the new jumps' rows:

- the decoder is refit, guarded. It is least squares pulled towards the
  source decoder as if ``prior_weight`` x N more rows, spread like the
  source's training latents, had been decoded by the source decoder:
  min ||q - W_d (xi - m) - c||^2 + r N (sum_i s_i^2 ||W_d[:, i] - W_d0[:, i]||^2
  + ||c - c0||^2), with m the new rows' latent mean, s the source's latent
  spread (its ``provenance.training.latent_spread``; older model files: the largest |xi|),
  c0 = W_d0 m + B_d0 and B_d = c - W_d m. Along a latent direction the new
  rows barely move in, the source decoder is kept. If the new rows vary, along
  some latent direction, by less than ``decoder_min_spread`` of the source's
  spread (a flight-only set in which one latent stays still, jumps in place),
  they cannot determine the decoder: ``DecoderRefitError`` is raised, and
  ``refit_decoder=False`` keeps the source decoder;
- each phase's Xi is refit by the ``FineTune`` regressor: sequential
  thresholding on the SINDy loss the source model was trained with (its
  ``decoded_weight``), pulled towards the source coefficients,
  + r ||Xi - Xi_0||^2, starting from the source support (terms may drop
  out, none are added). A phase the new rows do not hold keeps the source
  coefficients (``provenance.finetune.phases_kept``).

Both are closed form. ``prior_weight`` sets r relative to the data: 0 refits
from the new rows alone, large values keep the source model. Phases are
matched by name. ``experiments.finetune`` adds the check on validation jumps.

``method="calibrate"`` keeps every coefficient and fits only per
phase input gains, offsets and damping, and keeps the flight phase's gravity
unless the new rows contradict it (``learn.calibrate``): what a dozen jumps can
determine. ``method="acceleration"`` refits every coefficient as above.
``method="rollout"`` adapts the coefficients instead by the rollout-aware
refinement (``Refine``) started from the source coefficients, on the new
jumps: for a source model that was itself refined, whose coefficients an
acceleration fit would pull away from what makes its rollouts right. Only
the phases the new jumps hold are refit; the others keep the source's.

``method="calibrate_rollout"`` calibrates first, then refines by ``Refine``,
started from the calibrated coefficients, the coefficients of every non-flight
phase the new jumps hold (on the calibrated support: the source's and its
calibration terms) to the rollouts of the new jumps, with the flight phase held
exactly as calibration leaves it (``Refine.hold``): gravity is kept by
construction, and the contact phases may correct what an acceleration fit of a
few parameters cannot, such as a stance spring the target's ground does not
have, so that the jump leaves the ground with the speed the data show. The
record holds the calibration (the refinement's start) and the refinement's
(``regressor``, ``phases_rolled_out``). Without non-flight rows it is
``calibrate``. It is the default: on both sim-to-real targets' val jumps it
scores better than ``calibrate`` from every source (docs/results.md), at the cost of
the rollouts of its refinement.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from symrom.data.dataset import Dataset
from symrom.learn.adam import Adam
from symrom.learn.calibrate import CALIBRATION_TERMS, calibrate, flight_gravity, nothing_to_adapt
from symrom.learn.estimator import data_hash, invariant_terms, phase_data, trajectories
from symrom.learn.plugins import PluginConfigError, regressor_from_dict
from symrom.learn.regressors.base import Coefficients, RegressionProblem
from symrom.learn.regressors.prior import FineTune
from symrom.learn.regressors.refine import Refine
from symrom.learn.regressors.stlsq import STLSQ
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.hybrid import HybridModel, ModelDataError
from symrom.model.provenance import FineTuneRecord, freeze
from symrom.names import FLIGHT_PHASE

FINETUNE_METHODS = ("calibrate", "acceleration", "rollout", "calibrate_rollout")
ROLLOUT_METHODS = ("rollout", "calibrate_rollout")  # the methods that refine on rollouts (``Refine``)


class DecoderRefitError(ModelDataError):
    """The fine-tuning rows cannot determine the decoder; one clear line."""


@dataclass(frozen=True)
class FineTuneConfig:
    """prior_weight: pull towards the source model, relative to mean(diag ThetaᵀTheta)
    per phase, and for the decoder the weight of the source's pseudo-rows relative to
    the new rows; threshold: as in training, in the source's sparsity measure (None:
    the source's own threshold); refit_decoder: False keeps the source decoder;
    decoder_min_spread: the least spread, as a fraction of the source's, the new rows
    must have along every latent direction for the decoder to be refit; method:
    ``calibrate``, ``acceleration``, ``rollout`` or ``calibrate_rollout`` (module
    docstring); calibration_terms (``calibrate`` and ``calibrate_rollout``): ``every``
    (chosen on val), an offset and a damping in every non-flight equation, or
    ``support``, only where the source's equation has the term (``learn.calibrate``)."""

    prior_weight: float = 0.01
    threshold: float | None = None
    refit_decoder: bool = True
    decoder_min_spread: float = 0.05
    method: str = "calibrate_rollout"
    calibration_terms: str = "every"

    def __post_init__(self) -> None:
        if not self.prior_weight >= 0:
            raise ValueError(f"prior_weight must be >= 0, got {self.prior_weight}")
        if not 0 <= self.decoder_min_spread < 1:
            raise ValueError(f"decoder_min_spread must lie in [0, 1), got {self.decoder_min_spread}")
        if self.calibration_terms not in CALIBRATION_TERMS:
            raise ValueError(f"calibration_terms must be one of {CALIBRATION_TERMS}, got {self.calibration_terms!r}")
        if self.method not in FINETUNE_METHODS:
            raise ValueError(f"fine-tuning method must be one of {FINETUNE_METHODS}, got {self.method!r}")
        if self.method in ROLLOUT_METHODS and self.threshold is not None:
            raise ValueError(f"threshold applies to method 'acceleration'; method {self.method!r} refines the "
                             "source's active terms and thresholds nothing")
        if self.method == "calibrate" and self.threshold is not None:
            raise ValueError("threshold applies to method 'acceleration'; method 'calibrate' keeps the "
                             "source's active terms and thresholds nothing")


def source_spread(model: HybridModel) -> np.ndarray:
    """(l,) the spread of the source's training latents: its recorded standard deviation,
    or for model files without it the largest |xi| seen in training."""
    l = model.latent_dim
    s = model.provenance.training.latent_spread
    s = np.asarray(s, dtype=float) if s is not None and len(s) == l else np.asarray(model.latent_scale[:l])
    return np.maximum(s, 1e-12)


def source_sparsity(model: HybridModel) -> tuple[float, str, float]:
    """(threshold, measure, alpha) of the regressor that fitted ``model``, read from its
    file's ``estimator.regressor`` (a refinement's: its initial regressor's; Adam's: its
    coefficient threshold, no ridge); ``ModelDataError`` when the file records none."""
    record = model.estimator.get("regressor")
    if record is None:
        raise ModelDataError("estimator.regressor: the model records no regressor, so its sparsity "
                             "threshold and measure are unknown; fine-tune it by method 'rollout'")
    try:
        reg = regressor_from_dict(record, "estimator.regressor")
    except PluginConfigError as e:
        raise ModelDataError(str(e)) from None
    while isinstance(reg, Refine):
        reg = reg.initial
    if isinstance(reg, (STLSQ, FineTune)):
        return float(reg.threshold), reg.measure, float(reg.alpha)
    if isinstance(reg, Adam):
        return float(reg.threshold), "coefficient", 0.0
    raise ModelDataError(f"estimator.regressor: fine-tuning cannot take its threshold from kind {reg.kind!r}")


def decoder_excitation(xi: np.ndarray, spread: np.ndarray) -> tuple[float, np.ndarray]:
    """How well rows xi (N, l) determine a decoder: the smallest standard deviation of
    xi / spread over all latent directions, and that direction (l,) (unit, in xi)."""
    z = (xi - xi.mean(axis=0)) / spread
    w, v = np.linalg.eigh(z.T @ z / max(len(z), 1))
    d = v[:, 0] / spread
    return float(np.sqrt(max(w[0], 0.0))), d / np.linalg.norm(d)


def refit_decoder(xi: np.ndarray, q: np.ndarray, W0: np.ndarray, b0: np.ndarray, spread: np.ndarray,
                  weight: float) -> tuple[np.ndarray, np.ndarray]:
    """(W_d (18, l), B_d (18,)) from xi (N, l), q (N, 18), pulled towards (W0, b0) with the
    source's latent spread (l,) and relative weight (module docstring)."""
    n = xi.shape[0]
    m = xi.mean(axis=0)
    X = xi - m
    r = weight * n
    c = (q.mean(axis=0) + weight * (W0 @ m + b0)) / (1.0 + weight)
    A = X.T @ X + r * np.diag(spread ** 2)
    W = np.linalg.solve(A, X.T @ (q - q.mean(axis=0)) + r * np.diag(spread ** 2) @ W0.T).T
    return W, c - W @ m


def check_decoder(model: HybridModel, ds: Dataset, rows: np.ndarray, config: FineTuneConfig) -> float:
    """The excitation of the decoder refit by ``rows`` (N,) (``decoder_excitation``);
    ``DecoderRefitError`` if the decoder is to be refit and the rows cannot determine it."""
    excitation, direction = decoder_excitation(model.autoencoder.encode(ds.q[rows]), source_spread(model))
    if config.refit_decoder and excitation < config.decoder_min_spread:
        terms = " ".join(f"{c:+.2f} xi{i + 1}" for i, c in enumerate(direction) if abs(c) >= 0.01)
        raise DecoderRefitError(
            f"the fine-tuning rows cannot determine the decoder: along the latent direction "
            f"({terms.lstrip('+')}) they vary by {100 * excitation:.2g} % of the source's training spread "
            f"(at least {100 * config.decoder_min_spread:g} % is needed); keep the source decoder "
            "(refit_decoder=False) or add rows that move along it")
    return excitation


def finetune(model: HybridModel, ds: Dataset, rows: np.ndarray | None = None,
             config: FineTuneConfig = FineTuneConfig()) -> HybridModel:
    """A new model adapted to the ``train`` rows of ``ds`` (or boolean ``rows`` (N,)).

    Raises ``ModelDataError`` for rows the model cannot take (another robot, a phase
    it has no equations for) and ``DecoderRefitError`` when the rows cannot determine
    the decoder (module docstring).
    """
    rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
    if not rows.any():
        raise ValueError("no fine-tuning rows (the dataset has no 'train' jumps)")
    model.check_data(ds)
    row_phase = model.phase_index(ds, rows)  # every phase of the new rows must be one the model knows
    ae0 = model.autoencoder
    xi = ae0.encode(ds.q[rows])
    spread = source_spread(model)
    excitation = check_decoder(model, ds, rows, config)
    decoder = {"refit": bool(config.refit_decoder), "excitation": excitation,
               "max_abs_W_d_source": float(np.abs(ae0.W_d).max())}
    if config.refit_decoder:
        W_d, B_d = refit_decoder(xi, ds.q[rows], ae0.W_d, ae0.B_d, spread, config.prior_weight)
    else:
        W_d, B_d = ae0.W_d.copy(), ae0.B_d.copy()
    decoder["max_abs_W_d"] = float(np.abs(W_d).max())
    ae = LinearAutoencoder(ae0.W_e.copy(), ae0.B_e.copy(), W_d, B_d)
    weight = float(model.estimator.get("decoded_weight", 1.0))
    phases = phase_data(ds, rows, ae, model.library, weight, model.phase_names)
    if all(p is None for p in phases):
        raise ModelDataError("no fine-tuning rows in any of the model's phases")
    calibration, init, hold = None, Coefficients(model.Xi, model.mask), ()
    if config.method in ("calibrate", "calibrate_rollout"):
        Xi, mask, calibration = calibrate(model, ae, ds, rows, config.prior_weight, config.calibration_terms)
        # calibrate_rollout refines the other phases from here; the flight phase stays as calibration left it
        hold = tuple(n for n, p in zip(model.phase_names, phases) if n == FLIGHT_PHASE or p is None)
        if config.method == "calibrate" or len(hold) == len(phases):  # nothing for the rollouts to refine
            if not calibration["parameters"] and not config.refit_decoder:
                raise nothing_to_adapt()
            return _finetuned(model, ds, rows, config, ae, Xi, mask, phases, decoder, calibration)
        init = Coefficients(Xi, mask)
    all_ddxi = ae.encode_derivative(ds.ddq[rows])
    if config.method in ROLLOUT_METHODS:  # Refine rolls the new jumps out, in the model's phase numbering
        index = np.zeros(ds.n_samples, dtype=int)
        index[rows] = row_phase
        trajs, regressor = trajectories(ds, rows, ae, index), Refine(hold=hold)
    else:
        threshold, measure, alpha = source_sparsity(model)
        trajs, regressor = [], FineTune(prior_weight=config.prior_weight,
                                        threshold=threshold if config.threshold is None else config.threshold,
                                        measure=measure, alpha=alpha)
    barred, why = invariant_terms(model.library, ae, tuple(model.estimator.get("invariant", ())))
    problem = RegressionProblem(model.library, list(model.phase_names), phases,
                                np.maximum(all_ddxi.std(axis=0), 1e-12), ds.dt, trajs,
                                excluded=barred, excluded_reason=why)
    fit = regressor.fit(problem, init=init)
    Xi, mask = fit.Xi.copy(), fit.mask.copy()
    for k, p in enumerate(phases):  # a phase the rows do not hold keeps the source's, whatever the regressor
        if p is None:
            Xi[k], mask[k] = model.Xi[k], model.mask[k]
    return _finetuned(model, ds, rows, config, ae, Xi, mask, phases, decoder, calibration,
                      regressor=regressor.to_dict())


def _finetuned(model: HybridModel, ds: Dataset, rows: np.ndarray, config: FineTuneConfig,
               ae: LinearAutoencoder, Xi: np.ndarray, mask: np.ndarray, phases: list, decoder: dict,
               calibration: dict | None = None, regressor: dict | None = None) -> HybridModel:
    """The fine-tuned model and its ``provenance.finetune`` record (with the regressor's record, the
    calibration's, the phases fitted to rollouts, ``phases_rolled_out``, and the decoded flight
    acceleration on the rows' flight rows, ``flight_gravity``)."""
    held = [n for n, p in zip(model.phase_names, phases) if p is not None]
    rolled = ([] if regressor is None or regressor["kind"] != Refine.kind else
              [n for n in held if n not in regressor.get("hold", [])])
    refit = held if calibration is None else [n for n in held if calibration["phases"][n]["calibrated"]]
    n_rows = {n: int(p.theta.shape[0]) for n, p in zip(model.phase_names, phases) if p is not None}
    record = FineTuneRecord(config=freeze(asdict(config)), regressor=freeze(regressor), data_sha256=data_hash(ds),
                            source=ds.source, n_rows=int(rows.sum()), base_data_sha256=model.provenance.data.sha256,
                            phases_refit=tuple(refit), rows_per_phase=freeze(n_rows),
                            phases_kept=tuple(n for n in model.phase_names if n not in held),
                            phases_rolled_out=tuple(rolled), decoder=freeze(decoder), calibration=freeze(calibration))
    tuned = replace(model, autoencoder=ae, Xi=Xi, mask=mask, provenance=model.provenance.with_finetune(record))
    return replace(tuned, provenance=tuned.provenance.with_finetune(flight_gravity=flight_gravity(tuned, ds, rows)))
