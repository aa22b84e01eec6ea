"""The latent dynamics as sympy expressions: the one builder behind the printed
equations (``HybridModel.equations``), the generated code (``symrom.compiled``,
through ``latent_dynamics``) and the exports (``symrom.export``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import sympy

from symrom.compiled import LatentDynamics
from symrom.model.library import Library


def latent_expressions(library: Library, Xi: np.ndarray, digits: int | None = None) -> list[list[sympy.Expr]]:
    """Per phase of ``Xi`` (P, p, l), the l right-hand sides ddxi_j over ``library.sympy_features()``
    (the symbols of ``symbols(l)``), one term per nonzero coefficient.

    digits None: every coefficient exact (its double, 17 significant digits), for code;
    else rounded to ``digits`` significant digits, for reading. A phase's row without
    terms is the zero of the same kind (0.0 exact, 0 rounded)."""
    feats = library.sympy_features()
    if digits is None:
        def number(c: float) -> sympy.Expr:
            return sympy.Float(repr(float(c)), 17)
        zero = sympy.Float(0.0)
    else:
        def number(c: float) -> sympy.Expr:
            return sympy.Float(float(f"{c:.{digits}g}"), digits)
        zero = sympy.Integer(0)
    out = []
    for Xk in np.asarray(Xi):
        rows = []
        for j in range(Xk.shape[1]):
            terms = [number(c) * f for c, f in zip(Xk[:, j], feats) if c != 0]
            rows.append(sympy.Add(*terms) if terms else zero)
        out.append(rows)
    return out


def latent_dynamics(library: Library, Xi: np.ndarray, phase_names: Sequence[str]) -> LatentDynamics:
    """The hybrid latent model with coefficients Xi (P, p, l) over ``library`` as the compiled
    code reads it; its right-hand sides are ``latent_expressions(library, Xi)``, built when a
    compilation asks for them."""
    Xi = np.array(Xi, dtype=float)  # a copy: the description stays what it was made of
    return LatentDynamics(library.terms, Xi, tuple(phase_names), lambda: latent_expressions(library, Xi))
