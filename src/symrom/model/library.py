"""The SINDy candidate library Theta(xi, dxi, nu).

Columns, in order: all monomials of the 2l latent positions and velocities up
to ``poly_order`` (the constant first), then sin and cos of each of the 2l
latent positions and velocities, then the l latent inputs. With order p the
count is sum_k C(2l+k-1, k) + 2(2l) + l, the paper's Table 1: 15 for l=2, p=1
and 29 for l=4, p=1.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations_with_replacement
from math import comb

import numpy as np
import sympy


@dataclass(frozen=True)
class CandidateLibrary:
    """Feature library of a latent space of dimension ``latent_dim``.

    poly_order: highest total degree of the monomials of (xi, dxi);
    trig: include sin and cos of each latent position and velocity;
    inputs: include the latent inputs nu linearly.
    """

    latent_dim: int
    poly_order: int = 1
    trig: bool = True
    inputs: bool = True

    def __post_init__(self) -> None:
        if self.latent_dim < 1:
            raise ValueError(f"latent_dim must be >= 1, got {self.latent_dim}")
        if self.poly_order < 0:
            raise ValueError(f"poly_order must be >= 0, got {self.poly_order}")

    # State variables: xi1..xil, dxi1..dxil (column index into [xi, dxi]).
    @property
    def _state_names(self) -> list[str]:
        l = self.latent_dim
        return [f"xi{i + 1}" for i in range(l)] + [f"dxi{i + 1}" for i in range(l)]

    @property
    def monomials(self) -> list[tuple[int, ...]]:
        """Index tuples into [xi, dxi] of every monomial, by degree (() is the constant)."""
        n = 2 * self.latent_dim
        return [c for d in range(self.poly_order + 1)
                for c in combinations_with_replacement(range(n), d)]

    @property
    def n_features(self) -> int:
        n = 2 * self.latent_dim
        return (sum(comb(n + k - 1, k) for k in range(self.poly_order + 1))
                + (2 * n if self.trig else 0) + (self.latent_dim if self.inputs else 0))

    @property
    def feature_names(self) -> list[str]:
        s = self._state_names
        names = []
        for m in self.monomials:
            if not m:
                names.append("1")
                continue
            parts = []
            for i in sorted(set(m)):
                k = m.count(i)
                parts.append(s[i] if k == 1 else f"{s[i]}^{k}")
            names.append("*".join(parts))
        if self.trig:
            names += [f"sin({v})" for v in s] + [f"cos({v})" for v in s]
        if self.inputs:
            names += [f"nu{i + 1}" for i in range(self.latent_dim)]
        return names

    def transform(self, xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """Theta: xi, dxi, nu each (N, l) -> (N, n_features)."""
        xi = np.atleast_2d(xi)
        s = np.concatenate([xi, np.atleast_2d(dxi)], axis=1)
        cols = []
        for m in self.monomials:
            if not m:
                cols.append(np.ones((s.shape[0], 1)))
            elif len(m) == 1:
                cols.append(s[:, m[0]:m[0] + 1])
            else:
                cols.append(np.prod(s[:, list(m)], axis=1, keepdims=True))
        if self.trig:
            cols += [np.sin(s), np.cos(s)]
        if self.inputs:
            cols.append(np.atleast_2d(nu))
        return np.concatenate(cols, axis=1)

    def sympy_features(self) -> list[sympy.Expr]:
        """The features as sympy expressions of symbols xi_i, dxi_i, nu_i (i from 1)."""
        l = self.latent_dim
        xi = sympy.symbols(f"xi1:{l + 1}")
        dxi = sympy.symbols(f"dxi1:{l + 1}")
        nu = sympy.symbols(f"nu1:{l + 1}")
        s = list(xi) + list(dxi)
        feats: list[sympy.Expr] = [sympy.Mul(*[s[i] for i in m]) if m else sympy.Integer(1)
                                   for m in self.monomials]
        if self.trig:
            feats += [sympy.sin(v) for v in s] + [sympy.cos(v) for v in s]
        if self.inputs:
            feats += list(nu)
        return feats

    def to_dict(self) -> dict:
        return {"latent_dim": self.latent_dim, "poly_order": self.poly_order,
                "trig": self.trig, "inputs": self.inputs, "feature_names": self.feature_names}

    @classmethod
    def from_dict(cls, d: dict) -> CandidateLibrary:
        lib = cls(int(d["latent_dim"]), int(d["poly_order"]), bool(d["trig"]), bool(d["inputs"]))
        if "feature_names" in d and list(d["feature_names"]) != lib.feature_names:
            raise ValueError("library feature_names do not match its spec")
        return lib
