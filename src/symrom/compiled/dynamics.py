"""What the compiled code reads of a model: typed descriptions that the fitted model builds.

The compiled code knows no model class. ``symrom.model`` hands it the candidate terms
(``TermLibrary``: each term a sympy product of the state and input symbols) and, for the
generated code, the whole hybrid latent model (``LatentDynamics``: the terms, the
coefficients Xi of every phase, the phases' names and the exact right-hand sides).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import sympy


@dataclass(frozen=True, eq=False)
class TermLibrary:
    """The p candidate terms of a latent space of dimension l.

    features (p): each term as a sympy expression of ``state`` (2l symbols: xi then dxi)
    and ``inputs`` (l symbols: nu); identity: text that names the library (its record),
    with the coefficients the key of every cache of compiled code (in this process and
    on disk)."""

    features: tuple[sympy.Expr, ...]
    state: tuple[sympy.Symbol, ...]
    inputs: tuple[sympy.Symbol, ...]
    identity: str

    def __post_init__(self) -> None:
        if len(self.state) != 2 * len(self.inputs):
            raise ValueError(f"term library: {len(self.state)} state symbols for {len(self.inputs)} inputs "
                             "(expected 2l and l)")

    @property
    def latent_dim(self) -> int:
        return len(self.inputs)


@dataclass(frozen=True, eq=False)
class LatentDynamics:
    """A hybrid latent model ddxi = Theta(xi, dxi, nu) Xi_k in phase k.

    terms: the library's terms; Xi (P, p, l) float: the coefficients of every phase;
    phase_names (P): the phases' names (comments of the generated code);
    right_hand_sides(): per phase the l exact right-hand sides (sympy, over the terms'
    symbols, one term per nonzero coefficient), built on demand: only a compilation
    reads them, and building them costs more than a cached build's look-up."""

    terms: TermLibrary
    Xi: np.ndarray
    phase_names: tuple[str, ...]
    right_hand_sides: Callable[[], Sequence[Sequence[sympy.Expr]]] = field(repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "Xi", np.ascontiguousarray(self.Xi, dtype=float))
        object.__setattr__(self, "phase_names", tuple(self.phase_names))
        P, l = len(self.phase_names), self.terms.latent_dim
        if self.Xi.shape != (P, len(self.terms.features), l):
            raise ValueError(f"Xi: shape {self.Xi.shape}, expected {(P, len(self.terms.features), l)} "
                             "(phases, terms, latents)")

    @property
    def latent_dim(self) -> int:
        return self.terms.latent_dim

    @cached_property
    def key(self) -> str:
        """SHA-256 (hex) of the library's identity and the coefficients' bytes: the name of
        the model's compiled code, in this process and in the disk cache."""
        h = hashlib.sha256(self.terms.identity.encode())
        h.update(self.Xi.tobytes())
        return h.hexdigest()
