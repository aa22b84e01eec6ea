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
from symrom.learn.encoders import AdamAutoencoder, PCAEncoder, check_invariant, reading_latents, translation_basis
from symrom.learn.guards import CLOCK, GuardFit, guard_fit, refit_guards
from symrom.learn.plugins import PluginConfigError, encoder_from_dict, regressor_from_dict
from symrom.learn.regressors.base import PhaseData, RegressionProblem, Regressor, Trajectory
from symrom.learn.regressors.stlsq import STLSQ
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.guards import Guard
from symrom.model.hybrid import HybridModel, PhaseInfo, PhaseStability
from symrom.model.library import LibrarySpec, TermBlock
from symrom.model.provenance import DataRecord, Provenance, TrainingRecord, freeze, thaw
from symrom.names import FLIGHT_PHASE, Q_NAMES, STANCE_PHASE

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


def logged_guard_fit(ds: Dataset, rows: np.ndarray, val_rows: np.ndarray, ae: LinearAutoencoder,
                     invariant: tuple[str, ...] = ()) -> GuardFit:
    """The contact guards (``symrom.model.guards``) of the phases of ``ds`` and their finalists
    (``symrom.learn.guards.GuardFit``), fitted on the logged states of the jumps of ``rows`` (N,)
    bool and chosen on those of ``val_rows``, in the latent coordinates of ``ae``; none reads a
    latent position that moves with the base components ``invariant``."""
    idx = np.flatnonzero(rows | val_rows)
    Z = np.c_[ae.encode(ds.q[idx]), ae.encode_derivative(ds.dq[idx]), ae.encode_input(ds.u[idx])]
    bounds = jump_bounds(ds.jump[idx])
    is_train = rows[idx[bounds[:, 0]]]
    trained = [n for k, n in enumerate(ds.phase_names) if (rows & (ds.phase == k)).any()]
    barred = np.r_[reading_latents(ae, invariant), np.zeros(2 * ae.latent_dim, dtype=bool)]
    return guard_fit(Z, np.asarray(ds.phase[idx], dtype=int), bounds[is_train], bounds[~is_train],
                     list(ds.phase_names), ds.dt, trained, barred=barred)


def invariant_terms(lib, ae: LinearAutoencoder, invariant: tuple[str, ...]) -> tuple[np.ndarray | None, str]:
    """(p,) bool of the terms of ``lib`` that read a latent position moving with the base
    components ``invariant`` under ``ae`` (None if none does), and the reason a report gives."""
    moving = reading_latents(ae, invariant)
    if not moving.any():
        return None, ""
    return lib.terms_reading(moving), f"reads where the robot stands ({', '.join(invariant)}): held invariant"


OWN_PATH = "the model's own rollouts"  # what refit guards' reports name as their source


def own_path_guards(model: HybridModel, ds: Dataset, rows: np.ndarray, val_rows: np.ndarray,
                    fit: GuardFit) -> list[Guard]:
    """The guards of ``fit`` levelled again on ``model``'s own rollouts (``symrom.learn.guards.refit_guards``):
    each jump of ``rows`` and ``val_rows`` (N,) bool rolled out from its first state with its logged inputs
    and phases (RK4, 2 substeps; a diverging jump up to its divergence); the first fit's guards if no
    path is left."""
    from symrom.rollout.integrate import RolloutOptions, rollout

    sel = rows | val_rows
    jumps = np.unique(ds.jump[sel])
    try:
        ro = rollout(model, ds, jumps, RolloutOptions(method="rk4", substeps=2))
        phase = model.phase_index(ds)
    except ValueError:  # rows in a phase the model has no equations for: nothing to roll out
        return [replace(g) for g in fit.guards]
    path = _path_rows(model, ds, jumps, rows, sel, ro.xi, ro.dxi, phase)
    if path is None:
        return [replace(g) for g in fit.guards]
    return refit_guards(fit, *path, list(model.phase_names), ds.dt, OWN_PATH)


def _path_rows(model: HybridModel, ds: Dataset, jumps: np.ndarray, rows: np.ndarray, sel: np.ndarray,
               xs: list[np.ndarray], vs: list[np.ndarray], labels: np.ndarray):
    """What ``refit_guards`` reads of a path of ``jumps``: Z (M, 3l) of the rows of ``sel`` (N,)
    bool on the path's states ``xs``, ``vs`` (per jump (n_j, l); a diverged jump up to its
    divergence) with the logged inputs, their phase ``labels`` (N,), and the train (the jumps
    of ``rows``) and val bounds; None if no training jump is left."""
    bounds = ds.jump_bounds()
    Z, ph, tb, vb, start = [], [], [], [], 0
    for j, X, V in zip(jumps, xs, vs):
        a, b = bounds[j]
        keep = np.flatnonzero(sel[a:b])
        keep = keep[keep < int(np.isfinite(X).all(axis=1).sum())]
        if keep.size < 2:
            continue
        Z.append(np.c_[X[keep], V[keep], model.autoencoder.encode_input(ds.u[a + keep])])
        ph.append(labels[a + keep])
        (tb if rows[a + keep[0]] else vb).append((start, start + keep.size))
        start += keep.size
    if not tb:
        return None
    return np.concatenate(Z), np.concatenate(ph), np.array(tb), np.array(vb, dtype=int).reshape(-1, 2)


FREE_PATH = "the model's free predictions"  # what guards levelled along free predictions name as their source


def free_path_guards(model: HybridModel, ds: Dataset, rows: np.ndarray, val_rows: np.ndarray,
                     fit: GuardFit) -> list[Guard]:
    """``model``'s guards levelled again along its free predictions, one transition of the
    motion's phase sequence at a time, in its order (``refit_guards`` on the new path).

    A free prediction (``symrom.evaluate.switching.predicted_rollout``: from each jump's first
    state, the logged inputs, the guards deciding the phases) reaches a switch through the
    switches before it; one early switch into the push's next phase changes the lift-off, and
    the touchdown with it. So each transition's guard is levelled on free predictions of the
    jumps of ``rows`` and ``val_rows`` (N,) bool made with the guards before it already
    levelled and none from it on (the prediction stays in the transition's source phase), its
    loss against the logged switch times. A guard stays as it was unless better on that path.
    Between two stance phases (a froggy's front feet lifting) the time in the source phase is a
    finalist too (``symrom.learn.guards.CLOCK``): the controller may switch on its clock; lift-off
    and touchdown are the state's.
    Only the logged stays at the transition's place in the sequence count (a pronk's landing
    stay is contact too, but no lift-off follows it in a prediction). The guards as they are
    without a phase sequence (the motion is not in the registry)."""
    from symrom.evaluate.switching import predicted_rollout
    from symrom.model.guards import advance, first_stage
    from symrom.rollout.integrate import RolloutOptions

    guards = [replace(g) for g in model.guards or ()]
    seq, names = model.phase_sequence(), list(model.phase_names)
    if not seq or not guards:
        return guards
    pairs = [(seq[i], seq[i + 1]) for i in range(len(seq) - 1)]
    key = lambda g: (names.index(g.source), names.index(g.target))  # noqa: E731
    sel = rows | val_rows
    jumps, bounds, logged = np.unique(ds.jump[sel]), ds.jump_bounds(), model.phase_index(ds)
    stage = np.full(logged.shape, -1)  # each row's place in the sequence along its logged jump
    for j in jumps:
        a, b = bounds[j]
        cuts = np.r_[a, a + 1 + np.flatnonzero(np.diff(logged[a:b])), b]
        st = first_stage(seq, int(logged[a]))
        for c, e in zip(cuts[:-1], cuts[1:]):
            if c > a and st >= 0:
                st = advance(seq, st, int(logged[c])) if int(logged[c]) in seq[st + 1:] else -1
            stage[c:e] = st
    for i, pair in enumerate(pairs):
        k = next((k for k, g in enumerate(guards) if key(g) == pair), None)
        if k is None or pair not in fit.finalists or pair in pairs[:i]:
            continue
        before = [g for g in guards if key(g) in pairs[:i]]
        ro, _ = predicted_rollout(replace(model, guards=before), ds, jumps, RolloutOptions(method="rk4", substeps=2))
        # the source phase at another place of the sequence is no stay of this transition
        labels = np.where((logged == pair[0]) & (stage != i), len(names), logged)
        path = _path_rows(model, ds, jumps, rows, sel, ro.xi, ro.dxi, labels)
        if path is not None:
            cands = fit.finalists[pair] + ([CLOCK] if FLIGHT_PHASE not in (names[pair[0]], names[pair[1]]) else [])
            guards[k] = refit_guards(GuardFit([guards[k]], {pair: cands}), *path, names, ds.dt, FREE_PATH)[0]
    return guards


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
    sparsity path over these thresholds with its validation error; contact_guards: fit the
    contact guards (False: the model has none, ``guards`` None; for uses that follow the logged
    phases only, as the latent-dimension sweep, where fitting them is most of a fit); invariant: base
    components (``x``, ``y``) along which the dynamics are held invariant (``()``: none, the paper):
    the latent basis gives each its own latent (``symrom.learn.encoders.translation_basis``) and no
    term or guard reads that latent's position, so where the robot stands acts as no clock or
    force; settings: the flat settings it was built from (``TrainConfig.estimator`` sets them: a ``TrainConfig``'s
    fields), recorded in the fitted model's provenance."""

    latent_dim: int = 2
    library: LibrarySpec | TermBlock = field(default_factory=LibrarySpec.standard)
    encoder: PCAEncoder | AdamAutoencoder | None = field(default_factory=PCAEncoder)
    regressor: Regressor | None = field(default_factory=STLSQ)
    decoded_weight: float = 1.0
    contact_phase: str = STANCE_PHASE
    path_thresholds: tuple[float, ...] | None = None
    contact_guards: bool = True
    invariant: tuple[str, ...] = ()
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
        self.invariant = check_invariant(self.invariant)

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
        self.model_ = self._finish(prepared, self.regressor, say, free=True)
        return self

    def fit_variants(self, ds: Dataset, regressors: list[Regressor], rows: np.ndarray | None = None,
                     libraries: list[LibrarySpec | TermBlock] | None = None) -> list[HybridModel]:
        """One model per regressor, all on this estimator's encoder and contact guards fitted once
        to the same rows (what a sparsity path or a selection grid needs), each with its library
        in ``libraries`` (default: this estimator's; one regression problem per distinct
        library); ``model_`` unchanged. Their guards are levelled on their own rollouts along
        the logged phases only (``fit`` then levels them along free predictions too:
        ``free_path_guards``)."""
        say = lambda stage, frac: None  # noqa: E731
        if libraries is not None and len(libraries) != len(regressors):
            raise ValueError(f"libraries: {len(libraries)} for {len(regressors)} regressors")
        specs = [self.library if b is None else b for b in (libraries or [None] * len(regressors))]
        specs = [LibrarySpec((b,)) if isinstance(b, TermBlock) else b for b in specs]
        prepared = self._prepare(ds, rows, say, any(getattr(r, "needs_trajectories", False) for r in regressors))
        return [self._finish(prepared, r, say, spec) for r, spec in zip(regressors, specs)]

    def _prepare(self, ds: Dataset, rows: np.ndarray | None, say: Progress, with_trajectories: bool) -> dict:
        """Steps (a) and (b) and the contact guards on the logged states; the regression problem
        of step (c) is made per library (``_problem``)."""
        rows = ds.rows_of("train") if rows is None else np.asarray(rows, dtype=bool)
        if rows.shape != (ds.n_samples,):
            raise ValueError(f"rows: shape {rows.shape}, expected ({ds.n_samples},)")
        if not rows.any():
            raise ValueError("no training rows (the dataset has no 'train' jumps)")
        l = int(self.latent_dim)
        say("encoder (contact phase)", 0.0)
        cp = self.contact_phase
        has_contact = cp in ds.phase_names and bool((rows & (ds.phase == ds.phase_names.index(cp))).any())
        ae = self.encoder.fit(ds.q[contact_rows(ds, rows, cp)], ds.q[rows], l)
        if self.invariant:
            ae = translation_basis(ae, self.invariant, ds.q[rows])
        val_rows = ds.rows_of("val") & ~rows
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
        say("contact guards", 0.3)
        guards = logged_guard_fit(ds, rows, val_rows, ae, self.invariant) if self.contact_guards else None
        return {"ds": ds, "rows": rows, "val_rows": val_rows, "ae": ae, "phases": phases, "data": data,
                "training": training, "guards": guards, "phase_names": list(ds.phase_names),
                "with_trajectories": with_trajectories, "problems": {},
                "scale": np.maximum(np.concatenate([np.abs(xi).max(0), np.abs(dxi).max(0)]), 1e-9)}

    def _problem(self, prep: dict, spec: LibrarySpec):
        """The bound library and the regression problem of step (c) with ``spec`` (made once per
        distinct library of a prepared fit)."""
        key = repr(spec)
        if key not in prep["problems"]:
            ds, rows, val_rows, ae = prep["ds"], prep["rows"], prep["val_rows"], prep["ae"]
            lib = spec.bind(ae.latent_dim)
            ddxi_all = ae.encode_derivative(ds.ddq[rows])
            barred, why = invariant_terms(lib, ae, self.invariant)
            prep["problems"][key] = lib, RegressionProblem(
                lib, list(ds.phase_names), phase_data(ds, rows, ae, lib, self.decoded_weight),
                target_spread=np.maximum(ddxi_all.std(axis=0), 1e-12), dt=ds.dt,
                trajectories=trajectories(ds, rows, ae) if prep["with_trajectories"] else [],
                validation=phase_data(ds, val_rows, ae, lib, self.decoded_weight) if val_rows.any() else None,
                excluded=barred, excluded_reason=why)
        return prep["problems"][key]

    def fit_pruned(self, ds: Dataset, rows: np.ndarray | None = None) -> tuple[HybridModel, HybridModel | None]:
        """Fit with this estimator's regressor, a refinement with a term budget (``Refine.max_terms``):
        the model, and the model the refinement had before it pruned (what the same refinement
        without the budget fits, bit for bit), None if it pruned nothing; ``model_`` unchanged."""
        say = lambda stage, frac: None  # noqa: E731
        prep = self._prepare(ds, rows, say, getattr(self.regressor, "needs_trajectories", False))
        lib, coefs, regressor = self._coefficients(prep, self.regressor, say, None)
        model = self._model(prep, lib, coefs, regressor, say, free=True)
        if coefs.unpruned is None:
            return model, None
        return model, self._model(prep, lib, coefs.unpruned, replace(regressor, max_terms=None, keep=(), polish=()),
                                  say, free=True)

    def _finish(self, prep: dict, regressor: Regressor, say: Progress,
                library: LibrarySpec | None = None, free: bool = False) -> HybridModel:
        """Step (c) with ``regressor`` (and ``library``, default this estimator's) on a prepared fit,
        then the guards levelled on the model's own rollouts (and, with ``free``, along its free
        predictions): the fitted model."""
        return self._model(prep, *self._coefficients(prep, regressor, say, library), say, free)

    def _coefficients(self, prep: dict, regressor: Regressor, say: Progress, library: LibrarySpec | None):
        """Step (c): the bound library, the coefficients and the regressor that fitted them."""
        if isinstance(regressor, Adam) and isinstance(self.encoder, AdamAutoencoder):
            # One random stream for the whole run, as in the paper's training.
            regressor = replace(regressor, generator=self.encoder.generator_)
        say("dynamics", 0.5)
        lib, problem = self._problem(prep, self.library if library is None else library)
        coefs = regressor.fit(problem)
        if self.path_thresholds and isinstance(regressor, STLSQ):
            paths = regressor.path(problem, self.path_thresholds)
            for name, path in paths.items():
                coefs.report.setdefault(name, {})["path"] = path
        return lib, coefs, regressor

    def _model(self, prep: dict, lib, coefs, regressor: Regressor, say: Progress, free: bool = False) -> HybridModel:
        """The fitted model of step (c)'s coefficients, its guards levelled on its own rollouts
        (and, with ``free``, along its free predictions: ``free_path_guards``)."""
        phase_info = {}
        for name, (n_rows, op, stay) in zip(prep["phase_names"], prep["phases"]):
            phase_info[name] = PhaseInfo(trained=n_rows > 0, n_rows=n_rows, operating_point=op,
                                         duration_s=stay, report=dict(coefs.report.get(name, {})))
        training = replace(prep["training"], untrained_phases=tuple(n for n, p in phase_info.items() if not p.trained))
        model = HybridModel(prep["ae"], lib, list(prep["phase_names"]), coefs.Xi, coefs.mask,
                            prep["scale"].copy(), Provenance(prep["data"], training), phase_info,
                            self.to_dict(regressor),
                            None if prep["guards"] is None else [replace(g) for g in prep["guards"].guards])
        if prep["guards"] is not None:
            say("contact guards on the model's own rollouts", 0.9)
            model = replace(model, guards=own_path_guards(model, prep["ds"], prep["rows"], prep["val_rows"],
                                                          prep["guards"]))
            if free and model.guards:
                say("contact guards along the model's free predictions", 0.95)
                model = replace(model, guards=free_path_guards(model, prep["ds"], prep["rows"], prep["val_rows"],
                                                               prep["guards"]))
        say("done", 1.0)
        return model

    # ------------------------------------------------------------------ configuration
    def to_dict(self, regressor: Regressor | None = None) -> dict:
        """The settings beyond the model's latent_dim and library (which its file holds
        anyway), each plug-in as its ``{"kind": ...}`` record, JSON-ready: what a model
        file keeps as ``estimator``. ``regressor``: the one that fitted (default: this one's)."""
        return {"encoder": self.encoder.to_dict(), "regressor": (regressor or self.regressor).to_dict(),
                "decoded_weight": float(self.decoded_weight), "contact_phase": self.contact_phase,
                "path_thresholds": None if self.path_thresholds is None else list(self.path_thresholds),
                **({"invariant": list(self.invariant)} if self.invariant else {})}

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
                  invariant=tuple(est.get("invariant", ())),
                  settings=thaw(model.provenance.training.settings))
        rom.model_ = model
        return rom
