"""Fine-tuning with a check: a source model adapted to new jumps, never worse on their val split.

The procedure (``run_finetune``; ``symrom finetune SOURCE/model.json DATA.h5 --out DIR``):

1. The source model and the data must match (robot, joint layout), and the
   data's ``train`` and ``val`` splits must hold jumps. The ``train`` rows may
   hold only some of the model's phases (a flight-only set): those phases are
   refit, the others keep the source coefficients, and the result says which.
2. ``learn.finetune.finetune`` refits the decoder (guarded: a ridge towards
   the source decoder, and a refusal when the rows cannot determine it) and
   adapts each phase the rows hold at the configured ``prior_weight``: by
   default (``calibrate``) only its input gains, offsets and damping, the
   flight phase's gravity kept unless the rows contradict it
   (``learn.calibrate``); with ``acceleration`` every coefficient
   (``FineTune``: pulled towards the source coefficients); with
   ``calibrate_rollout`` the calibration, then its non-flight phases refined
   on rollouts of the train jumps, the flight phase held as calibrated.
3. The source and the fine-tuned model are rolled out on the ``val`` jumps at
   both horizons (the full jump, 0.1 s resets). Score: the mean over the 18
   components of RMSE / spread (the component's standard deviation on the val
   rows, at least ``floor`` times the largest of its unit), averaged over the
   horizons, a diverged jump scored up to its divergence.
4. The fine-tuned model is accepted if it has no more diverged val jumps than
   the source and its score is at most ``tolerance`` (5 %) above the source's.
   Otherwise the prior weight is raised tenfold, towards the source model, and
   steps 2-4 repeat, up to ``max_raises`` times; if none is accepted the
   fine-tuning is refused (the source model stays the better one; the message
   names the other methods). With
   ``method="rollout"`` (the rollout-aware refinement started from the source
   coefficients) the prior weight pulls only the decoder, not the coefficients:
   one attempt (with ``calibrate_rollout`` it pulls the calibration the
   refinement starts from, and is raised as for ``calibrate``).

Only ``train`` and ``val`` are read, so ``symrom evaluate`` on the ``test``
split stays an honest measure of the result.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from symrom.data.dataset import Dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.evaluate.outputs import write_json, write_metrics
from symrom.evaluate.records import Metrics
from symrom.learn.encoders import unit_floored
from symrom.learn.finetune import FineTuneConfig, check_decoder, finetune
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import write_model_files
from symrom.model.provenance import FineTuneRecord, thaw
from symrom.names import Q_NAMES
from symrom.rollout.integrate import RolloutOptions

HORIZONS = (None, 0.1)


class FineTuneRefused(ValueError):
    """The fine-tuning cannot be done or does not pass its check; one clear line."""


@dataclass(frozen=True)
class FineTuneCheck:
    """config: the fine-tuning itself; tolerance: how much the val score may rise (a
    fraction of the source's); max_raises: how many times the prior weight may be
    raised tenfold when the val score rises more; floor: the spread floor of the score;
    integrator: of the val rollouts."""

    config: FineTuneConfig = field(default_factory=FineTuneConfig)
    tolerance: float = 0.05
    max_raises: int = 4
    floor: float = 0.05
    integrator: str = "rk4"

    def __post_init__(self) -> None:
        if not self.tolerance >= 0:
            raise ValueError(f"tolerance={self.tolerance}: must be >= 0")
        if self.max_raises < 0:
            raise ValueError(f"max_raises must be >= 0, got {self.max_raises}")
        if self.integrator not in ("lsoda", "rk4"):
            raise ValueError(f"integrator={self.integrator!r}: choose lsoda or rk4")


@dataclass
class FineTuneResult:
    """The accepted model; the val metrics of the source (``before``) and of it
    (``after``); per attempt its prior weight, score and diverged jumps; the record
    (``to_dict``) written beside it."""

    model: HybridModel
    before: Metrics
    after: Metrics
    attempts: list[dict]
    check: FineTuneCheck
    data: str = ""
    train_rows: str = ""

    @property
    def record(self) -> FineTuneRecord:
        return self.model.provenance.finetune

    def messages(self) -> list[tuple[bool, str]]:
        """The fine-tuning in words, in order: ``(is_warning, line)``: the rows it fitted, the
        phases kept, the decoder, the val scores, the calibration, and the val divergences."""
        record = self.to_dict()
        out: list[tuple[bool, str]] = []
        if self.train_rows:
            out.append((False, f"fine-tuning rows (train): {self.train_rows}"))
        out += [(True, f"phase {name!r}: no rows in the train split of {self.data or 'the data'}: its source "
                       "coefficients are kept") for name in record["phases_kept"]]
        dec = record["decoder"]
        out.append((False, ("decoder: refit towards the source" if dec["refit"] else "decoder: the source's (kept)")
                    + f"; the rows vary by at least {100 * dec['excitation']:.3g} % of the source's latent spread "
                    f"in every direction; max |W_d| {dec['max_abs_W_d_source']:.3g} -> {dec['max_abs_W_d']:.3g}"))
        raised = "" if len(self.attempts) == 1 else (
            f" (prior weight raised to {record['prior_weight']:g}: at " + ", ".join(
                f"{a['prior_weight']:g} the score was {a['score']:.4g}" for a in self.attempts[:-1]) + ")")
        out.append((False, f"refit phases: {', '.join(record['phases_refit'])}; val "
                           f"({self.before.n_jumps} jumps): score {record['score_before']:.4g} -> "
                           f"{record['score_after']:.4g} (mean RMSE / spread, both horizons; at most "
                           f"+{100 * self.check.tolerance:g} % allowed), diverged {record['diverged_before']} -> "
                           f"{record['diverged_after']}{raised}"))
        out += calibration_lines(record)
        out += [(True, w) for w in self.after.warnings()]
        return out

    def to_dict(self) -> dict[str, Any]:
        a = self.attempts[-1]
        return {"version": FINETUNE_VERSION, "check": asdict(self.check), "attempts": self.attempts,
                "prior_weight": a["prior_weight"], "score_before": self.attempts[0]["score_before"],
                "score_after": a["score"], "diverged_before": self.attempts[0]["diverged_before"],
                "diverged_after": a["diverged"], "phases_refit": list(self.record.phases_refit),
                "phases_kept": list(self.record.phases_kept),
                "phases_rolled_out": list(self.record.phases_rolled_out), "decoder": thaw(self.record.decoder),
                "flight_gravity": thaw(self.record.flight_gravity),
                **({"calibration": thaw(self.record.calibration)} if self.record.calibration is not None else {}),
                "rule": RULE}


# finetune.json (``FineTuneResult.to_dict``)
FINETUNE_VERSION = 1
RULE = ("score: mean over the 18 components of val RMSE / spread, averaged over the full horizon and 0.1 s "
        "resets; accepted if no more diverged val jumps than the source and a score at most the tolerance "
        "above the source's; else the prior weight is raised tenfold")


def val_score(metrics: Metrics, spread: np.ndarray) -> tuple[float, int]:
    """(score, diverged jumps) of val metrics: mean over horizons of mean(RMSE / spread) over
    the 18 components (inf when nothing could be scored), and the diverged jumps summed."""
    scores, diverged = [], 0
    for h in metrics.horizons.values():
        diverged += h.diverged_jumps
        comps = h.components
        scores.append(float(np.mean([comps[c].rmse / s for c, s in zip(Q_NAMES, spread)]))
                      if comps else float("inf"))
    return float(np.mean(scores)), diverged


def check_data(model: HybridModel, ds: Dataset, config: FineTuneConfig = FineTuneConfig()) -> None:
    """Refuse data that cannot fine-tune ``model``, before any work: other robot or layout,
    no train or val jumps, rows in a phase the model cannot roll out, a decoder the train
    rows cannot determine."""
    model.check_data(ds)
    for split in ("train", "val"):
        if ds.jumps_in(split).size == 0:
            raise FineTuneRefused(f"the data have no {split!r} jumps: fine-tuning fits the train jumps and is "
                                  "checked on the val jumps (split= at import)")
    model.phase_index(ds, ds.rows_of("train"))
    model.phase_index(ds, ds.rows_of("val"))
    check_decoder(model, ds, ds.rows_of("train"), config)


def run_finetune(model: HybridModel, ds: Dataset, check: FineTuneCheck = FineTuneCheck(),
                 progress=None, first: HybridModel | None = None) -> FineTuneResult:
    """Fine-tune ``model`` on the train jumps of ``ds``, checked on its val jumps (module
    docstring). Raises ``FineTuneRefused`` (or ``ModelDataError`` / ``DecoderRefitError``)
    with one clear line when it cannot, or when every attempt makes val worse.

    first: ``finetune(model, ds, config=check.config)`` where the caller has it already (a
    reproduction's candidates hold it): the first attempt's model, not fitted again."""
    say = progress or (lambda msg: None)
    check_data(model, ds, check.config)
    if first is not None:
        _check_first(first, ds, check.config)
    spread = unit_floored(ds.q[ds.rows_of("val")].std(axis=0), check.floor)
    options = RolloutOptions(method=check.integrator)
    say("the source model on the val jumps")
    before, _ = evaluate_model(model, ds, "val", HORIZONS, options)
    score0, div0 = val_score(before, spread)
    attempts = []
    weight = check.config.prior_weight
    for k in range(check.max_raises + 1):
        say(f"fine-tuning (prior weight {weight:g})")
        tuned = (first if k == 0 and first is not None else
                 finetune(model, ds, config=replace(check.config, prior_weight=weight)))
        after, _ = evaluate_model(tuned, ds, "val", HORIZONS, options)
        score, div = val_score(after, spread)
        ok = div <= div0 and score <= score0 * (1.0 + check.tolerance)
        attempts.append({"prior_weight": weight, "score": score, "diverged": div, "score_before": score0,
                         "diverged_before": div0, "accepted": bool(ok)})
        if ok:
            tuned = replace(tuned, provenance=tuned.provenance.with_finetune(check={
                "val_score_before": score0, "val_score_after": score, "tolerance": check.tolerance,
                "prior_weight": weight}))
            return FineTuneResult(tuned, before, after, attempts, check)
        if check.config.method == "rollout":  # the prior weight does not enter the coefficients' rollout fit
            break
        weight = 10.0 * weight if weight > 0 else 0.01
    tried = ", ".join(f"{a['prior_weight']:g}" for a in attempts)
    raise FineTuneRefused(f"fine-tuning makes the val error worse at every prior weight tried ({tried}): "
                          f"score {score0:.4g} before, at best {min(a['score'] for a in attempts):.4g} after "
                          f"(tolerance +{100 * check.tolerance:g} %), diverged val jumps {div0} before; the source "
                          f"model stays the better one{_others(check.config.method)}")


def _check_first(first: HybridModel, ds: Dataset, config: FineTuneConfig) -> None:
    """``ValueError`` naming what differs where ``first`` is not a fine-tuning by ``config`` on
    ``ds``'s rows (its record's configuration and data hash)."""
    from symrom.learn.estimator import data_hash

    record = first.provenance.finetune
    if record is None:
        raise ValueError("first: the model is not a fine-tuning (its provenance records none)")
    wanted, have = asdict(config), thaw(record.config)
    differ = sorted(k for k in wanted.keys() | have.keys() if have.get(k) != wanted.get(k))
    if differ:
        raise ValueError(f"first: fine-tuned with other settings than the check's ({', '.join(differ)})")
    if record.data_sha256 != data_hash(ds):
        raise ValueError("first: fine-tuned on other data (its data_sha256 is not this dataset's)")


def write_finetune(folder: str | Path, result: FineTuneResult) -> list[Path]:
    """A fine-tuning's folder in the existing directory ``folder``: the tuned model
    (``model.json``, ``equations.txt``), ``finetune.json`` (``FineTuneResult.to_dict``) and
    the val evaluations before and after (``val_before/``, ``val_after/``: ``metrics.json``,
    ``table.md``). Returns the paths written."""
    folder = Path(folder)
    written = write_model_files(result.model, folder) + [write_json(folder / "finetune.json", result.to_dict())]
    for name, metrics in (("val_before", result.before), ("val_after", result.after)):
        (folder / name).mkdir(exist_ok=True)
        written += write_metrics(folder / name, metrics, title=f"{name.replace('_', ' ')} fine-tuning")
    return written


def calibration_lines(record: dict) -> list[tuple[bool, str]]:
    """The calibrated gains per phase, the flight test and the fine-tuned flight gravity of a
    fine-tuning's record (``FineTuneResult.to_dict``): ``(is_warning, line)``."""
    out: list[tuple[bool, str]] = []
    cal = record.get("calibration")
    for name, p in (cal or {}).get("phases", {}).items():
        if p["calibrated"]:
            def values(kind: str, added: list[bool]) -> str:  # "*": a calibration term the source lacked
                return ", ".join("-" if x is None else f"{x:+.3g}" + ("*" if new else "")
                                 for x, new in zip(p[kind], added))

            n = len(p["gain"])
            g = ", ".join("-" if x is None else f"{x:.3g}" for x in p["gain"])
            o = values("offset", p.get("offset_added", [False] * n))
            d = values("damping", p.get("damping_added", [False] * n))
            added = any(p.get("offset_added", [])) or any(p.get("damping_added", []))
            out.append((False, f"calibrated {name}: input gains [{g}], offsets [{o}] latent units/s², "
                               f"damping [{d}] 1/s"
                        + (" (*: a calibration term the source's equation lacked)" if added else "")))
    rolled = record.get("phases_rolled_out") or []
    if cal and rolled:
        out.append((False, f"then refined on rollouts of the train jumps: {', '.join(rolled)} (from the calibrated "
                           "coefficients; the other phases as calibrated)"))
    test = (cal or {}).get("flight_test")
    if test:
        se = "-" if test["se"] is None else f"{test['se']:.2g}"  # None: a single jump
        where, verdict = (("beyond", "the data contradict the source, gravity calibrated") if test["contradicted"]
                          else ("within", "the data do not contradict the source, gravity kept"))
        out.append((False, f"flight test: decoded z acceleration residual {test['mean']:+.3g} ± {se} m/s² over "
                           f"{test['jumps']} jumps, {where} the limits of {test['limit']:.2g} m/s² and "
                           f"{test['t_limit']:g} standard errors: {verdict}"))
    fg = record.get("flight_gravity")
    if fg:
        out.append((False, f"flight gravity: {fg['model']:.3g} m/s² ({100 * fg['ratio']:.1f} % of g; the data "
                           f"{fg['data']:.3g})"))
        if abs(fg["ratio"] - 1.0) > 0.05:
            out.append((True, f"the fine-tuned flight equations fall at {-fg['model']:.3g} m/s², more than 5 % "
                              f"from g (the data's flight rows: {-fg['data']:.3g} m/s²)"))
    return out


def finetune_into(out: str | Path, model_path: str | Path, data: str | Path, check: FineTuneCheck = FineTuneCheck(),
                  force: bool = False, progress=None) -> FineTuneResult:
    """``run_finetune`` of the model file ``model_path`` on the dataset file ``data``, written as
    the folder ``out`` (``write_finetune``; atomically, an existing folder only with ``force``,
    never one holding an input); the result, whose model records both files. Refused before
    any work: an output in the way, data that cannot fine-tune the model (``check_data``)."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.data.io import read_dataset
    from symrom.model.persistence import load_model

    check_output_file(out, force, inputs=(model_path, data))
    model = load_model(model_path)
    ds = read_dataset(data)
    check_data(model, ds, check.config)
    result = run_finetune(model, ds, check, progress=progress)
    tuned = result.model
    tuned = replace(tuned, provenance=tuned.provenance.with_finetune(path=str(data), source_model=str(model_path)))
    result = replace(result, model=tuned, data=str(data), train_rows=ds.phase_rows(ds.rows_of("train")))
    with atomic_dir(out, force) as tmp:
        write_finetune(tmp, result)
    return result


def _others(method: str) -> str:
    """What else could be tried after ``method`` was refused."""
    from symrom.learn.finetune import FINETUNE_METHODS

    return "; " + " or ".join(f"method={m!r}" for m in FINETUNE_METHODS if m != method) + " fit otherwise"
