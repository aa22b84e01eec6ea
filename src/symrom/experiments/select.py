"""Model selection on validation data: every setting chosen on train/val, never on test.

A grid of candidates is trained on the ``train`` split with the exact solver
and scored by rollouts of the ``val`` split at both horizons (the full jump
and 0.1 s resets). The grid spans

- the encoder: ``all`` 18 components (the paper), the ``base_pose`` (x ...
  yaw), the ``base_position`` (x, y, z), all components ``standardised`` by
  their spread, or ``pose+joints``: min(3, l - 1) latents from the base pose
  (a jump moves the body mostly in x, z and pitch) and the rest from the
  joints;
- the latent dimension;
- the library blocks (``poly1+trig+inputs`` is the paper's);
- the sparsity: thresholds of the ``explained`` measure, from dense to sparse
  (a term explaining less than 0.1 % ... 3 % of its latent acceleration's spread goes);
- the rollout-aware refinement, tried on ``refine_top`` candidates of the
  exact grid (it rolls the model out many times; an exact fit solves once): the best by
  score, those diverging at the full horizon ranked by their 0.1 s score; with
  a reference, first the sparsest that meet it with 0.1 s resets (the
  refinement is what may make them meet it over the full jump too). A
  candidate the checks below already refuse (physics, integrator) is not
  refined;
- nothing of where the robot stands forward: every candidate is held invariant to
  the base's x (``invariant``, ``SymbolicROM.invariant``): x gets a latent of its
  own, and no term or guard reads that latent's position;
- a term budget: ``max_terms`` (None: none), or else ``compact_terms`` (60 by
  default). A refinement whose candidate has more terms than the budget prunes
  it to the budget (``Refine.max_terms``: the coefficients least needed by the
  training rollouts go, a share at a time, and the rest are refined again). Under
  the hard budget it then refines the phases of ``polish`` the data has again,
  each alone (``Refine.polish``); under the soft one the pruning leaves those
  phases whole (``Refine.keep``: their refined coefficients held while the others
  are pruned, unless they alone fill the budget): pruned with the rest, the SIM
  A1's flight lost the touchdown its refinement predicted. The model before the
  pruning (the refinement without a budget, bit for bit) is a candidate too. When
  a usual pick has more terms than the budget, the cell (encoder, latent
  dimension, library) of the exact
  candidate with the best 0.1 s score is refined from ``refine_top`` more of its
  thresholds with at most ``PRUNE_REACH`` (3) times the budget's terms, the
  sparsest with at least the budget's terms first (an exact
  fit's own val score says little of what it becomes once pruned, and the fewer
  terms pruning removes, the less it costs). ``max_terms`` is a hard budget:
  only candidates within it compete in the rule below, unless none of them
  stands (then all do, and the selection says so in its notes), and every
  refinement is polished. ``compact_terms`` is a soft one: the pruned models
  compete with the rest, so the rule's preference for the sparsest takes the
  compact model whenever it is as accurate on val.

Each cell (encoder, latent dimension) is one task: its encoder and its contact
guards on the logged states are fitted once and shared by its libraries and
thresholds; each candidate's guards are then levelled on its own rollouts
(``symrom.learn.estimator``). The refinements are tasks too, run after the
cells on the same back end.

Score of a candidate: at each horizon, the mean over the components of the
validation RMSE divided by a yardstick; the score is the mean of the two
horizons. The yardstick is, by default, the component's spread (its standard
deviation over the validation rows, at least ``floor`` times the largest
spread among the components of the same unit, so a joint that never moves
does not dominate), over all 18 components. A candidate with any diverged
validation jump is rejected. Among the rest, the sparsest (fewest active
terms) whose score is within ``tolerance`` of the best is chosen; ties go to
the better score.

With a ``reference`` (per horizon, per component, an RMSE to reach: e.g. the
errors a paper publishes), the yardstick is the reference over its
components, and the rule is the one the reference asks for: the sparsest
candidate at or below the reference on every one of its components at both
horizons is chosen; if none is, the tolerance rule above applies to the mean
ratio. Components whose reference is below ``REFERENCE_FLOOR`` (a joint the
reference's robot held still) are left out of it.

A model is chosen to be acted on, so every candidate is also checked for use
(``symrom.evaluate.usability``), and the rule above runs over those that pass;
each refusal is in the candidate's row (``refused``: the check and why):

- ``physics``: its decoded base acceleration keeps the data's momentum balance
  (in flight within 5 % of the data's fall, in every phase within the noise)
  and does not read what cannot move the base (the robot's sideways position
  and speed; in flight, the base's speed), on the train and the val rows
  (``physics_check``). Never set aside.
- ``integrator``: the planner's RK4 step (``plan.problem.PlanConfig``: its
  longest stance over its force intervals and substeps; the data's median
  flight over the planner's rise and fall intervals and substeps; a partial
  phase as a stance) and the rollouts' (the data's sample period over
  ``substeps``) carry every mode of every phase (``integrator_check``).
- ``free``: rolled out free from each val jump's first state with its own
  guards and the logged inputs (``evaluate.switching.predicted_rollout``), it
  does not diverge, it takes every logged transition once (none missed, none
  extra) and its median switching error is within ``switch_tolerance`` for
  every transition.

If no candidate passes them all, the ``free`` check and then the
``integrator`` check are set aside, in that order (the notes say so); a
candidate refused on physics is never chosen.

Every candidate and its numbers are kept in the selection table
(``selection.json``, ``SELECTION_VERSION``). The fitting of a cell reads only
the training rows and the validation jumps: replacing every value of the test
split by NaN changes nothing.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from symrom.atomic import atomic_dir, check_output_file, write_text_atomic
from symrom.compiled import start_windows_helper
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.evaluate.switching import predicted_rollout, switching_errors
from symrom.evaluate.usability import integrator_check, physics_check
from symrom.execution import HELPER_TIMEOUT, Backend, LocalBackend, wait_helper
from symrom.experiments import SELECT_WORKER_MODULES
from symrom.experiments.grid import Store, run_grid
from symrom.learn.encoders import check_invariant, unit_floored
from symrom.learn.training import TrainConfig, data_hash, train
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import model_from_dict, model_to_dict, write_model_files
from symrom.model.provenance import SelectionRecord
from symrom.names import BASE_NAMES, FLIGHT_PHASE, PARTIAL_PHASE, Q_NAMES, STANCE_PHASE
from symrom.rollout.integrate import RolloutOptions

SELECTION_VERSION = 3
CELL_VERSION = 4  # since 3 a cell's rows hold the physics check's moves (usability.MOVES); 4: invariant
# 2: a switch between two stance phases may be a clock (symrom.learn.guards.CLOCK); 3: the soft
# budget's pruning keeps the polished phases whole (Refine.keep)
REFINED_VERSION = 3
# The settings the rows of a cell depend on (besides the data, the integrator steps and the cell itself).
CELL_SETTINGS = ("libraries", "thresholds", "floor", "measure", "collinearity", "alpha", "decoded_weight",
                 "contact_phase", "substeps", "reference", "switch_tolerance", "checks", "invariant")
# ... and those of a refinement, besides its candidate's settings.
REFINED_SETTINGS = CELL_SETTINGS[1:] + ("max_terms", "compact_terms", "polish", "acceleration_weight")
BASE_SHARE = 3  # latents pose+joints gives the base pose at most (x, z and pitch of a jump)
# The soft term budget of the default selection: equations one can read, as the paper's (17 terms
# on Go1); a model pruned to it is chosen when it is as accurate on val (under a hard budget of 60,
# SIM A1 meets Table 2 as without one: docs/results.md).
COMPACT_TERMS = 60
SWITCH_TOLERANCE = 0.02  # s: a free prediction's median switching error per transition, at most
# The budget's extra refinements (``to_refine``) take the best cell's candidates with at most this
# many times the budget's terms: pruned further (3.5-5x: 35-50 terms to 10 on 40 Go1 MuJoCo and A1
# froggy jumps) they broke the momentum balance or lost on val, at twice the selection's time.
PRUNE_REACH = 3
CHECKS = ("physics", "integrator", "free")  # what a refusal names; the last two are set aside in reverse order
# Every candidate's dynamics are invariant to where the robot stands forward: the data's jumps all
# start at x = 0, so a law free to read x can use it as the push's clock, right on the data and wrong
# wherever a plan starts a phase elsewhere (docs/results.md).
INVARIANT = ("x",)
FREE = "free"  # the row's horizon key of the free prediction


@dataclass(frozen=True)
class EncoderChoice:
    """An encoder of the grid: its ``TrainConfig`` fields for latent dimension l, and the
    dimensions it can span."""

    settings: Callable[[int], dict[str, Any]]
    min_dim: int = 1
    max_dim: int = len(Q_NAMES)


ENCODERS: dict[str, EncoderChoice] = {
    "all": EncoderChoice(lambda l: {}),
    "base_pose": EncoderChoice(lambda l: {"encoder_components": BASE_NAMES}, max_dim=len(BASE_NAMES)),
    "base_position": EncoderChoice(lambda l: {"encoder_components": ("x", "y", "z")}, max_dim=3),
    "standardised": EncoderChoice(lambda l: {"encoder_scaling": "spread"}),
    "pose+joints": EncoderChoice(lambda l: {"encoder_base_latents": min(BASE_SHARE, l - 1)}, min_dim=2),
}
HORIZONS: tuple[float | None, ...] = (None, 0.1)
REFERENCE_FLOOR = 1e-6  # a reference RMSE below this marks a component the reference held still

SelectProgress = Callable[[int, int, str], None]  # (tasks done, tasks in total, what finished)


def parse_library(text: str) -> dict[str, Any]:
    """``poly1+trig+inputs`` -> TrainConfig fields (poly_order, trig, inputs)."""
    parts = [p.strip() for p in str(text).split("+") if p.strip()]
    out = {"poly_order": 0, "trig": False, "inputs": False}
    for p in parts:
        if p.startswith("poly") and p[4:].isdigit():
            out["poly_order"] = int(p[4:])
        elif p in ("trig", "inputs"):
            out[p] = True
        else:
            raise ValueError(f"library {text!r}: unknown block {p!r}; use poly<p>, trig and inputs, "
                             f"joined by + (e.g. poly1+trig+inputs)")
    if not any(p.startswith("poly") for p in parts):
        raise ValueError(f"library {text!r}: needs a poly<p> block (the constant)")
    return out


def library_name(poly_order: int, trig: bool, inputs: bool) -> str:
    """TrainConfig's library fields -> ``poly1+trig+inputs`` (the inverse of ``parse_library``)."""
    return f"poly{poly_order}" + ("+trig" if trig else "") + ("+inputs" if inputs else "")


def encoder_name(config: TrainConfig) -> str:
    """The grid's name (``ENCODERS``) of the encoder ``config`` describes; ValueError if none."""
    fields = ("encoder_components", "encoder_scaling", "encoder_base_latents")
    for name, choice in ENCODERS.items():
        grid = replace(TrainConfig(latent_dim=config.latent_dim), **choice.settings(config.latent_dim))
        if all(getattr(grid, f) == getattr(config, f) for f in fields):
            return name
    raise ValueError(f"the encoder settings {[getattr(config, f) for f in fields]} are none of the grid's")


@dataclass
class SelectionConfig:
    """The grid and the rules (module docstring). The fixed settings of every
    candidate: ``measure`` of the thresholds, ``collinearity`` of the audit,
    ``alpha`` ridge, ``decoded_weight`` of the SINDy loss (0: the latent
    accelerations alone; the decoded term asks the latent model to explain
    swing-leg accelerations the latent state does not hold). ``max_terms``: the
    hard term budget (None: none); ``compact_terms``: the soft one, used without
    ``max_terms`` (None: none); ``switch_tolerance``: s, the largest median
    switching error of a free prediction; ``acceleration_weight``: the refinements'
    (``Refine.acceleration_weight``: the acceleration fit kept beside the rollouts); ``checks``:
    those of ``CHECKS`` that refuse a candidate (each row holds every check's numbers whatever
    they are; fewer only for data too small to judge a model by, as the tests' three-jump files);
    ``invariant``: the base components every candidate's dynamics are held invariant to
    (``TrainConfig.invariant``)."""

    encoders: tuple[str, ...] = tuple(ENCODERS)
    latent_dims: tuple[int, ...] = (2, 3, 4)
    libraries: tuple[str, ...] = ("poly1+trig+inputs", "poly1+inputs")
    thresholds: tuple[float, ...] = (1e-3, 3e-3, 1e-2, 3e-2)
    refine_top: int = 2
    tolerance: float = 0.05
    floor: float = 0.05
    measure: str = "explained"
    collinearity: float = 0.995
    alpha: float = 1e-6
    decoded_weight: float = 0.0
    contact_phase: str = STANCE_PHASE
    workers: int = 1
    substeps: int = 2
    reference: dict[str, dict[str, float]] | None = None
    max_terms: int | None = None
    compact_terms: int | None = COMPACT_TERMS
    polish: tuple[str, ...] = (FLIGHT_PHASE,)
    switch_tolerance: float = SWITCH_TOLERANCE
    acceleration_weight: float = 1.0
    checks: tuple[str, ...] = CHECKS
    invariant: tuple[str, ...] = INVARIANT

    def __post_init__(self) -> None:
        bad = [e for e in self.encoders if e not in ENCODERS]
        if bad:
            raise ValueError(f"unknown encoder choice(s) {bad}; choose from {list(ENCODERS)}")
        for lib in self.libraries:
            parse_library(lib)
        if not self.latent_dims or any(not 1 <= d <= len(Q_NAMES) for d in self.latent_dims):
            raise ValueError(f"latent dimensions must lie within 1..{len(Q_NAMES)}, got {self.latent_dims}")
        if not self.thresholds or any(not t >= 0 for t in self.thresholds):
            raise ValueError(f"thresholds must be >= 0, got {self.thresholds}")
        if not self.tolerance >= 0:
            raise ValueError(f"tolerance must be >= 0, got {self.tolerance}")
        if self.workers < 1:
            raise ValueError(f"workers={self.workers}: the number of workers must be at least 1")
        if self.refine_top < 0:
            raise ValueError(f"refine_top must be >= 0, got {self.refine_top}")
        for key in ("max_terms", "compact_terms"):
            if getattr(self, key) is not None and getattr(self, key) < 1:
                raise ValueError(f"{key}={getattr(self, key)}: must be a positive number of terms")
        bad = [c for c in self.checks if c not in CHECKS]
        if bad:
            raise ValueError(f"checks: unknown {bad}; choose from {list(CHECKS)}")
        self.checks = tuple(self.checks)
        self.invariant = check_invariant(self.invariant)
        if any(l <= len(self.invariant) for l in self.latent_dims):
            raise ValueError(f"latent dimensions {self.latent_dims}: each must exceed the {len(self.invariant)} "
                             f"component(s) held invariant (invariant={','.join(self.invariant)!r}), which take a "
                             "latent each")
        if not self.acceleration_weight >= 0:
            raise ValueError(f"acceleration_weight must be >= 0, got {self.acceleration_weight}")
        if not self.switch_tolerance > 0:
            raise ValueError(f"switch_tolerance must be > 0 s, got {self.switch_tolerance}")
        if self.reference is not None:
            keys = {"full", "0.1"}
            if set(self.reference) != keys:
                raise ValueError(f"reference: needs exactly the horizons {sorted(keys)}, got {sorted(self.reference)}")
            for h, comps in self.reference.items():
                bad = [c for c in comps if c not in Q_NAMES]
                if bad:
                    raise ValueError(f"reference.{h}: unknown component(s) {bad}")

    @property
    def budget(self) -> int | None:
        """The term budget of the refinements: ``max_terms``, else ``compact_terms``."""
        return self.max_terms if self.max_terms is not None else self.compact_terms

    def yardstick(self, ds: Dataset) -> dict[str, dict[str, float]]:
        """Per horizon key (and the free prediction's), per scored component, the RMSE that
        counts as 1."""
        if self.reference is not None:
            out = {h: {c: float(v) for c, v in comps.items() if v >= REFERENCE_FLOOR}
                   for h, comps in self.reference.items()}
            return {**out, FREE: out["full"]}
        spread = dict(zip(Q_NAMES, component_spread(ds, self.floor).tolist()))
        return {"full": spread, "0.1": spread, FREE: spread}

    def cells(self) -> list[tuple[str, int]]:
        """(encoder, latent dim) of every cell, skipping encoders too narrow for l."""
        out = []
        for enc in self.encoders:
            choice = ENCODERS[enc]
            out += [(enc, l) for l in self.latent_dims if choice.min_dim <= l <= choice.max_dim]
        return out

    def candidates(self) -> int:
        """The exact candidates of the grid: cells x libraries x thresholds."""
        return len(self.cells()) * len(self.libraries) * len(self.thresholds)

    def train_config(self, encoder: str, latent_dim: int, library: str, threshold: float,
                     refine: bool = False, max_terms: int | None = None) -> TrainConfig:
        """The settings of one candidate; a refinement prunes to ``max_terms`` (None: no pruning):
        with the hard budget (``SelectionConfig.max_terms``) every refinement prunes to it, then
        polishes ``polish``; under the soft one the pruning keeps ``polish`` whole."""
        hard = self.max_terms is not None
        if refine and hard:
            max_terms = self.max_terms
        pruned = refine and max_terms is not None
        return TrainConfig(latent_dim=latent_dim, **parse_library(library), threshold=threshold,
                           measure=self.measure, collinearity=self.collinearity, alpha=self.alpha,
                           decoded_weight=self.decoded_weight, **ENCODERS[encoder].settings(latent_dim),
                           contact_phase=self.contact_phase, refine=refine, invariant=self.invariant,
                           max_terms=max_terms if refine else None,
                           keep=self.polish if pruned and not hard else (),
                           polish=self.polish if pruned and hard else ())


def component_spread(ds: Dataset, floor: float) -> np.ndarray:
    """(18,) standard deviation of each component over the val rows, floored at ``floor``
    times the largest among the components of the same unit."""
    return unit_floored(ds.q[ds.rows_of("val")].std(axis=0), floor)


def _ratios(rmse: dict | None, diverged: int, yardstick: dict[str, float]) -> dict[str, Any]:
    ratio = (np.array([rmse[c] / v for c, v in yardstick.items()]) if rmse is not None and not diverged else None)
    return {"score": None if ratio is None else float(ratio.mean()),
            "worst": None if ratio is None else float(ratio.max()), "diverged_jumps": diverged, "rmse": rmse}


def score_model(model: HybridModel, ds: Dataset, yardstick: dict[str, dict[str, float]],
                substeps: int) -> dict[str, Any]:
    """Validation rollouts at both horizons. Per horizon: ``score`` (mean of RMSE / yardstick
    over the yardstick's components), ``worst`` (their largest ratio), the diverged jumps
    and the RMSE of every component (ratios None if any jump diverged); ``score``, the
    mean over horizons (None if any diverged)."""
    metrics, _ = evaluate_model(model, ds, "val", HORIZONS,
                                RolloutOptions("rk4", substeps=substeps, backend=ROLLOUT_BACKEND))
    out: dict[str, Any] = {"horizons": {}}
    scores = []
    for key, h in metrics.horizons.items():
        rmse = {n: h.components[n].rmse for n in Q_NAMES} if h.components else None
        out["horizons"][key] = _ratios(rmse, h.diverged_jumps, yardstick[key])
        scores.append(out["horizons"][key]["score"])
    out["score"] = None if any(s is None for s in scores) else float(np.mean(scores))
    return out


# The selection's rollouts run on the term-table kernel: it compiles once (cached on disk), where
# ``auto`` may compile each candidate's own code, which does not pay in one val rollout.
ROLLOUT_BACKEND = "table"


def free_prediction(model: HybridModel, ds: Dataset, yardstick: dict[str, float], substeps: int,
                    switch_tolerance: float) -> dict[str, Any]:
    """The model rolled out free from each val jump's first state with its own guards and the
    logged inputs: ``score``, ``worst``, ``diverged_jumps``, ``rmse`` as a horizon of
    ``score_model``; ``switching``: per transition the logged, matched, missed and extra
    switches and the median |error| (s); ``follows``: whether it follows the motion (no
    diverged jump, every transition matched once, medians within ``switch_tolerance``)."""
    jumps = ds.jumps_in("val")
    if model.guards is None:
        return {"score": None, "worst": None, "diverged_jumps": None, "rmse": None, "switching": {},
                "follows": False}
    options = RolloutOptions("rk4", substeps=substeps, backend=ROLLOUT_BACKEND)
    ro, phases = predicted_rollout(model, ds, jumps, options)
    sw = switching_errors(model, ds, jumps, phases, ro.diverged_at)
    rows = np.concatenate([np.arange(a, b) for a, b in ds.jump_bounds()[jumps]])
    q_pred = np.concatenate(ro.q_pred)
    n_div = int(ro.diverged.sum())
    rmse = None
    if not n_div:
        err = q_pred - ds.q[rows]
        rmse = {n: float(np.sqrt(np.mean(err[:, i] ** 2))) for i, n in enumerate(Q_NAMES)}
    out = _ratios(rmse, n_div, yardstick)
    out["switching"] = {k: {f: r[f] for f in ("logged", "matched", "missed", "extra", "median_abs_s")}
                        for k, r in sw.items()}
    out["follows"] = bool(not n_div and all(
        not r["missed"] and not r["extra"] and (r["median_abs_s"] is None or r["median_abs_s"] <= switch_tolerance)
        for r in sw.values()))
    return out


def plan_steps(ds: Dataset, substeps: int) -> dict[str, dict[str, float]]:
    """Per phase of ``ds``, the RK4 steps (s) its model must carry: the planner's (``PlanConfig``:
    the longest stance over its force intervals and substeps for a stance or partial phase; the
    median training flight, split into rise and fall, over the flight intervals and substeps)
    and the rollouts' (the sample period over ``substeps``)."""
    from symrom.learn.estimator import _median_stay
    from symrom.plan.config import PlanConfig  # no CasADi: the base install selects too

    pc = PlanConfig()
    out = {}
    for k, name in enumerate(ds.phase_names):
        if name == FLIGHT_PHASE:
            stay = _median_stay(ds, ds.rows_of("train"), k)
            h = None if stay is None else stay / 2 / (pc.flight_intervals * pc.substeps)
        elif name in (STANCE_PHASE, PARTIAL_PHASE):
            h = pc.stance_max / (pc.knots * pc.substeps)
        else:
            h = None
        out[name] = {**({"planner": round(h, 9)} if h is not None else {}), "rollout": ds.dt / substeps}
    return out


def assess(model: HybridModel, ds: Dataset, cfg: SelectionConfig, yardstick: dict, steps: dict) -> dict[str, Any]:
    """Everything the selection's table holds of a candidate besides its settings: the val
    scores (``score_model``), its free prediction (``free_prediction``), the checks for use
    and the refusals (module docstring)."""
    out = score_model(model, ds, yardstick, cfg.substeps)
    out[FREE] = free_prediction(model, ds, yardstick[FREE], cfg.substeps, cfg.switch_tolerance)
    rows = ds.rows_of("train") | ds.rows_of("val")
    steps_checked = integrator_check(model, ds, rows, steps)
    phys = physics_check(model, ds)
    flight = {a.split: {"data": a.data, "model": a.model} for a in phys if a.kind == "flight"}
    out["integrator"] = [c.to_dict() for c in steps_checked]
    out["physics"] = {"checks": len(phys), "flight_z": flight, "failed": [a.to_dict() for a in phys if not a.ok]}
    refused = [{"check": "physics", "reason": a.text()} for a in phys if not a.ok]
    refused += [{"check": "integrator", "reason": c.text()} for c in steps_checked if not c.carried]
    if not out[FREE]["follows"]:
        refused.append({"check": "free", "reason": _free_reason(out[FREE], cfg.switch_tolerance)})
    out["refused"] = [r for r in refused if r["check"] in cfg.checks]
    return out


def _free_reason(free: dict, tolerance: float) -> str:
    if free["diverged_jumps"] is None:
        return "the model has no guards to predict its phases"
    if free["diverged_jumps"]:
        return f"its free prediction diverged on {free['diverged_jumps']} val jump(s)"
    bad = []
    for key, r in free["switching"].items():
        if r["missed"] or r["extra"]:
            bad.append(f"{key}: {r['matched']} of {r['logged']} logged switches matched, {r['extra']} extra")
        elif r["median_abs_s"] is not None and r["median_abs_s"] > tolerance:
            bad.append(f"{key}: median switching error {1e3 * r['median_abs_s']:.0f} ms")
    return "its free prediction does not follow the motion (" + "; ".join(bad) + ")"


def meets(row: dict, horizons: tuple[str, ...] = ("full", "0.1")) -> bool:
    """Whether the row is at or below the yardstick on every component at ``horizons``."""
    return all(row["horizons"][h]["worst"] is not None and row["horizons"][h]["worst"] <= 1.0 for h in horizons)


def _row(cfg: SelectionConfig, encoder: str, l: int, library: str, threshold: float, model: HybridModel,
         assessed: dict, seconds: float) -> dict[str, Any]:
    reg = model.estimator.get("regressor", {})
    refine = reg.get("kind") == "refine"
    budget = ({"max_terms": reg["max_terms"], **{k: list(reg[k]) for k in ("keep", "polish") if reg.get(k)}}
              if refine and reg.get("max_terms") is not None else {})
    return {"encoder": encoder, "latent_dim": l, "library": library, "threshold": threshold, "refine": refine,
            **budget, "active_terms": int(model.mask.sum()), "active_per_phase": model.active_terms(),
            "fast_unstable_phases": [s.phase for s in model.stability() if s.fast_unstable],
            "seconds": round(seconds, 3), **assessed}


def run_cell(ds: Dataset, cfg: SelectionConfig, steps: dict, encoder: str, l: int) -> list[dict[str, Any]]:
    """Train and assess every library and threshold of one (encoder, latent dim) cell: one
    encoder and its logged-state guards, one regression problem per library, one regressor
    per threshold."""
    yardstick = cfg.yardstick(ds)
    t0 = time.perf_counter()
    configs = [cfg.train_config(encoder, l, lib, t) for lib in cfg.libraries for t in cfg.thresholds]
    models = configs[0].estimator().fit_variants(
        ds, [c.regressor() for c in configs], libraries=[c.estimator().library for c in configs])
    share = (time.perf_counter() - t0) / len(models)  # the shared fit, split between the candidates
    rows = []
    for c, model in zip(configs, models):
        model = replace(model, provenance=model.provenance.with_settings(asdict(c)))
        t1 = time.perf_counter()
        assessed = assess(model, ds, cfg, yardstick, steps)
        rows.append(_row(cfg, encoder, l, library_name(c.poly_order, c.trig, c.inputs), c.threshold, model,
                         assessed, share + time.perf_counter() - t1))
    return rows


def cell_key(cfg: SelectionConfig, data_sha256: str, cell: tuple[str, int], steps: dict | None = None) -> str:
    """Hash of everything the rows of ``cell`` depend on (not the rest of the grid, the
    workers, the refinement or the rule), to match stored cells on a resumed run."""
    settings = asdict(cfg)
    spec = {"version": CELL_VERSION, "data": data_sha256, "cell": list(cell), "steps": steps,
            **{k: settings[k] for k in CELL_SETTINGS}}
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


def cell_path(folder: str | Path, cell: tuple[str, int]) -> Path:
    """The file of ``cell`` in a folder of finished cells: ``base_pose_l02.json``."""
    encoder, l = cell
    return Path(folder) / f"{encoder}_l{l:02d}.json"


Pick = tuple[str, int, str, float, bool]  # (encoder, latent dim, library, threshold, prune) of a refinement


def refined_key(cfg: SelectionConfig, data_sha256: str, pick: Pick, steps: dict | None = None) -> str:
    """Hash of everything the refinement of ``pick`` depends on, to match stored refinements."""
    settings = asdict(cfg)
    spec = {"version": REFINED_VERSION, "cell_version": CELL_VERSION, "data": data_sha256, "pick": list(pick),
            "steps": steps, **{k: settings[k] for k in REFINED_SETTINGS}}
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


def refined_path(folder: str | Path, pick: Pick) -> Path:
    """The file of a finished refinement: ``refined/base_pose_l02_poly1+inputs_t0.003.json``."""
    encoder, l, library, threshold, prune = pick
    return Path(folder) / "refined" / f"{encoder}_l{l:02d}_{library}_t{threshold:g}{'_pruned' if prune else ''}.json"


def run_refinement(ds: Dataset, cfg: SelectionConfig, steps: dict, encoder: str, l: int, library: str,
                   threshold: float, prune: bool) -> list[dict[str, Any]]:
    """The refined versions of one exact candidate, assessed, each row with its model (``model``:
    a model file's dict): the refinement; with ``prune``, the refinement pruned to the budget
    and polished (``SelectionConfig.train_config``), and, if it pruned, the refinement before
    the pruning (the refinement without a budget, bit for bit)."""
    t0 = time.perf_counter()
    tc = cfg.train_config(encoder, l, library, threshold, refine=True, max_terms=cfg.budget if prune else None)
    est = tc.estimator()
    est.regressor = replace(est.regressor, acceleration_weight=cfg.acceleration_weight)
    model, unpruned = est.fit_pruned(ds)
    seconds = time.perf_counter() - t0
    yardstick = cfg.yardstick(ds)
    out = []
    for m in (model, unpruned):
        if m is None:
            continue
        reg = m.estimator["regressor"]
        settings = replace(tc, max_terms=reg.get("max_terms"), keep=tuple(reg.get("keep", ())),
                           polish=tuple(reg.get("polish", ())))
        m = replace(m, provenance=m.provenance.with_settings(asdict(settings)))
        t1 = time.perf_counter()
        assessed = assess(m, ds, cfg, yardstick, steps)
        out.append({**_row(cfg, encoder, l, library, threshold, m, assessed, seconds + time.perf_counter() - t1),
                    "model": model_to_dict(m)})
    return out


def _standing(rows: list[dict], set_aside: tuple[str, ...] = ()) -> list[int]:
    """Indices of the rows with a val score and no refusal but for the checks ``set_aside``."""
    return [i for i, r in enumerate(rows) if r["score"] is not None
            and all(x["check"] in set_aside for x in r.get("refused", ()))]


def choose(rows: list[dict], tolerance: float, reference: bool = False,
           max_terms: int | None = None) -> int | None:
    """Index of the chosen row among those standing (a val score and no refusal; if none does,
    with the ``free`` check and then the ``integrator`` check set aside, never ``physics``):
    with a ``reference``, the sparsest that meets it at both horizons if any; else the sparsest
    with a score within ``tolerance`` of the best. With ``max_terms``, only the rows within
    that many active terms compete, unless none of them stands (then all rows do)."""
    ok = next((idx for idx in (_standing(rows, aside) for aside in set_asides()) if idx), [])
    if not ok:
        return None
    within = [i for i in ok if max_terms is None or rows[i]["active_terms"] <= max_terms]
    ok = within or ok
    sparsest = lambda idx: min(idx, key=lambda i: (rows[i]["active_terms"], rows[i]["score"]))  # noqa: E731
    meeting = [i for i in ok if meets(rows[i])] if reference else []
    if meeting:
        return sparsest(meeting)
    best = min(rows[i]["score"] for i in ok)
    return sparsest([i for i in ok if rows[i]["score"] <= (1 + tolerance) * best])


def set_asides() -> list[tuple[str, ...]]:
    """The checks a choice sets aside, in turn, when no candidate passes the rest: none, then
    ``free``, then ``free`` and ``integrator`` (``physics`` never)."""
    return [(), ("free",), ("free", "integrator")]


def set_aside_for(rows: list[dict]) -> tuple[str, ...]:
    """The checks ``choose`` had to set aside on ``rows`` (() if a candidate passed them all)."""
    return next((aside for aside in set_asides() if _standing(rows, aside)), ())


def _refinable(r: dict) -> bool:
    """Whether a row may be refined: not refused by a check a refinement does not change."""
    return not any(x["check"] in ("physics", "integrator") for x in r.get("refused", ()))


def to_refine(rows: list[dict], k: int, reference: bool = False, max_terms: int | None = None) -> list[int]:
    """Indices of the exact candidates to refine (module docstring): ``k`` of them, and
    when one of those has more than ``max_terms`` terms (the budget), up to ``k`` more from
    the best cell at 0.1 s, none with more than ``PRUNE_REACH`` times the budget's terms.
    Candidates refused on physics or by the integrator are not refined."""
    short = [i for i, r in enumerate(rows) if r["horizons"]["0.1"]["score"] is not None and _refinable(r)]
    picked = []
    if reference:  # the sparsest that meet the reference with 0.1 s resets
        picked = sorted((i for i in short if meets(rows[i], ("0.1",))),
                        key=lambda i: (rows[i]["active_terms"], rows[i]["horizons"]["0.1"]["score"]))[:k]
    rest = sorted((i for i in short if i not in picked),
                  key=lambda i: (rows[i]["score"] is None, rows[i]["score"] if rows[i]["score"] is not None
                                 else rows[i]["horizons"]["0.1"]["score"]))
    picked += rest[:k - len(picked)]
    if max_terms is None or not short or all(rows[i]["active_terms"] <= max_terms for i in picked):
        return picked
    cell = lambda r: (r["encoder"], r["latent_dim"], r["library"])  # noqa: E731
    best = cell(rows[min(short, key=lambda i: rows[i]["horizons"]["0.1"]["score"])])
    members = [i for i, r in enumerate(rows) if cell(r) == best and _refinable(r)
               and r["active_terms"] <= PRUNE_REACH * max_terms]
    members.sort(key=lambda i: (rows[i]["active_terms"] < max_terms,
                                abs(rows[i]["active_terms"] - max_terms)))
    return picked + [i for i in members if i not in picked][:k]


def selection_rule(cfg: SelectionConfig) -> str:
    """The score and the choice of ``choose`` under ``cfg``, in words."""
    tol = f"the sparsest within {cfg.tolerance:.0%} of the best score"
    budget = ""
    if cfg.max_terms is not None:
        budget = (f"; refinements pruned to at most {cfg.max_terms} active terms"
                  + (f", then {', '.join(cfg.polish)} refined again alone" if cfg.polish else "")
                  + f", and only candidates within {cfg.max_terms} terms compete (all if none stands)")
    elif cfg.compact_terms is not None:
        budget = (f"; refinements of candidates with more than {cfg.compact_terms} terms also pruned to "
                  f"{cfg.compact_terms}"
                  + (f" ({', '.join(cfg.polish)} kept whole)" if cfg.polish else "")
                  + ", the pruned models competing with the rest")
    checks = ("; a candidate must keep the data's momentum balance (physics: never set aside), have every mode "
              "carried by the planner's and the rollouts' RK4 steps (integrator) and, rolled out free from each "
              "val jump's first state, follow the motion (free: no divergence, every transition once, median "
              f"switching error within {1e3 * cfg.switch_tolerance:.0f} ms); if none passes, free and then "
              "integrator are set aside")
    if tuple(cfg.checks) != CHECKS:
        checks += (f" (only {', '.join(cfg.checks)} refusing here)" if cfg.checks else
                   " (none refusing here: each row holds their numbers)")
    if cfg.reference is None:
        return ("score = mean over horizons (full, 0.1 s) of mean_c val RMSE_c / spread_c; candidates with "
                f"a diverged val jump rejected; {tol} chosen" + budget + checks)
    return ("score = mean over horizons (full, 0.1 s) of mean_c val RMSE_c / reference_c; candidates with a "
            "diverged val jump rejected; the sparsest at or below the reference on every component at both "
            f"horizons chosen, else {tol}" + budget + checks)


@dataclass
class Selection:
    """The table (one row per candidate), the index of the chosen row and its model."""

    rows: list[dict[str, Any]]
    chosen: int | None
    model: HybridModel | None
    config: SelectionConfig
    data_sha256: str = ""
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)
    execution: dict[str, Any] = field(default_factory=dict)
    steps: dict[str, dict[str, float]] = field(default_factory=dict)

    def rule(self) -> str:
        """The score and the choice, in words."""
        return selection_rule(self.config)

    def summary(self) -> str:
        """The chosen candidate in one line: its settings, terms and val score."""
        if self.chosen is None:
            return f"none of {len(self.rows)} candidate models chosen: " + (self.notes[0] if self.notes else "")
        r = self.rows[self.chosen]
        return (f"chosen of {len(self.rows)} candidate models: encoder {r['encoder']}, l={r['latent_dim']}, "
                f"{r['library']}, threshold {r['threshold']:g}, refined {'yes' if r['refine'] else 'no'}"
                + (f" (pruned to {r['max_terms']})" if r.get("max_terms") else "")
                + f"; {r['active_terms']} active terms, val score {r['score']:.3g} ({self.seconds:.0f} s)")

    def refusals(self) -> dict[str, int]:
        """How many candidates each check refused."""
        return {c: sum(any(x["check"] == c for x in r.get("refused", ())) for r in self.rows) for c in CHECKS}

    def to_dict(self) -> dict[str, Any]:
        return {"version": SELECTION_VERSION, "config": asdict(self.config), "data_sha256": self.data_sha256,
                "rule": self.rule(), "steps": self.steps, "refusals": self.refusals(),
                "chosen": self.chosen, "seconds": round(self.seconds, 2), "notes": self.notes,
                "execution": self.execution, "rows": self.rows}


def check_splits(ds: Dataset) -> None:
    """ValueError unless ``ds`` has the train and val jumps a selection needs."""
    if ds.jumps_in("train").size == 0 or ds.jumps_in("val").size == 0:
        raise ValueError("selection needs 'train' and 'val' jumps (the test split is never read)")


def select(ds: Dataset, cfg: SelectionConfig = SelectionConfig(),
           progress: SelectProgress | None = None, backend: Backend | None = None,
           cells_dir: str | Path | None = None) -> Selection:
    """Run the grid on ``ds`` (train and val splits only) and return the selection.

    The cells, then the refinements, run as tasks on ``backend`` (default: ``cfg.workers``
    local processes); the table does not depend on where they ran. ``execution`` of the
    selection records the back end and every attempt lost to a dying worker. ``cells_dir``:
    a folder where each finished cell (``cell_path``) and refinement (``refined_path``, with
    its models) is written at once, JSON, and from which those of an interrupted run are
    reused when their key (``cell_key``, ``refined_key``) matches.
    """
    check_splits(ds)
    cfg = replace(cfg, polish=tuple(p for p in cfg.polish if p in ds.phase_names))  # a motion may have no flight
    t0 = time.perf_counter()
    say = progress or (lambda done, total, what: None)
    backend = backend or LocalBackend(cfg.workers)
    backend.prestart(SELECT_WORKER_MODULES)  # the workers' imports beside the hash and the steps below
    sha = data_hash(ds)
    steps = plan_steps(ds, cfg.substeps)
    cells = cfg.cells()
    total = len(cells) + cfg.refine_top * (1 if cfg.budget is None else 2)
    # The refinements' window kernel made ready in numba's disk cache by a helper beside the grid:
    # on a cold cache it compiles once there, not in every worker when the refinements start (a
    # selection that stops early leaves it to finish: it only fills the cache).
    helper = start_windows_helper() if cfg.refine_top > 0 else None
    store = None if cells_dir is None else Store(
        path=lambda c: cell_path(cells_dir, c), key=lambda c: cell_key(cfg, sha, c, steps),
        record=lambda c, rows, key, execution: {"key": key, "cell": list(c), "rows": rows, "execution": execution},
        value=lambda stored: stored["rows"])
    grid = run_grid(cells, run_cell, (ds, cfg, steps), backend, "selection cell", store, preload=SELECT_WORKER_MODULES,
                    progress=lambda done, n, c, task: say(done, total, f"{c[0]} l={c[1]}"
                                                          + (" (reused)" if task is None else "")))
    rows: list[dict] = [r for c in cells for r in grid.results[c]]
    retries = [{"task": f"{c[0]} l={c[1]}", **r} for c in grid.ran for r in grid.retries[c]]
    lib_order = {lib: i for i, lib in enumerate(cfg.libraries)}
    order = {c: i for i, c in enumerate(cells)}
    rows.sort(key=lambda r: (order[(r["encoder"], r["latent_dim"])], lib_order[r["library"]], r["threshold"]))
    budget = cfg.budget
    idx = to_refine(rows, cfg.refine_top, cfg.reference is not None, budget)
    picks: list[Pick] = [(rows[i]["encoder"], rows[i]["latent_dim"], rows[i]["library"], rows[i]["threshold"],
                          budget is not None and (cfg.max_terms is not None or rows[i]["active_terms"] > budget))
                         for i in idx]
    total = len(cells) + len(picks)  # fewer than refine_top when fewer candidates qualify
    if picks:
        wait_helper(helper, HELPER_TIMEOUT)  # left behind after that: the workers compile the kernel themselves
    say(len(cells), total, f"refining {len(picks)} candidate model(s)" if picks else "no candidate to refine")
    rstore = None if cells_dir is None else Store(
        path=lambda p: refined_path(cells_dir, p), key=lambda p: refined_key(cfg, sha, p, steps),
        record=lambda p, out, key, execution: {"key": key, "pick": list(p), "rows": out, "execution": execution},
        value=lambda stored: stored["rows"])
    # The refinements take longest: the densest first, so that the workers stay busy to the end.
    terms = {p: rows[i]["active_terms"] for p, i in zip(picks, idx)}
    refined = run_grid(picks, run_refinement, (ds, cfg, steps), backend, "selection refinement", rstore,
                       preload=SELECT_WORKER_MODULES,
                       order=lambda p: -terms[p],
                       progress=lambda done, n, p, task: say(len(cells) + done, total,
                                                             f"refined {p[0]} l={p[1]} {p[2]} {p[3]:g}"
                                                             + (" (reused)" if task is None else "")))
    retries += [{"task": f"refinement {p[0]} l={p[1]} {p[2]} {p[3]:g}", **r}
                for p in refined.ran for r in refined.retries[p]]
    models: dict[int, dict] = {}
    for p in picks:
        for r in refined.results[p]:
            r = dict(r)
            models[len(rows)] = r.pop("model")
            rows.append(r)
    chosen = choose(rows, cfg.tolerance, cfg.reference is not None, cfg.max_terms)
    notes = []
    if chosen is None:
        physics = sum(any(x["check"] == "physics" for x in r.get("refused", ())) for r in rows)
        notes.append("every candidate diverged on a validation jump or broke the data's momentum balance "
                     f"({physics} refused on physics): none chosen")
    else:
        aside = set_aside_for(rows)
        if aside:
            notes.append(f"no candidate passed every check: {' and '.join(aside)} set aside "
                         f"(see each row's refused)")
        if cfg.max_terms is not None and rows[chosen]["active_terms"] > cfg.max_terms:
            notes.append(f"no candidate within the budget of {cfg.max_terms} active terms stood: chosen among all")
    model = None
    if chosen is not None:
        r = rows[chosen]
        if chosen in models:
            model = model_from_dict(models[chosen])
        else:
            model = train(ds, cfg.train_config(r["encoder"], r["latent_dim"], r["library"], r["threshold"]))
        model = replace(model, provenance=model.provenance.with_selection(SelectionRecord(
            **{k: r[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine", "score", "active_terms")})))
    execution = {**backend.describe(), "cells_run": len(grid.ran), "cells_reused": len(cells) - len(grid.ran),
                 "refinements_run": len(refined.ran), "refinements_reused": len(picks) - len(refined.ran),
                 "retries": retries}
    return Selection(rows, chosen, model, cfg, sha, time.perf_counter() - t0, notes, execution, steps)


def write_selection(sel: Selection, out: str | Path) -> Path:
    """``selection.json`` in directory ``out`` (written atomically); its path."""
    path = Path(out) / "selection.json"
    write_text_atomic(path, json.dumps(sel.to_dict(), indent=1, allow_nan=False) + "\n")
    return path


def selection_config(**overrides: Any) -> SelectionConfig:
    """The default grid with ``overrides`` applied (names as in ``SelectionConfig``)."""
    return replace(SelectionConfig(), **overrides)


def parts_dir(out: str | Path) -> Path:
    """Where ``select_into`` keeps the finished cells and refinements of a selection written to ``out``."""
    return Path(str(out) + ".parts")


def parts_done(parts: str | Path) -> tuple[int, int]:
    """(finished cells, finished refinements) kept in a selection's parts folder."""
    parts = Path(parts)
    if not parts.is_dir():
        return 0, 0
    return len(list(parts.glob("*.json"))), len(list((parts / "refined").glob("*.json")))


def check_parts(out: str | Path, resume: bool, force: bool, inputs: tuple = ()) -> Path:
    """The cells folder of ``out``; ValueError if ``out`` exists (without ``force``) or is one of
    ``inputs``, or if its cells folder holds an interrupted selection that neither ``resume``
    continues nor ``force`` discards (checked before any work)."""
    check_output_file(out, force, inputs=inputs)
    parts = parts_dir(out)
    if parts.exists() and not resume and not force:
        cells, refined = parts_done(parts)
        raise ValueError(f"{parts} holds an interrupted selection ({cells} finished cells, {refined} finished "
                         "refinements); resume=True continues it, force=True starts over")
    return parts


class NoCandidateError(ValueError):
    """Every candidate of a selection diverged on a validation jump or broke the momentum balance:
    no model was chosen."""


def select_into(out: str | Path, data: Dataset | str | Path, cfg: SelectionConfig = SelectionConfig(),
                resume: bool = False, force: bool = False, progress: Callable[[int, int, str], None] | None = None,
                backend: Backend | None = None) -> Selection:
    """The selection's folder ``out``, written atomically: ``selection.json``
    (``write_selection``) and the chosen model (``model.json``, ``equations.txt``).
    ``data``: the dataset or its file (then recorded in the model as where it was trained).
    Raises ``NoCandidateError`` (after writing the table) when no candidate could be chosen.

    Each finished cell and refinement is kept in ``out.parts`` (``parts_dir``) until the
    folder is written, so that ``resume`` continues an interrupted selection without redoing
    any of them; ``force`` starts over (and replaces ``out``). The parts are removed once the
    folder is in place."""
    path = None if isinstance(data, Dataset) else Path(data)
    parts = check_parts(out, resume, force, inputs=() if path is None else (path,))
    ds = data if path is None else read_dataset(path)
    check_splits(ds)
    if parts.exists() and not resume:
        shutil.rmtree(parts)  # force: start over
    sel = select(ds, cfg, progress=progress, backend=backend, cells_dir=parts)
    with atomic_dir(Path(out), force) as tmp:
        write_selection(sel, tmp)
        if sel.model is not None:
            if path is not None:
                sel = replace(sel, model=replace(sel.model, provenance=sel.model.provenance.with_data_path(str(path))))
            write_model_files(sel.model, tmp)
    shutil.rmtree(parts, ignore_errors=True)
    if sel.model is None:
        raise NoCandidateError(f"none of the {len(sel.rows)} candidate models could be chosen ({sel.notes[0]}); "
                               f"the table is in {Path(out) / 'selection.json'}")
    return sel
