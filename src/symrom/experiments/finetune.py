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
from symrom.evaluate.metrics import evaluate
from symrom.evaluate.outputs import write_json, write_metrics
from symrom.learn.encoders import unit_floored
from symrom.learn.finetune import FineTuneConfig, check_decoder, finetune
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import write_model_files
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
            raise ValueError(f"tolerance must be >= 0, got {self.tolerance}")
        if self.max_raises < 0:
            raise ValueError(f"max_raises must be >= 0, got {self.max_raises}")


@dataclass
class FineTuneResult:
    """The accepted model; the val metrics of the source (``before``) and of it
    (``after``); per attempt its prior weight, score and diverged jumps; the record
    (``to_dict``) written beside it."""

    model: HybridModel
    before: dict
    after: dict
    attempts: list[dict]
    check: FineTuneCheck

    @property
    def record(self) -> dict:
        return self.model.info["finetune"]

    def to_dict(self) -> dict[str, Any]:
        a = self.attempts[-1]
        return {"version": 1, "check": asdict(self.check), "attempts": self.attempts,
                "prior_weight": a["prior_weight"], "score_before": self.attempts[0]["score_before"],
                "score_after": a["score"], "diverged_before": self.attempts[0]["diverged_before"],
                "diverged_after": a["diverged"], "phases_refit": self.record["phases_refit"],
                "phases_kept": self.record["phases_kept"],
                "phases_rolled_out": self.record.get("phases_rolled_out", []), "decoder": self.record["decoder"],
                "flight_gravity": self.record.get("flight_gravity"),
                **({"calibration": self.record["calibration"]} if "calibration" in self.record else {}),
                "rule": RULE}


RULE = ("score: mean over the 18 components of val RMSE / spread, averaged over the full horizon and 0.1 s "
        "resets; accepted if no more diverged val jumps than the source and a score at most the tolerance "
        "above the source's; else the prior weight is raised tenfold")


def val_score(metrics: dict, spread: np.ndarray) -> tuple[float, int]:
    """(score, diverged jumps) of val metrics: mean over horizons of mean(RMSE / spread) over
    the 18 components (inf when nothing could be scored), and the diverged jumps summed."""
    scores, diverged = [], 0
    for h in metrics["horizons"].values():
        diverged += h["diverged_jumps"]
        comps = h["components"]
        scores.append(float(np.mean([comps[c]["rmse"] / s for c, s in zip(Q_NAMES, spread)]))
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
                                  "checked on the val jumps (--split at import)")
    model.phase_index(ds, ds.rows_of("train"))
    model.phase_index(ds, ds.rows_of("val"))
    check_decoder(model, ds, ds.rows_of("train"), config)


def run_finetune(model: HybridModel, ds: Dataset, check: FineTuneCheck = FineTuneCheck(),
                 progress=None) -> FineTuneResult:
    """Fine-tune ``model`` on the train jumps of ``ds``, checked on its val jumps (module
    docstring). Raises ``FineTuneRefused`` (or ``ModelDataError`` / ``DecoderRefitError``)
    with one clear line when it cannot, or when every attempt makes val worse."""
    say = progress or (lambda msg: None)
    check_data(model, ds, check.config)
    spread = unit_floored(ds.q[ds.rows_of("val")].std(axis=0), check.floor)
    options = RolloutOptions(method=check.integrator)
    say("the source model on the val jumps")
    before, _ = evaluate(model, ds, "val", HORIZONS, options)
    score0, div0 = val_score(before, spread)
    attempts = []
    weight = check.config.prior_weight
    for k in range(check.max_raises + 1):
        say(f"fine-tuning (prior weight {weight:g})")
        tuned = finetune(model, ds, config=replace(check.config, prior_weight=weight))
        after, _ = evaluate(tuned, ds, "val", HORIZONS, options)
        score, div = val_score(after, spread)
        ok = div <= div0 and score <= score0 * (1.0 + check.tolerance)
        attempts.append({"prior_weight": weight, "score": score, "diverged": div, "score_before": score0,
                         "diverged_before": div0, "accepted": bool(ok)})
        if ok:
            tuned.info["finetune"]["check"] = {"val_score_before": score0, "val_score_after": score,
                                               "tolerance": check.tolerance, "prior_weight": weight}
            return FineTuneResult(tuned, before, after, attempts, check)
        if check.config.method == "rollout":  # the prior weight does not enter the coefficients' rollout fit
            break
        weight = 10.0 * weight if weight > 0 else 0.01
    tried = ", ".join(f"{a['prior_weight']:g}" for a in attempts)
    raise FineTuneRefused(f"fine-tuning makes the val error worse at every prior weight tried ({tried}): "
                          f"score {score0:.4g} before, at best {min(a['score'] for a in attempts):.4g} after "
                          f"(tolerance +{100 * check.tolerance:g} %), diverged val jumps {div0} before; the source "
                          f"model stays the better one{_others(check.config.method)}")


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


def _others(method: str) -> str:
    """What else could be tried after ``method`` was refused."""
    from symrom.learn.finetune import FINETUNE_METHODS

    return "; " + " or ".join(f"--method {m}" for m in FINETUNE_METHODS if m != method) + " fit otherwise"
