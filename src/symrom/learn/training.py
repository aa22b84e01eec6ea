"""Multi-phase training, the paper's three steps, from one configuration object.

(a) encoder and decoder on the contact phase, minimising the reconstruction
    loss ||q - W_d (W_e q + B_e) - B_d||^2;
(b) encoder frozen, decoder on all phases, same loss;
(c) autoencoder frozen, one sparse Xi per phase minimising
    ||ddxi - Theta Xi||^2 + ||ddq - W_d Theta Xi||^2 (+ sparsity).

``train(ds, TrainConfig(...))`` is a thin wrapper: ``TrainConfig`` is the
command line's flat factory of an estimator, ``TrainConfig.estimator()`` builds
the ``SymbolicROM`` with its plug-ins and ``fit`` does the work. The model file
records the plug-ins themselves (``HybridModel.estimator``), not this object.
Solvers: ``exact`` (default) takes each step's closed-form optimum
(``PCAEncoder`` then ``STLSQ``); ``adam`` is the paper's gradient training
(``AdamAutoencoder`` then ``Adam``).

The defaults reproduce the paper. Options beyond it: ``encoder_components``
and ``encoder_scaling`` (what the encoder reads, and whether components are
standardised by their spread), ``decoded_weight`` (weight of the
decoded-acceleration term of step (c)), ``alpha`` (ridge on the standardised
library terms), ``measure`` (``contribution``: a scale-free threshold),
``collinearity`` (leave out terms near-collinear with simpler ones),
``refine`` (rollout-aware refinement of the coefficients) and the library
blocks (``poly_order``, ``trig``, ``inputs``).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from symrom.data.dataset import Dataset
from symrom.learn.adam import Adam, AdamConfig, Progress, check_seed
from symrom.learn.encoders import (
    SCALINGS,
    AdamAutoencoder,
    PCAEncoder,
    check_components,
    check_invariant,
    fit_decoder,
    principal_encoder,
    varimax,
)
from symrom.learn.estimator import SymbolicROM, contact_rows, data_hash
from symrom.learn.regressors.base import Regressor
from symrom.learn.regressors.stlsq import STLSQ, check_measure
from symrom.model.hybrid import HybridModel
from symrom.model.library import LibrarySpec
from symrom.model.provenance import Provenance, thaw
from symrom.names import STANCE_PHASE

__all__ = ["AdamConfig", "SOLVERS", "TrainConfig", "contact_rows", "data_hash", "fit_decoder",
           "principal_encoder", "reconstruction_error", "train", "train_into", "varimax"]

SOLVERS = ("exact", "adam")


@dataclass
class TrainConfig:
    """latent_dim l, polynomial order p, library options, solver and its settings.

    ``contact_phase`` names the phase that trains the encoder in step (a).
    ``encoder_components``: names of the q components the encoder reads (None =
    all 18, the paper); ``encoder_scaling``: ``none`` or ``spread``;
    ``encoder_base_latents``: latents from the base pose, the rest from the joints
    (None: one PCA over what the encoder reads, the paper);
    ``decoded_weight``: weight of the decoded-acceleration term of the SINDy loss
    (1 = the paper); ``alpha``: ridge on the standardised features in step (c)
    (0 = none, the paper); ``measure``: what ``threshold`` applies to,
    ``coefficient`` (the paper) or ``contribution``; ``collinearity``: leave out
    terms whose |correlation| with a simpler one exceeds it on a phase's rows
    (None = keep all, the paper); ``refine``: refine the coefficients on rollout
    error (``symrom.learn.regressors.refine``); ``max_terms``: with ``refine``, the
    refinement prunes the model to at most this many active terms (``Refine.max_terms``;
    None = the support STLSQ chose); ``keep``: with ``max_terms``, phases the pruning
    leaves whole (``Refine.keep``); ``polish``: with ``refine``, phases refined
    again alone after it (``Refine.polish``); ``path``: thresholds of a sparsity
    path to record with validation errors (None = none); ``invariant``: base components
    (``x``, ``y``) along which the dynamics are held invariant (``SymbolicROM.invariant``;
    () = none, the paper).
    """

    latent_dim: int = 2
    poly_order: int = 1
    trig: bool = True
    inputs: bool = True
    solver: str = "exact"
    threshold: float = 0.01
    alpha: float = 0.0
    seed: int = 0
    contact_phase: str = STANCE_PHASE
    encoder_components: tuple[str, ...] | None = None
    encoder_scaling: str = "none"
    encoder_base_latents: int | None = None
    decoded_weight: float = 1.0
    measure: str = "coefficient"
    collinearity: float | None = None
    refine: bool = False
    max_terms: int | None = None
    keep: tuple[str, ...] = ()
    polish: tuple[str, ...] = ()
    path: tuple[float, ...] | None = None
    invariant: tuple[str, ...] = ()
    adam: AdamConfig = field(default_factory=AdamConfig)

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise ValueError(f"unknown solver {self.solver!r}; choose from {SOLVERS}")
        if not 1 <= self.latent_dim <= 18:
            raise ValueError(f"latent_dim={self.latent_dim}: must be within 1..18")
        if not self.threshold >= 0:  # checked here, before any data is read
            raise ValueError(f"threshold={self.threshold:g}: a sparsity threshold must be >= 0")
        if isinstance(self.adam, dict):
            self.adam = AdamConfig(**self.adam)
        if self.solver == "adam":
            check_seed(self.seed)
        self.encoder_components = check_components(self.encoder_components, self.latent_dim)
        self.invariant = check_invariant(self.invariant)
        if len(self.invariant) >= self.latent_dim:
            raise ValueError(f"invariant={','.join(self.invariant)}: latent_dim {self.latent_dim} leaves no latent "
                             "position the dynamics may read (each component takes one)")
        if self.encoder_base_latents is not None and not 1 <= self.encoder_base_latents < self.latent_dim:
            raise ValueError(f"encoder_base_latents must lie within 1..{self.latent_dim - 1} (latent_dim "
                             f"{self.latent_dim}, at least one latent left for the joints), got "
                             f"{self.encoder_base_latents}")
        if self.encoder_scaling not in SCALINGS:
            raise ValueError(f"encoder_scaling must be one of {SCALINGS}, got {self.encoder_scaling!r}")
        check_measure(self.measure)
        if not self.alpha >= 0:
            raise ValueError(f"alpha={self.alpha:g}: must be >= 0")
        if not self.decoded_weight >= 0:
            raise ValueError(f"decoded_weight={self.decoded_weight:g}: must be >= 0")
        if self.collinearity is not None and not 0 < self.collinearity <= 1:
            raise ValueError(f"collinearity={self.collinearity:g}: must lie in (0, 1]")
        if self.path is not None:
            self.path = tuple(float(t) for t in self.path)
        if self.refine and self.solver != "exact":
            raise ValueError("refine applies to the exact solver")
        if self.max_terms is not None and self.max_terms < 1:
            raise ValueError(f"max_terms={self.max_terms}: must be a positive number of terms")
        if self.max_terms is not None and not self.refine:
            raise ValueError(f"max_terms={self.max_terms}: a budget of the refinement; needs refine=True (or "
                             "select=True, where it is the budget of the selection's refinements)")
        self.keep = tuple(self.keep)
        if self.keep and self.max_terms is None:
            raise ValueError(f"keep={','.join(self.keep)}: a rule of the pruning; needs max_terms=N")
        self.polish = tuple(self.polish)
        if self.polish and not self.refine:
            raise ValueError(f"polish={','.join(self.polish)}: a stage of the refinement; needs refine=True")

    def regressor(self) -> Regressor:
        """The step (c) plug-in these settings describe."""
        if self.solver == "adam":
            return Adam(config=self.adam, threshold=self.threshold, seed=self.seed)
        base = STLSQ(threshold=self.threshold, measure=self.measure, alpha=self.alpha,
                     collinearity=self.collinearity)
        if self.refine:
            from symrom.learn.regressors.refine import Refine

            return Refine(base, max_terms=self.max_terms, keep=self.keep, polish=self.polish)
        return base

    def estimator(self, progress: Progress | None = None) -> SymbolicROM:
        """The ``SymbolicROM`` these settings describe."""
        if self.solver == "adam":
            encoder = AdamAutoencoder(config=self.adam, components=self.encoder_components, seed=self.seed,
                                      progress=progress)
            regressor = Adam(config=self.adam, threshold=self.threshold, seed=self.seed, progress=progress)
        else:
            encoder = PCAEncoder(components=self.encoder_components, scaling=self.encoder_scaling,
                                 base_latents=self.encoder_base_latents)
            regressor = self.regressor()
        return SymbolicROM(latent_dim=self.latent_dim,
                           library=LibrarySpec.standard(self.poly_order, self.trig, self.inputs),
                           encoder=encoder, regressor=regressor, decoded_weight=self.decoded_weight,
                           contact_phase=self.contact_phase, path_thresholds=self.path, invariant=self.invariant,
                           settings=asdict(self))

    @classmethod
    def from_provenance(cls, provenance: Provenance, **changes) -> TrainConfig:
        """The settings a model was trained with (``provenance.training.settings``), ``changes``
        applied; ``ValueError`` if the model records none (fitted by a hand-built estimator)."""
        settings = provenance.training.settings
        if settings is None:
            raise ValueError("the model records no training settings (provenance.training.settings): it was "
                             "fitted by a SymbolicROM built by hand, whose plug-ins its file's estimator holds")
        return replace(cls(**thaw(settings)), **changes)


def train(ds: Dataset, config: TrainConfig = TrainConfig(), rows: np.ndarray | None = None,
          progress: Progress | None = None, data_path: str | None = None) -> HybridModel:
    """Train a HybridModel on the ``train`` split of ``ds`` (or on boolean ``rows`` (N,));
    ``data_path``: the file ``ds`` was read from, recorded in the model.

    Returns a model whose arrays are all in physical units (rad, m, s).
    """
    model = config.estimator(progress).fit(ds, rows, progress).model
    if data_path is not None:
        model = replace(model, provenance=model.provenance.with_data_path(data_path))
    return model


def train_into(out: str | os.PathLike, data: str | os.PathLike, config: TrainConfig = TrainConfig(),
               force: bool = False, progress: Progress | None = None) -> HybridModel:
    """``train`` on the dataset file ``data``, written as the model folder ``out`` (``model.json``,
    ``equations.txt``; atomically, an existing folder only with ``force``, never one holding
    ``data``); the model, which records ``data`` as where it was trained. Refused before any
    work: an output in the way, kept or polished phases the data do not have."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.data.io import read_dataset
    from symrom.model.persistence import write_model_files

    check_output_file(out, force, inputs=(data,))
    ds = read_dataset(data)
    for key in ("keep", "polish"):
        unknown = [p for p in getattr(config, key) if p not in ds.phase_names]
        if unknown:
            raise ValueError(f"{key}={','.join(unknown)}: no such phase in {data} (its phases are "
                             f"{', '.join(ds.phase_names)})")
    model = train(ds, config, progress=progress, data_path=str(data))
    with atomic_dir(out, force) as tmp:
        write_model_files(model, tmp)
    return model


def reconstruction_error(model: HybridModel, ds: Dataset, rows: np.ndarray) -> float:
    """The reconstruction loss ||q - q_recon||^2 (squared 2-norm over the 18
    components, as the paper's L_recon) averaged over ``rows``: the sweep's E_dec."""
    q = ds.q[rows]
    return float(np.mean(np.sum((model.autoencoder.reconstruct(q) - q) ** 2, axis=1)))
