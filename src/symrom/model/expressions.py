"""The latent dynamics as sympy expressions: the one builder behind the printed
equations (``Equations``, what ``HybridModel.equations`` gives), the generated code
(``symrom.compiled``, through ``latent_dynamics``) and the exports (``symrom.export``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

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


class Equations(Mapping):
    """A model's equations, the one shape ``HybridModel.equations`` and ``SymbolicROM.equations``
    give: a mapping from each phase's name to its l right-hand sides ddxi_j (sympy, coefficients
    rounded to ``digits`` significant digits), with the contact switches (``guards``: objects
    with ``text(latex, digits)``) and what each latent reads (``loadings``: per latent, its
    largest encoder weights ``[(component, weight per rad or m), ...]`` and how many more pass).

    ``str()`` (``text()``) is the plain text of a model folder's ``equations.txt``; ``latex()``
    the same in LaTeX."""

    def __init__(self, phases: dict[str, list[sympy.Expr]], guards=(), loadings=(), digits: int = 3) -> None:
        self._phases = {k: tuple(v) for k, v in phases.items()}
        self.guards = tuple(guards)
        self.loadings = tuple(loadings)
        self.digits = digits

    def __getitem__(self, phase: str) -> tuple[sympy.Expr, ...]:
        return self._phases[phase]

    def __iter__(self):
        return iter(self._phases)

    def __len__(self) -> int:
        return len(self._phases)

    def __repr__(self) -> str:
        return f"Equations({', '.join(self._phases)}; {self.digits} digits)"

    def __str__(self) -> str:
        return self.text()

    def legend(self, latex: bool = False) -> list[str]:
        """One line per latent naming it by its largest encoder loadings: ``xi1 ~ 1.00 x``
        (LaTeX: ``% \\xi_{1} \\approx 1.00 x``, a comment)."""
        lines = []
        for i, (terms, more) in enumerate(self.loadings, start=1):
            text = " ".join(f"{w:.2f} {name}" if k == 0 else f"{'-' if w < 0 else '+'} {abs(w):.2f} {name}"
                            for k, (name, w) in enumerate(terms))
            tail = f" + ... ({more} more)" if more else ""
            if latex:
                tex = text.replace("_", "\\_")
                lines.append(rf"% \xi_{{{i}}} \approx {tex}{tail}")
            else:
                lines.append(f"xi{i} ~ {text}{tail}")
        return lines

    def text(self, latex: bool = False) -> str:
        """All phases' equations as plain text (or LaTeX), then the contact switches and what
        each latent reads."""
        lines = []
        l = len(self.loadings) or max((len(v) for v in self._phases.values()), default=0)
        names = {sympy.Symbol(f"{v}{i}"): tex for i in range(1, l + 1) for v, tex in
                 (("xi", rf"\xi_{{{i}}}"), ("dxi", rf"\dot{{\xi}}_{{{i}}}"), ("nu", rf"\nu_{{{i}}}"))}
        for phase, rhs in self._phases.items():
            lines.append(f"% phase: {phase}" if latex else f"[{phase}]")
            for j, e in enumerate(rhs, start=1):
                if latex:
                    lines.append(rf"\ddot{{\xi}}_{{{j}}} = {sympy.latex(e, symbol_names=names)}")
                else:
                    lines.append(f"ddxi{j} = {sympy.sstr(e)}")
        if self.guards:
            lines.append("% contact switches (guards):" if latex else "contact switches (guards):")
            lines += [g.text(latex, self.digits) for g in self.guards]
        lines.append("% latents, by their largest encoder loadings (per rad or m):" if latex
                     else "latents, by their largest encoder loadings (per rad or m):")
        lines += self.legend(latex)
        return "\n".join(lines)

    def latex(self) -> str:
        return self.text(latex=True)
