"""HybridModel: the autoencoder, the library and one coefficient matrix per phase.

Latent dynamics in phase k: ddxi = Theta(xi, dxi, nu) Xi_k.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy

from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.library import CandidateLibrary


@dataclass
class HybridModel:
    """autoencoder; library; phase_names (P,); Xi (P, p, l); mask (P, p, l) bool;
    latent_scale (2l,): largest |xi|, |dxi| seen in training, the yardstick for
    divergence; info: robot, motion, dt, training configuration, solver, seeds,
    data hash."""

    autoencoder: LinearAutoencoder
    library: CandidateLibrary
    phase_names: list[str]
    Xi: np.ndarray
    mask: np.ndarray
    latent_scale: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        P, p, l = len(self.phase_names), self.library.n_features, self.autoencoder.latent_dim
        if self.library.latent_dim != l:
            raise ValueError(f"library latent_dim {self.library.latent_dim} != autoencoder's {l}")
        for name, arr in (("Xi", self.Xi), ("mask", self.mask)):
            if np.shape(arr) != (P, p, l):
                raise ValueError(f"{name}: shape {np.shape(arr)}, expected {(P, p, l)}")
        if np.shape(self.latent_scale) != (2 * l,):
            raise ValueError(f"latent_scale: shape {np.shape(self.latent_scale)}, expected {(2 * l,)}")

    @property
    def latent_dim(self) -> int:
        return self.autoencoder.latent_dim

    def active_terms(self) -> dict[str, int]:
        """Number of nonzero coefficients per phase."""
        return {n: int(self.mask[i].sum()) for i, n in enumerate(self.phase_names)}

    def latent_acceleration(self, xi: np.ndarray, dxi: np.ndarray, nu: np.ndarray,
                            phase: np.ndarray) -> np.ndarray:
        """ddxi (N, l) from xi, dxi, nu (N, l) and phase indices (N,)."""
        theta = self.library.transform(xi, dxi, nu)  # (N, p)
        return np.einsum("np,npl->nl", theta, self.Xi[np.asarray(phase)])

    def equations(self, digits: int = 3) -> dict[str, list[sympy.Expr]]:
        """Per phase, the l right-hand sides of ddxi_j, coefficients rounded to ``digits``
        significant digits."""
        feats = self.library.sympy_features()
        out = {}
        for k, name in enumerate(self.phase_names):
            rhs = []
            for j in range(self.latent_dim):
                terms = [sympy.Float(float(f"{c:.{digits}g}"), digits) * f
                         for c, f in zip(self.Xi[k][:, j], feats) if c != 0]
                rhs.append(sympy.Add(*terms) if terms else sympy.Integer(0))
            out[name] = rhs
        return out

    def equations_text(self, latex: bool = False, digits: int = 3) -> str:
        """All phases' equations as plain text (or LaTeX)."""
        lines = []
        l = self.latent_dim
        names = {sympy.Symbol(f"{v}{i}"): tex for i in range(1, l + 1) for v, tex in
                 (("xi", rf"\xi_{{{i}}}"), ("dxi", rf"\dot{{\xi}}_{{{i}}}"), ("nu", rf"\nu_{{{i}}}"))}
        for phase, rhs in self.equations(digits).items():
            lines.append(f"% phase: {phase}" if latex else f"[{phase}]")
            for j, e in enumerate(rhs, start=1):
                if latex:
                    lines.append(rf"\ddot{{\xi}}_{{{j}}} = {sympy.latex(e, symbol_names=names)}")
                else:
                    lines.append(f"ddxi{j} = {sympy.sstr(e)}")
        return "\n".join(lines)
