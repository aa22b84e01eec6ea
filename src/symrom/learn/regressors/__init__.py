"""Step (c) of the training as plug-ins behind one interface (``Regressor.fit``).

``STLSQ``: sequentially thresholded least squares, exact on each support;
``FineTune``: STLSQ pulled towards a source model; ``Adam`` (in
``symrom.learn.adam``): the paper's gradient training; ``Refine``: rollout-aware
refinement of another regressor's coefficients.
"""

from symrom.learn.regressors.base import Coefficients, PhaseData, RegressionProblem, Regressor, Trajectory
from symrom.learn.regressors.prior import FineTune
from symrom.learn.regressors.stlsq import STLSQ, STLSQConfig

__all__ = ["Coefficients", "FineTune", "PhaseData", "RegressionProblem", "Regressor", "STLSQ",
           "STLSQConfig", "Trajectory"]
