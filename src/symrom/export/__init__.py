"""Models outside Python: standalone C, plain Python, CasADi functions with their Jacobians.

Every export holds the whole model: the encoder (xi = W_e q + B_e, dxi = W_e
dq, nu = pinv(W_e^T) u), the decoder (q = W_d xi + B_d), every phase's latent
dynamics ddxi = f_k(xi, dxi, nu) written out term by term from the sympy form
of the library (full double precision, only the active terms), one classical
Runge-Kutta step of the latent state with the input and the phase held, as the
rollouts do; the learned contact guards, free prediction from (q0, dq0) with an
input sequence (the schedule given or the guards deciding, as
``HybridModel.predict_path``), and, for a model of a described robot, the input
map from joint torques and feet to u. Each export states the model's hash
(SHA-256 of its model file's content) and its phase names; phase k is the k-th
name. Every function takes the latent state as one vector s = [xi, dxi] (2l) and
the inputs as nu (l).

What is the same for every model is written once, as source files of this
package (``runtime/``: ``symrom_runtime.c``, ``symrom_runtime.h``,
``symrom_runtime.py``); an export writes the model's tables
(``tables.export_tables``) and per-phase dynamics beside it:

- ``c``: ``symrom_model.h``, ``symrom_model.c`` (which includes the runtime) and
  the runtime's two files (C99, math.h only; ``to_c``);
- ``python``: ``symrom_model.py``, NumPy only, the runtime inside (``to_python``);
- ``casadi``: one ``symrom_model_<name>.casadi`` per ``casadi.Function``
  (``casadi_functions``) and ``symrom_model_casadi.json`` (``to_casadi``).
"""

from __future__ import annotations

import os
from pathlib import Path

from symrom.export import to_c, to_casadi, to_python
from symrom.export.tables import ExportTables, export_tables
from symrom.model.hybrid import HybridModel

TARGETS = ("c", "casadi", "python")

__all__ = ["ExportTables", "TARGETS", "casadi_functions", "export", "export_tables"]


def export(model: HybridModel, target: str, out: str | os.PathLike) -> list[Path]:
    """Write the export of ``model`` for ``target`` into directory ``out``; the paths written
    (for C: the model's header and source first)."""
    if target not in TARGETS:
        raise ValueError(f"unknown export target {target!r}; choose from {TARGETS}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    writer = {"c": to_c.write, "casadi": to_casadi.write, "python": to_python.write}[target]
    return writer(export_tables(model), out)


def casadi_functions(model: HybridModel) -> dict:
    """``{name: casadi.Function}`` of ``model`` (``to_casadi.functions``: the dynamics, RK4 steps,
    Jacobians, encoder and decoder, guards and input map)."""
    return to_casadi.functions(export_tables(model))
