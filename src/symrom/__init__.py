"""symrom: symbolic reduced-order models of legged-robot jumping learned from data.

The public Python API (docs/design.md, "Public Python API")::

    import symrom
    ds = symrom.read_dataset("data/go1.h5")                     # Dataset, validated
    rom = symrom.SymbolicROM(latent_dim=2, library=symrom.Polynomial(1) + symrom.Inputs(),
                             regressor=symrom.STLSQ(threshold=3e-3, measure="explained"))
    rom.fit(ds)                                                  # or SymbolicROM.from_config(TrainConfig(...))
    print(rom.equations())                                       # Equations: per phase sympy, prints as text
    metrics, rollouts = symrom.evaluate_model(rom, ds, "test")   # Metrics; full horizon and 0.1 s resets
    newton = symrom.Newton.fit(ds)                               # every baseline: Baseline.fit(ds)

``SymbolicROM`` is the one entry point for a model (fit, load, save, simulate, equations);
``evaluate_model`` scores any model that can be rolled out. The names are imported when
first used, so that ``import symrom`` (and the command line's ``--help`` and ``--version``)
loads no numerical library; no name shadows a subpackage.
"""

from __future__ import annotations

import importlib

__version__ = "0.2.0"

# public name -> the module that defines it
_EXPORTS: dict[str, str] = {
    # the entry point and its settings
    "SymbolicROM": "symrom.learn.estimator", "TrainConfig": "symrom.learn.training",
    # data
    "Dataset": "symrom.data.dataset", "read_dataset": "symrom.data.io", "write_dataset": "symrom.data.io",
    # plug-ins: library blocks, encoder, regressors
    "Library": "symrom.model.library", "Polynomial": "symrom.model.library", "Trigonometric": "symrom.model.library",
    "Inputs": "symrom.model.library", "Custom": "symrom.model.library", "PCAEncoder": "symrom.learn.encoders",
    "STLSQ": "symrom.learn.regressors", "FineTune": "symrom.learn.regressors",
    "Refine": "symrom.learn.regressors.refine",
    # the fitted model and its records
    "HybridModel": "symrom.model.hybrid", "Provenance": "symrom.model.provenance",
    "Equations": "symrom.model.expressions",
    # evaluation of any model that can be rolled out
    "evaluate_model": "symrom.evaluate.metrics", "Metrics": "symrom.evaluate.records",
    "RolloutOptions": "symrom.rollout.integrate",
    # baselines, each made by Baseline.fit(ds)
    "ASlip": "symrom.baselines.aslip", "ASlipParams": "symrom.baselines.aslip", "Newton": "symrom.baselines.newton",
    "AffineForce": "symrom.baselines.newton",
}
_MODULES = ("names",)  # submodules that are public names themselves

__all__ = sorted([*_EXPORTS, *_MODULES])


def __getattr__(name: str):
    if name in _MODULES:
        return importlib.import_module(f"symrom.{name}")
    if name not in _EXPORTS:
        raise AttributeError(f"module 'symrom' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
