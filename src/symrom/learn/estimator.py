"""``SymbolicROM``: the learner as one estimator with plug-in parts.

In the manner of PySINDy and scikit-learn, the estimator holds only its
settings until ``fit``; its parts are plug-ins:

- ``library``: term blocks (``symrom.model.library``), bound to the latent
  dimension at fit;
- ``encoder``: steps (a) and (b) (``symrom.learn.encoders``): the exact
  ``PCAEncoder`` or the paper's ``AdamAutoencoder``;
- ``regressor``: step (c) (``symrom.learn.regressors``): ``STLSQ``, ``Adam``,
  ``FineTune`` (towards a prior model) or ``Refine`` (rollout-aware).

``SymbolicROM`` is the one entry point for a model: ``fit(ds)`` trains on the
``train`` split and leaves the fitted model in ``model`` (a ``HybridModel``,
what a model file holds; its ``provenance`` says where it comes from);
``from_config`` builds the estimator a flat ``TrainConfig`` (the command
line's settings) describes; ``load`` reads any model file and ``save`` writes
one. Then ``predict`` gives latent accelerations, ``simulate`` rolls the model
out along logged jumps, ``equations`` gives its equations (an ``Equations``
record: per phase the sympy right-hand sides; it prints as text),
``stability`` linearises it. ``symrom.evaluate.metrics.evaluate_model`` scores
it (or any model that can be rolled out) on a split.

Example::

    rom = SymbolicROM(latent_dim=2, library=Polynomial(1) + Inputs(),
                      encoder=PCAEncoder(components=("x", "y", "z")),
                      regressor=STLSQ(threshold=0.05, measure="contribution", alpha=1e-3,
                                      collinearity=0.995))
    rom.fit(ds)
    print(rom.equations())
    ro = rom.simulate(ds, ds.jumps_in("test"))
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from symrom.data.dataset import Dataset, jump_bounds
from symrom.data.envelope import jump_envelope
from symrom.learn.adam import Adam
from symrom.learn.encoders import AdamAutoencoder, PCAEncoder
from symrom.learn.guards import fit_guards
from symrom.learn.plugins import PluginConfigError, encoder_from_dict, regressor_from_dict
from symrom.learn.regressors.base import PhaseData, RegressionProblem, Regressor, Trajectory
from symrom.learn.regressors.stlsq import STLSQ
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.guards import Guard
from symrom.model.hybrid import HybridModel, PhaseInfo, PhaseStability
from symrom.model.library import LibrarySpec, TermBlock
from symrom.model.provenance import DataRecord, Provenance, TrainingRecord, freeze, thaw
from symrom.names import Q_NAMES, STANCE_PHASE

Progress = Callable[[str, float], None]  # (stage description, fraction done 0..1)


def data_hash(ds: Dataset) -> str:
    """SHA-256 of the arrays a model is trained on."""
    h = hashlib.sha256()
    for a in (ds.jump, ds.q, ds.dq, ds.ddq, ds.u, ds.phase):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(np.asarray(ds.split, dtype=str).tobytes())
    return h.hexdigest()


def contact_rows(ds: Dataset, rows: np.ndarray, contact_phase: str) -> np.ndarray:
    """(N,) bool: the ``rows`` in phase ``contact_phase`` (all ``rows`` if there are none)."""
    pid = ds.phase_names.index(contact_phase) if contact_phase in ds.phase_names else 0
    sel = rows & (ds.phase == pid)
    return sel if sel.sum() > 0 else rows


def phase_data(ds: Dataset, rows: np.ndarray, ae: LinearAutoencoder, library, decoded_weight: float,
               phase_names: list[str] | None = None) -> list[PhaseData | None]:
    """Per phase name (default: those of ``ds``), its ``rows`` encoded for step (c)
    (None where ``ds`` has no such row)."""
    sw = np.sqrt(decoded_weight)
    out: list[PhaseData | None] = []
    for name in ds.phase_names if phase_names is None else phase_names:
        r = rows & (ds.phase == ds.phase_names.index(name)) if name in ds.phase_names else np.zeros(0, bool)
        if not r.any():
            out.append(None)
            continue
        theta = library.transform(ae.encode(ds.q[r]), ae.encode_derivative(ds.dq[r]), ae.encode_input(ds.u[r]))
        out.append(PhaseData(theta, ae.encode_derivative(ds.ddq[r]), sw * ds.ddq[r], sw * ae.W_d))
    return out


def trajectories(ds: Dataset, rows: np.ndarray, ae: LinearAutoencoder,
                 phase: np.ndarray | None = None) -> list[Trajectory]:
    """The jumps holding ``rows``, encoded (their rows among ``rows`` only); ``phase``
    (N,) the model's phase index of every row (default: the dataset's own)."""
    phase = ds.phase if phase is None else phase
    out = []
    for a, b in jump_bounds(ds.jump):
        r = np.flatnonzero(rows[a:b]) + a
        if r.size:
            out.append(Trajectory(ae.encode(ds.q[r]), ae.encode_derivative(ds.dq[r]),
                                  ae.encode_input(ds.u[r]), phase[r].astype(int)))
    return out


def learn_guards(ds: Dataset, rows: np.ndarray, val_rows: np.ndarray, ae: LinearAutoencoder) -> list[Guard]:
    """The contact guards (``symrom.model.guards``) of the phases of ``ds``, fitted by ``symrom.learn.guards``
    on the jumps of ``rows`` (N,) bool and chosen on those of ``val_rows``, in the latent coordinates of
    ``ae``."""
    idx = np.flatnonzero(rows | val_rows)
    Z = np.c_[ae.encode(ds.q[idx]), ae.encode_derivative(ds.dq[idx]), ae.encode_input(ds.u[idx])]
    bounds = jump_bounds(ds.jump[idx])
    is_train = rows[idx[bounds[:, 0]]]
    trained = [n for k, n in enumerate(ds.phase_names) if (rows & (ds.phase == k)).any()]
    return fit_guards(Z, np.asarray(ds.phase[idx], dtype=int), bounds[is_train], bounds[~is_train],
                      list(ds.phase_names), ds.dt, trained)


def _median_stay(ds: Dataset, rows: np.ndarray, k: int) -> float | None:
    """Median length (s) of the contiguous runs of phase k among ``rows``, within jumps."""
    lengths = []
    for a, b in jump_bounds(ds.jump):
        inside = (rows[a:b] & (ds.phase[a:b] == k)).astype(np.int8)
        edges = np.diff(np.r_[0, inside, 0])
        lengths += list(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))
    return float(np.median(lengths) * ds.dt) if lengths else None


@dataclass
class SymbolicROM:
    """The learner (module docstring). latent_dim: l; library: blocks (a ``LibrarySpec``
    or one block); encoder, regressor: plug-ins; decoded_weight: weight of the
    decoded-acceleration term ||ddq - W_d Theta Xi||^2 of the SINDy loss (1 = the
    paper); contact_phase: the phase that trains the encoder in step (a);
    path_thresholds: if set (and the regressor is ``STLSQ``), record each phase's
    sparsity path over these thresholds with its validation error; settings: the flat
    settings it was built from (``TrainConfig.estimator`` sets them: a ``TrainConfig``'s
    fields), recorded in the fitted model's provenance."""

    latent_dim: int = 2
    library: LibrarySpec | TermBlock = field(default_factory=LibrarySpec.standard)
    encoder: PCAEncoder | AdamAutoencoder | None = field(default_factory=PCAEncoder)
    regressor: Regressor | None = field(default_factory=STLSQ)
    decoded_weight: float = 1.0
    contact_phase: str = STANCE_PHASE
    path_thresholds: tuple[float, ...] | None = None
    settings: dict | None = field(default=None, repr=False)
    model_: HybridModel | None = field(default=None, init=False, repr=False)

    @classmethod
    def from_config(cls, config, progress: Progress | None = None) -> SymbolicROM:
        """The estimator a flat ``TrainConfig`` (``symrom.learn.training``, the command line's
        settings) describes, its settings recorded in the models it fits; ``progress`` is the
        gradient solver's."""
        return config.estimator(progress)

    def __post_init__(self) -> None:
        if isinstance(self.library, TermBlock):
            self.library = LibrarySpec((self.library,))
        if not 1 <= int(self.latent_dim) <= len(Q_NAMES):
            raise ValueError(f"latent_dim must be within 1..{len(Q_NAMES)}, got {self.latent_dim}")
        if not self.decoded_weight >= 0:
            raise ValueError(f"decoded_weight must be >= 0, got {self.decoded_weight}")

    # ------------------------------------------------------------------ fit
    def fit(self, ds: Dataset, rows: np.ndarray | None = None, progress: Progress | None = None) -> SymbolicROM:
        """Train on the ``train`` split of ``ds`` (or on boolean ``rows`` (N,)); sets ``model_``.

        A phase of ``ds`` without training rows is kept untrained (its equations are
        zero and rollouts through it are refused); ``model_.trained_phases()`` lists
        the others. The model's ``provenance`` records the data and the training.
        """
        if self.encoder is None or self.regressor is None:
            raise ValueError("this SymbolicROM was loaded from a model file that records no plug-ins (format 2 or "
                             "older): set its encoder and regressor to fit it again")
        say = progress or (lambda stage, frac: None)
        prepared = self._prepare(ds, rows, say, getattr(self.regressor, "needs_trajectories", False))
        self.model_ = self._finish(prepared, self.regressor, say)
        return self

    def fit_variants(self, ds: Dataset, regressors: list[Regressor],
                     rows: np.ndarray | None = None) -> list[HybridModel]:
        """One model per regressor, all on this estimator's encoder and library fitted once to
        the same rows (what a sparsity path or a selection grid needs); ``model_`` unchanged."""
        say = lambda stage, frac: None  # noqa: E731
        prepared = self._prepare(ds, rows, say, any(getattr(r, "needs_trajectories", False) for r in regressors))
        return [self._finish(prepared, r, say) for r in regressors]

    def _prepare(self, ds: Dataset, rows: np.ndarray | None, say: Progress, with_trajectories: bool) -> dict:
        """Steps (a) and (b), and the regression problem of step (c)."""
        rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
        if rows.shape != (ds.n_samples,):
            raise ValueError(f"rows: shape {rows.shape}, expected ({ds.n_samples},)")
        if not rows.any():
            raise ValueError("no training rows (the dataset has no 'train' jumps)")
        l = int(self.latent_dim)
        lib = self.library.bind(l)
        say("encoder (contact phase)", 0.0)
        cp = self.contact_phase
        has_contact = cp in ds.phase_names and bool((rows & (ds.phase == ds.phase_names.index(cp))).any())
        ae = self.encoder.fit(ds.q[contact_rows(ds, rows, cp)], ds.q[rows], l)
        say("dynamics", 0.5)
        ddxi_all = ae.encode_derivative(ds.ddq[rows])
        val_rows = ds.rows_of("val") & ~rows
        problem = RegressionProblem(
            lib, list(ds.phase_names), phase_data(ds, rows, ae, lib, self.decoded_weight),
            target_spread=np.maximum(ddxi_all.std(axis=0), 1e-12), dt=ds.dt,
            trajectories=trajectories(ds, rows, ae) if with_trajectories else [],
            validation=phase_data(ds, val_rows, ae, lib, self.decoded_weight) if val_rows.any() else None)
        xi, dxi, nu = ae.encode(ds.q[rows]), ae.encode_derivative(ds.dq[rows]), ae.encode_input(ds.u[rows])
        phases = []
        for k in range(len(ds.phase_names)):
            r = ds.phase[rows] == k
            phases.append((int(r.sum()), np.concatenate([xi[r].mean(0), dxi[r].mean(0), nu[r].mean(0)])
                           if r.any() else None, _median_stay(ds, rows, k)))
        data = DataRecord(robot=ds.robot, motion=ds.motion, source=ds.source, dt=ds.dt, q_names=tuple(Q_NAMES),
                          sha256=data_hash(ds), train_rows=int(rows.sum()),
                          train_jumps=int(np.unique(ds.jump[rows]).size),
                          envelope=freeze(jump_envelope(ds, np.unique(ds.jump[rows]))))
        training = TrainingRecord(settings=freeze(self.settings),
                                  encoder_rows=(f"the {self.contact_phase!r} phase" if has_contact
                                                else f"all training rows (they hold no {self.contact_phase!r} row)"),
                                  latent_mean=tuple(xi.mean(axis=0).tolist()),
                                  latent_spread=tuple(xi.std(axis=0).tolist()))
        say("contact guards", 0.8)
        guards = learn_guards(ds, rows, val_rows, ae)
        return {"ae": ae, "lib": lib, "problem": problem, "phases": phases, "data": data, "training": training,
                "guards": guards,
                "phase_names": list(ds.phase_names),
                "scale": np.maximum(np.concatenate([np.abs(xi).max(0), np.abs(dxi).max(0)]), 1e-9)}

    def _finish(self, prep: dict, regressor: Regressor, say: Progress) -> HybridModel:
        """Step (c) with ``regressor`` on a prepared problem: the fitted model."""
        if isinstance(regressor, Adam) and isinstance(self.encoder, AdamAutoencoder):
            # One torch stream for the whole run, as in the paper's training.
            regressor = replace(regressor, generator=self.encoder.generator_)
        problem = prep["problem"]
        coefs = regressor.fit(problem)
        paths = (regressor.path(problem, self.path_thresholds)
                 if self.path_thresholds and isinstance(regressor, STLSQ) else {})
        phase_info = {}
        for name, (n_rows, op, stay) in zip(prep["phase_names"], prep["phases"]):
            report = dict(coefs.report.get(name, {}))
            if name in paths:
                report["path"] = paths[name]
            phase_info[name] = PhaseInfo(trained=n_rows > 0, n_rows=n_rows, operating_point=op,
                                         duration_s=stay, report=report)
        training = replace(prep["training"], untrained_phases=tuple(n for n, p in phase_info.items() if not p.trained))
        say("done", 1.0)
        return HybridModel(prep["ae"], prep["lib"], list(prep["phase_names"]), coefs.Xi, coefs.mask,
                           prep["scale"].copy(), Provenance(prep["data"], training), phase_info,
                           self.to_dict(regressor),
                           [replace(g) for g in prep["guards"]])

    # ------------------------------------------------------------------ configuration
    def to_dict(self, regressor: Regressor | None = None) -> dict:
        """The settings beyond the model's latent_dim and library (which its file holds
        anyway), each plug-in as its ``{"kind": ...}`` record, JSON-ready: what a model
        file keeps as ``estimator``. ``regressor``: the one that fitted (default: this one's)."""
        return {"encoder": self.encoder.to_dict(), "regressor": (regressor or self.regressor).to_dict(),
                "decoded_weight": float(self.decoded_weight), "contact_phase": self.contact_phase,
                "path_thresholds": None if self.path_thresholds is None else list(self.path_thresholds)}

    # ------------------------------------------------------------------ use
    @property
    def model(self) -> HybridModel:
        if self.model_ is None:
            raise ValueError("this SymbolicROM is not fitted yet: call fit(ds) first")
        return self.model_

    def predict(self, ds: Dataset, rows: np.ndarray | None = None) -> np.ndarray:
        """Latent accelerations ddxi (N, l) the model predicts at the logged rows (all by default)."""
        m = self.model
        m.check_data(ds)
        rows = np.ones(ds.n_samples, bool) if rows is None else np.asarray(rows, dtype=bool)
        ae = m.autoencoder
        return m.latent_acceleration(ae.encode(ds.q[rows]), ae.encode_derivative(ds.dq[rows]),
                                     ae.encode_input(ds.u[rows]), m.phase_index(ds, rows))

    def simulate(self, ds: Dataset, jumps=None, reset: float | None = None, method: str = "rk4", options=None):
        """Roll the model out along logged ``jumps`` of ``ds`` (default: all), resetting to the
        logged state every ``reset`` s (None: the full jump), with ``method`` (``rk4`` or
        ``lsoda``) or every setting of ``options`` (a ``RolloutOptions``); a ``Rollout``
        (predicted q (n, 18) per jump, divergences)."""
        from symrom.rollout.integrate import RolloutOptions, rollout

        return rollout(self.model, ds, jumps, options or RolloutOptions(method=method, reset=reset))

    def equations(self, digits: int = 3):
        """The fitted model's equations (``symrom.model.expressions.Equations``): per phase its
        sympy right-hand sides; ``str()`` is their text, ``latex()`` their LaTeX."""
        return self.model.equations(digits)

    def predict_path(self, q0: np.ndarray, dq0: np.ndarray, inputs, dt: float, phases=None, **kwargs):
        """Free prediction from (q0, dq0) with one's own inputs: ``HybridModel.predict_path``."""
        return self.model.predict_path(q0, dq0, inputs, dt, phases=phases, **kwargs)

    def stability(self) -> list[PhaseStability]:
        return self.model.stability()

    # Rollable: a fitted estimator goes wherever its model goes (rollout, evaluate).
    @property
    def components(self) -> tuple[str, ...]:
        return tuple(self.model.components)

    def rollout_system(self, ds: Dataset, jumps):
        return self.model.rollout_system(ds, jumps)

    def save(self, path: str | os.PathLike) -> None:
        from symrom.model.persistence import save_model

        save_model(self.model, path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> SymbolicROM:
        """A fitted estimator from any model file (``symrom.model.persistence``: every format),
        with the exact plug-ins recorded there. ``ModelFileError`` naming the key when the file
        records plug-ins it cannot restore, or records one of them and not the other; a file
        older than the plug-in records (format 1 and 2 without them) gives an estimator whose
        plug-ins are None: its model is used as it is, and ``fit`` asks for them."""
        from symrom.model.persistence import ModelFileError, load_model

        model = load_model(path)
        est = model.estimator
        encoder = regressor = None
        if "encoder" in est or "regressor" in est:
            for key in ("encoder", "regressor"):
                if key not in est:
                    raise ModelFileError(f"{path}: estimator.{key}: not recorded (the file records the other "
                                         "plug-in only)")
            try:
                encoder = encoder_from_dict(est["encoder"], "estimator.encoder")
                regressor = regressor_from_dict(est["regressor"], "estimator.regressor")
            except PluginConfigError as e:
                raise ModelFileError(f"{path}: {e}") from None
        paths = est.get("path_thresholds")
        rom = cls(latent_dim=model.latent_dim, library=model.library.spec, encoder=encoder, regressor=regressor,
                  decoded_weight=float(est.get("decoded_weight", 1.0)),
                  contact_phase=str(est.get("contact_phase", "contact")),
                  path_thresholds=None if paths is None else tuple(float(t) for t in paths),
                  settings=thaw(model.provenance.training.settings))
        rom.model_ = model
        return rom
