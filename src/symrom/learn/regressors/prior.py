"""Fine-tuning with a prior: STLSQ pulled towards a source model's coefficients.

Per phase, min ||ddxi - Theta Xi||^2 + w ||ddq - W_d Theta Xi||^2
+ r ||Xi - Xi_0||^2 with r = ``prior_weight`` * mean(diag Theta^T Theta),
starting from the source support (terms may drop out, none are added). A
phase without rows keeps the source coefficients unchanged. ``prior_weight``
0 refits from the new rows alone; large values keep the source model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from symrom.learn.regressors.base import Coefficients, RegressionProblem, Regressor
from symrom.learn.regressors.stlsq import STLSQConfig, check_measure, stlsq


@dataclass(frozen=True)
class FineTune(Regressor):
    """prior_weight: pull towards the source (relative to mean(diag Theta^T Theta));
    threshold, measure, alpha: as in ``STLSQ``. ``fit`` needs ``init``: the source."""

    kind: ClassVar[str] = "finetune"
    prior_weight: float = 0.01
    threshold: float = 0.01
    measure: str = "coefficient"
    alpha: float = 0.0

    def __post_init__(self) -> None:
        check_measure(self.measure)
        if not self.prior_weight >= 0:
            raise ValueError(f"prior_weight must be >= 0, got {self.prior_weight}")

    def _reduce(self, problem: RegressionProblem, allowed: np.ndarray,
                init: Coefficients | None) -> Coefficients:
        if init is None:
            raise ValueError("fine-tuning needs the source model's coefficients (init)")
        Xi, mask = init.Xi.copy(), init.mask.copy()
        # the pull towards the source is STLSQ's ridge with the source as its prior
        cfg = STLSQConfig(threshold=self.threshold, ridge=self.prior_weight, alpha=self.alpha, measure=self.measure,
                          target_spread=tuple(float(s) for s in problem.target_spread))
        for k, ph in enumerate(problem.phases):
            if ph is None:
                continue  # no new evidence: keep the source coefficients
            start = init.mask[k] & allowed[k][:, None]
            Xi[k], mask[k] = stlsq(ph.theta, ph.ddxi, ph.ddq, ph.W_d, cfg, prior=init.Xi[k], mask=start)
        return Coefficients(Xi, mask)
