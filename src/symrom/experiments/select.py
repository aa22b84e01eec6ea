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
  refinement is what may make them meet it over the full jump too);
- a term budget, ``max_terms`` (None: none): every refinement prunes its
  candidate to at most that many active terms (``Refine.max_terms``: the
  coefficients least needed by the training rollouts go, a share at a time,
  and the rest are refined again), and only candidates within the budget
  compete in the rule below, unless none of them stands (then all do, and the
  selection says so in its notes). The exact candidates keep their thresholds'
  supports; a dense candidate that meets the reference at 0.1 s is thus turned
  into one within the budget, rather than a sparse one refined as it is.
  With a budget, two more things: the refinement ends with the phases of
  ``polish`` the data has refined again, each alone (``Refine.polish``); and besides the
  picks above, the cell (encoder, latent dimension, library) of the exact
  candidate with the best 0.1 s score is refined from ``refine_top`` of its
  thresholds, the sparsest with at least ``max_terms`` terms first (an exact
  fit's own val score says little of what it becomes once pruned, and the
  fewer terms pruning removes, the less it costs).

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

Every candidate and its numbers are kept in the selection table
(``selection.json``). The fitting of a cell (encoder, latent dimension,
library: one encoder and problem shared by its thresholds) reads only the
training rows and the validation jumps: replacing every value of the test
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
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.execution import Backend, LocalBackend
from symrom.experiments.grid import Store, run_grid
from symrom.learn.encoders import unit_floored
from symrom.learn.training import TrainConfig, data_hash, train
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import write_model_files
from symrom.model.provenance import SelectionRecord
from symrom.names import BASE_NAMES, FLIGHT_PHASE, Q_NAMES, STANCE_PHASE
from symrom.rollout.integrate import RolloutOptions

SELECTION_VERSION = 2
CELL_VERSION = 1
# The settings the rows of a cell depend on (besides the data and the cell itself).
CELL_SETTINGS = ("thresholds", "floor", "measure", "collinearity", "alpha", "decoded_weight", "contact_phase",
                 "substeps", "reference")
BASE_SHARE = 3  # latents pose+joints gives the base pose at most (x, z and pitch of a jump)


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

SelectProgress = Callable[[int, int, str], None]  # (cells done, cells in total, what finished)


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
    swing-leg accelerations the latent state does not hold)."""

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
    polish: tuple[str, ...] = (FLIGHT_PHASE,)

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
        if self.max_terms is not None and self.max_terms < 1:
            raise ValueError(f"max_terms={self.max_terms}: must be a positive number of terms")
        if self.reference is not None:
            keys = {"full", "0.1"}
            if set(self.reference) != keys:
                raise ValueError(f"reference: needs exactly the horizons {sorted(keys)}, got {sorted(self.reference)}")
            for h, comps in self.reference.items():
                bad = [c for c in comps if c not in Q_NAMES]
                if bad:
                    raise ValueError(f"reference.{h}: unknown component(s) {bad}")

    def yardstick(self, ds: Dataset) -> dict[str, dict[str, float]]:
        """Per horizon key, per scored component, the RMSE that counts as 1."""
        if self.reference is not None:
            return {h: {c: float(v) for c, v in comps.items() if v >= REFERENCE_FLOOR}
                    for h, comps in self.reference.items()}
        spread = dict(zip(Q_NAMES, component_spread(ds, self.floor).tolist()))
        return {"full": spread, "0.1": spread}

    def cells(self) -> list[tuple[str, int, str]]:
        """(encoder, latent dim, library) of every cell, skipping encoders too narrow for l."""
        out = []
        for enc in self.encoders:
            choice = ENCODERS[enc]
            for l in self.latent_dims:
                if choice.min_dim <= l <= choice.max_dim:
                    out += [(enc, l, lib) for lib in self.libraries]
        return out

    def train_config(self, encoder: str, latent_dim: int, library: str, threshold: float,
                     refine: bool = False) -> TrainConfig:
        return TrainConfig(latent_dim=latent_dim, **parse_library(library), threshold=threshold,
                           measure=self.measure, collinearity=self.collinearity, alpha=self.alpha,
                           decoded_weight=self.decoded_weight, **ENCODERS[encoder].settings(latent_dim),
                           contact_phase=self.contact_phase, refine=refine,
                           max_terms=self.max_terms if refine else None,
                           polish=self.polish if refine and self.max_terms is not None else ())


def component_spread(ds: Dataset, floor: float) -> np.ndarray:
    """(18,) standard deviation of each component over the val rows, floored at ``floor``
    times the largest among the components of the same unit."""
    return unit_floored(ds.q[ds.rows_of("val")].std(axis=0), floor)


def score_model(model: HybridModel, ds: Dataset, yardstick: dict[str, dict[str, float]],
                substeps: int) -> dict[str, Any]:
    """Validation rollouts at both horizons. Per horizon: ``score`` (mean of RMSE / yardstick
    over the yardstick's components), ``worst`` (their largest ratio), the diverged jumps
    and the RMSE of every component (ratios None if any jump diverged); ``score``, the
    mean over horizons (None if any diverged)."""
    metrics, _ = evaluate_model(model, ds, "val", HORIZONS, RolloutOptions("rk4", substeps=substeps))
    out: dict[str, Any] = {"horizons": {}}
    scores = []
    for key, h in metrics.horizons.items():
        rmse = {n: h.components[n].rmse for n in Q_NAMES} if h.components else None
        ratio = (np.array([rmse[c] / v for c, v in yardstick[key].items()])
                 if rmse is not None and not h.diverged_jumps else None)
        out["horizons"][key] = {"score": None if ratio is None else float(ratio.mean()),
                                "worst": None if ratio is None else float(ratio.max()),
                                "diverged_jumps": h.diverged_jumps, "rmse": rmse}
        scores.append(out["horizons"][key]["score"])
    out["score"] = None if any(s is None for s in scores) else float(np.mean(scores))
    return out


def meets(row: dict, horizons: tuple[str, ...] = ("full", "0.1")) -> bool:
    """Whether the row is at or below the yardstick on every component at ``horizons``."""
    return all(row["horizons"][h]["worst"] is not None and row["horizons"][h]["worst"] <= 1.0 for h in horizons)


def _row(cfg: SelectionConfig, encoder: str, l: int, library: str, threshold: float, refine: bool,
         model: HybridModel, scored: dict, seconds: float) -> dict[str, Any]:
    budget = ({"max_terms": cfg.max_terms, **({"polish": list(cfg.polish)} if cfg.polish else {})}
              if refine and cfg.max_terms is not None else {})
    return {"encoder": encoder, "latent_dim": l, "library": library, "threshold": threshold, "refine": refine,
            **budget, "active_terms": int(model.mask.sum()), "active_per_phase": model.active_terms(),
            "fast_unstable_phases": [s.phase for s in model.stability() if s.fast_unstable],
            "seconds": round(seconds, 3), **scored}


def run_cell(ds: Dataset, cfg: SelectionConfig, encoder: str, l: int, library: str) -> list[dict[str, Any]]:
    """Train and score every threshold of one (encoder, latent dim, library) cell: one
    encoder and regression problem, one regressor per threshold."""
    yardstick = cfg.yardstick(ds)
    t0 = time.perf_counter()
    configs = [cfg.train_config(encoder, l, library, t) for t in cfg.thresholds]
    models = configs[0].estimator().fit_variants(ds, [c.regressor() for c in configs])
    share = (time.perf_counter() - t0) / len(models)  # the shared fit, split between the thresholds
    rows = []
    for c, model in zip(configs, models):
        model = replace(model, provenance=model.provenance.with_settings(asdict(c)))
        t1 = time.perf_counter()
        scored = score_model(model, ds, yardstick, cfg.substeps)
        rows.append(_row(cfg, encoder, l, library, c.threshold, False, model, scored,
                         share + time.perf_counter() - t1))
    return rows


def cell_key(cfg: SelectionConfig, data_sha256: str, cell: tuple[str, int, str]) -> str:
    """Hash of everything the rows of ``cell`` depend on (not the rest of the grid, the
    workers, the refinement or the rule), to match stored cells on a resumed run."""
    settings = asdict(cfg)
    spec = {"version": CELL_VERSION, "data": data_sha256, "cell": list(cell),
            **{k: settings[k] for k in CELL_SETTINGS}}
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


def cell_path(folder: str | Path, cell: tuple[str, int, str]) -> Path:
    """The file of ``cell`` in a folder of finished cells: ``base_pose_l02_poly1+inputs.json``."""
    encoder, l, library = cell
    return Path(folder) / f"{encoder}_l{l:02d}_{library}.json"


def run_refined(ds: Dataset, cfg: SelectionConfig, row: dict) -> tuple[dict[str, Any], HybridModel]:
    """The refined version of a candidate row, scored."""
    t0 = time.perf_counter()
    model = train(ds, cfg.train_config(row["encoder"], row["latent_dim"], row["library"], row["threshold"], True))
    scored = score_model(model, ds, cfg.yardstick(ds), cfg.substeps)
    return _row(cfg, row["encoder"], row["latent_dim"], row["library"], row["threshold"], True, model, scored,
                time.perf_counter() - t0), model


def choose(rows: list[dict], tolerance: float, reference: bool = False,
           max_terms: int | None = None) -> int | None:
    """Index of the chosen row: with a ``reference``, the sparsest that meets it at both
    horizons if any; else the sparsest with a score within ``tolerance`` of the best.
    With ``max_terms``, only the rows within that many active terms compete, unless none
    of them stands (then all rows do)."""
    ok = [i for i, r in enumerate(rows) if r["score"] is not None]
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


def to_refine(rows: list[dict], k: int, reference: bool = False, max_terms: int | None = None) -> list[int]:
    """Indices of the exact candidates to refine (module docstring): ``k`` of them, and
    with ``max_terms`` up to ``k`` more from the best cell at 0.1 s."""
    short = [i for i, r in enumerate(rows) if r["horizons"]["0.1"]["score"] is not None]
    picked = []
    if reference:  # the sparsest that meet the reference with 0.1 s resets
        picked = sorted((i for i in short if meets(rows[i], ("0.1",))),
                        key=lambda i: (rows[i]["active_terms"], rows[i]["horizons"]["0.1"]["score"]))[:k]
    rest = sorted((i for i in short if i not in picked),
                  key=lambda i: (rows[i]["score"] is None, rows[i]["score"] if rows[i]["score"] is not None
                                 else rows[i]["horizons"]["0.1"]["score"]))
    picked += rest[:k - len(picked)]
    if max_terms is None or not short:
        return picked
    cell = lambda r: (r["encoder"], r["latent_dim"], r["library"])  # noqa: E731
    best = cell(rows[min(short, key=lambda i: rows[i]["horizons"]["0.1"]["score"])])
    members = [i for i, r in enumerate(rows) if cell(r) == best]
    members.sort(key=lambda i: (rows[i]["active_terms"] < max_terms,
                                abs(rows[i]["active_terms"] - max_terms)))
    return picked + [i for i in members if i not in picked][:k]


def selection_rule(cfg: SelectionConfig) -> str:
    """The score and the choice of ``choose`` under ``cfg``, in words."""
    tol = f"the sparsest within {cfg.tolerance:.0%} of the best score"
    budget = ("" if cfg.max_terms is None else
              f"; refinements pruned to at most {cfg.max_terms} active terms"
              + (f", then {', '.join(cfg.polish)} refined again alone" if cfg.polish else "")
              + f", and only candidates within {cfg.max_terms} terms compete (all if none stands)")
    if cfg.reference is None:
        return ("score = mean over horizons (full, 0.1 s) of mean_c val RMSE_c / spread_c; candidates with "
                f"a diverged val jump rejected; {tol} chosen" + budget)
    return ("score = mean over horizons (full, 0.1 s) of mean_c val RMSE_c / reference_c; candidates with a "
            "diverged val jump rejected; the sparsest at or below the reference on every component at both "
            f"horizons chosen, else {tol}" + budget)


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

    def rule(self) -> str:
        """The score and the choice, in words."""
        return selection_rule(self.config)

    def summary(self) -> str:
        """The chosen candidate in one line: its settings, terms and val score."""
        if self.chosen is None:
            return f"none of {len(self.rows)} candidate models chosen: every one diverged on a validation jump"
        r = self.rows[self.chosen]
        return (f"chosen of {len(self.rows)} candidate models: encoder {r['encoder']}, l={r['latent_dim']}, "
                f"{r['library']}, threshold {r['threshold']:g}, refined {'yes' if r['refine'] else 'no'}; "
                f"{r['active_terms']} active terms, val score {r['score']:.3g} ({self.seconds:.0f} s)")

    def to_dict(self) -> dict[str, Any]:
        return {"version": SELECTION_VERSION, "config": asdict(self.config), "data_sha256": self.data_sha256,
                "rule": self.rule(),
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

    The cells run as tasks on ``backend`` (default: ``cfg.workers`` local processes), the
    refinements then in this process; the table does not depend on where they ran.
    ``execution`` of the selection records the back end and every attempt lost to a dying
    worker. ``cells_dir``: a folder where each finished cell is written at once
    (``cell_path``, JSON) and from which the cells of an interrupted run are reused when
    their key (``cell_key``) matches.
    """
    check_splits(ds)
    cfg = replace(cfg, polish=tuple(p for p in cfg.polish if p in ds.phase_names))  # a motion may have no flight
    t0 = time.perf_counter()
    say = progress or (lambda done, total, what: None)
    backend = backend or LocalBackend(cfg.workers)
    sha = data_hash(ds)
    cells = cfg.cells()
    total = len(cells) + cfg.refine_top * (1 if cfg.max_terms is None else 2)
    store = None if cells_dir is None else Store(
        path=lambda c: cell_path(cells_dir, c), key=lambda c: cell_key(cfg, sha, c),
        record=lambda c, rows, key, execution: {"key": key, "cell": list(c), "rows": rows, "execution": execution},
        value=lambda stored: stored["rows"])
    grid = run_grid(cells, run_cell, (ds, cfg), backend, "selection cell", store, progress=lambda done, n, c, task: say(
        done, total, f"{c[0]} l={c[1]} {c[2]}" + (" (reused)" if task is None else "")))
    rows: list[dict] = [r for c in cells for r in grid.results[c]]
    retries = [{"task": f"{c[0]} l={c[1]} {c[2]}", **r} for c in grid.ran for r in grid.retries[c]]
    todo = grid.ran
    order = {c: i for i, c in enumerate(cells)}
    rows.sort(key=lambda r: (order[(r["encoder"], r["latent_dim"], r["library"])], r["threshold"]))
    refined_models = {}
    # The refinements (refine_top of them) run in this process, which compiles the refinement
    # kernel once; a fresh worker process would compile it again before refining.
    picks = to_refine(rows, cfg.refine_top, cfg.reference is not None, cfg.max_terms)
    total = len(cells) + len(picks)  # fewer than refine_top when fewer candidates qualify
    for k, i in enumerate(picks):
        row = rows[i]
        # Said before it starts: a refinement takes as long as many cells.
        say(len(cells) + k, total, f"refining {row['encoder']} l={row['latent_dim']} {row['library']}")
        new, model = run_refined(ds, cfg, row)
        rows.append(new)
        refined_models[len(rows) - 1] = model
        say(len(cells) + k + 1, total, f"refined {row['encoder']} l={row['latent_dim']} {row['library']}")
    if not picks:
        say(total, total, "no candidate to refine")
    chosen = choose(rows, cfg.tolerance, cfg.reference is not None, cfg.max_terms)
    notes = [] if chosen is not None else ["every candidate diverged on a validation jump: none chosen"]
    if chosen is not None and cfg.max_terms is not None and rows[chosen]["active_terms"] > cfg.max_terms:
        notes.append(f"no candidate within the budget of {cfg.max_terms} active terms stood: chosen among all")
    model = None
    if chosen is not None:
        r = rows[chosen]
        model = refined_models.get(chosen) or train(
            ds, cfg.train_config(r["encoder"], r["latent_dim"], r["library"], r["threshold"], r["refine"]))
        model = replace(model, provenance=model.provenance.with_selection(SelectionRecord(
            **{k: r[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine", "score", "active_terms")})))
    execution = {**backend.describe(), "cells_run": len(todo), "cells_reused": len(cells) - len(todo),
                 "retries": retries}
    return Selection(rows, chosen, model, cfg, sha, time.perf_counter() - t0, notes, execution)


def write_selection(sel: Selection, out: str | Path) -> Path:
    """``selection.json`` in directory ``out`` (written atomically); its path."""
    path = Path(out) / "selection.json"
    write_text_atomic(path, json.dumps(sel.to_dict(), indent=1, allow_nan=False) + "\n")
    return path


def selection_config(**overrides: Any) -> SelectionConfig:
    """The default grid with ``overrides`` applied (names as in ``SelectionConfig``)."""
    return replace(SelectionConfig(), **overrides)


def parts_dir(out: str | Path) -> Path:
    """Where ``select_into`` keeps the finished cells of a selection written to ``out``."""
    return Path(str(out) + ".parts")


def check_parts(out: str | Path, resume: bool, force: bool, inputs: tuple = ()) -> Path:
    """The cells folder of ``out``; ValueError if ``out`` exists (without ``force``) or is one of
    ``inputs``, or if its cells folder holds an interrupted selection that neither ``resume``
    continues nor ``force`` discards (checked before any work)."""
    check_output_file(out, force, inputs=inputs)
    parts = parts_dir(out)
    if parts.exists() and not resume and not force:
        raise ValueError(f"{parts} holds an interrupted selection; resume=True continues it, force=True "
                         "starts over")
    return parts


class NoCandidateError(ValueError):
    """Every candidate of a selection diverged on a validation jump: no model was chosen."""


def select_into(out: str | Path, data: Dataset | str | Path, cfg: SelectionConfig = SelectionConfig(),
                resume: bool = False, force: bool = False, progress: Callable[[int, int, str], None] | None = None,
                backend: Backend | None = None) -> Selection:
    """The selection's folder ``out``, written atomically: ``selection.json``
    (``write_selection``) and the chosen model (``model.json``, ``equations.txt``).
    ``data``: the dataset or its file (then recorded in the model as where it was trained).
    Raises ``NoCandidateError`` (after writing the table) when every candidate diverged.

    Each finished cell is kept in ``out.parts`` (``parts_dir``) until the folder is
    written, so that ``resume`` continues an interrupted selection; ``force`` starts over
    (and replaces ``out``). The parts are removed once the folder is in place."""
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
        raise NoCandidateError(f"every one of the {len(sel.rows)} candidate models diverged on a validation jump; "
                               f"the table is in {Path(out) / 'selection.json'}")
    return sel
