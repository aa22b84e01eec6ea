"""symrom: symbolic reduced-order models of legged-robot jumping learned from data.

The public Python API::

    import symrom
    ds = symrom.read_dataset("data/go1.h5")                     # Dataset, validated
    rom = symrom.SymbolicROM(latent_dim=2, library=symrom.Polynomial(1) + symrom.Inputs(),
                             regressor=symrom.STLSQ(threshold=3e-3, measure="explained"))
    rom.fit(ds)                                                  # or symrom.train(ds, TrainConfig(...))
    print(rom.equations())
    metrics, rollouts = symrom.evaluate(rom.model, ds, "test")   # full horizon and 0.1 s resets
"""

__version__ = "0.2.0"

from symrom import names
from symrom.baselines.aslip import ASlip, ASlipParams
from symrom.baselines.newton import AffineForce, Newton
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset, write_dataset
from symrom.evaluate.metrics import evaluate
from symrom.learn.encoders import PCAEncoder
from symrom.learn.estimator import SymbolicROM
from symrom.learn.regressors import STLSQ, FineTune
from symrom.learn.regressors.refine import Refine
from symrom.learn.training import TrainConfig, train
from symrom.model.hybrid import HybridModel
from symrom.model.library import Custom, Inputs, Library, Polynomial, Trigonometric
from symrom.model.persistence import load_model, save_model
from symrom.rollout.integrate import RolloutOptions, rollout

__all__ = ["ASlip", "ASlipParams", "AffineForce", "Custom", "Dataset", "FineTune", "HybridModel", "Inputs", "Library",
           "Newton", "PCAEncoder", "Polynomial", "Refine", "RolloutOptions", "STLSQ", "SymbolicROM",
           "TrainConfig", "Trigonometric", "evaluate", "load_model", "names", "read_dataset", "rollout",
           "save_model", "train", "write_dataset"]
