"""Learned contact switching: one sparse symbolic guard per transition of the phase graph.

A guard of the transition ``source -> target`` is an affine function of at
most two features of the latent state and inputs, z = [xi, dxi, nu] (3l):
g(z) = bias + sum_i w_i z_i. While the model is in ``source`` and has stayed
there at least ``min_dwell_s``, the first sample k at which g(z_k) >= 0
switches it to ``target`` (the step from k on is taken in ``target``). When
several guards of one phase fire at the same sample, the largest g wins.

A guard of no terms (and bias 0) is a *clock*: it fires as soon as the dwell
has passed, whatever the state. It stands for a switch a controller makes on
its own schedule (the froggy's front feet lift a set time after the push
begins), which no feature of the state marks. ``symrom.learn`` offers it only
between two stance phases; a planner refuses it for lift-off and touchdown
(``symrom.plan.guards.LearnedGuards``).

A motion's jump passes through its phases in one order (``symrom.motions``: a
pronk's contact, flight, contact). Along such a sequence of phase indices a
prediction keeps its *stage*, the place in the sequence it is at: from stage i
only guards into a phase later in the sequence may fire (``sequence_targets``),
and a switch moves to that phase's first place after i (``advance``). So each
transition is taken once, and a phase the motion has left is never entered
again; at the last stage nothing switches. Stage -1: no sequence, every guard
of the phase may fire.

This module holds the guard as a record of the model and how guards decide
(``switch``, ``first_switch``, ``dwell_ok``, the stages); ``symrom.learn.guards``
fits them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy

from symrom.model.library import input_names, state_names

EPS_T = 1e-12  # s, rounding allowance of the dwell test (the same in every export)


def feature_names(l: int) -> list[str]:
    """Names of z = [xi, dxi, nu] (3l): xi1.., dxi1.., nu1.."""
    return state_names(l) + input_names(l)


@dataclass
class Guard:
    """The switch ``source -> target`` (phase names): fires when
    ``bias + sum(weights[i] * z[terms[i]]) >= 0`` after ``min_dwell_s`` (s) in ``source``.
    terms: feature names (``feature_names``), weights (k,) per unit of the feature; no terms
    (and bias 0): a clock, firing once ``min_dwell_s`` has passed;
    report: the fit's record (losses in s on train and val, candidates tried)."""

    source: str
    target: str
    terms: list[str]
    weights: np.ndarray
    bias: float
    min_dwell_s: float
    report: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.weights = np.asarray(self.weights, dtype=float).reshape(-1)
        if len(self.terms) != self.weights.size:
            raise ValueError(f"guard {self.source}->{self.target}: {len(self.terms)} terms, "
                             f"{self.weights.size} weights")
        if not self.terms and self.bias != 0.0:
            raise ValueError(f"guard {self.source}->{self.target}: a clock (no terms) has bias 0, "
                             f"got {self.bias!r}")
        if not (np.isfinite(self.weights).all() and np.isfinite(self.bias) and self.min_dwell_s >= 0):
            raise ValueError(f"guard {self.source}->{self.target}: weights, bias and dwell must be finite "
                             "(dwell >= 0)")

    def indices(self, l: int) -> np.ndarray:
        """Columns of ``terms`` in z (3l)."""
        names = feature_names(l)
        bad = [t for t in self.terms if t not in names]
        if bad:
            raise ValueError(f"guard {self.source}->{self.target}: term {bad[0]!r} is not one of {names}")
        return np.array([names.index(t) for t in self.terms], dtype=np.int64)

    @property
    def clock(self) -> bool:
        """Whether the guard reads no feature: it fires once its dwell has passed."""
        return not self.terms

    def value(self, z: np.ndarray) -> np.ndarray:
        """g (N,) at z (N, 3l) (or (3l,) -> scalar array)."""
        z = np.asarray(z, dtype=float)
        l = z.shape[-1] // 3
        return self.bias + z[..., self.indices(l)] @ self.weights

    def expression(self, digits: int | None = None) -> sympy.Expr:
        """g as a sympy expression of the feature symbols (coefficients rounded to ``digits``
        significant digits, or exact)."""
        def num(c: float) -> sympy.Expr:
            return sympy.Float(repr(float(c)), 17) if digits is None else sympy.Float(float(f"{c:.{digits}g}"), digits)
        return num(self.bias) + sympy.Add(*[num(w) * sympy.Symbol(t) for w, t in zip(self.weights, self.terms)])

    def condition(self, latex: bool = False, digits: int = 3) -> str:
        """The firing condition as text: ``nu3 <= -12.3`` for one feature, ``... >= 0`` for two,
        ``t >= 0.858`` (s in the source phase) for a clock."""
        if self.clock:
            if latex:
                src = self.source.replace("_", r"\_")
                return rf"t_{{\mathrm{{{src}}}}} \geq {self.min_dwell_s:.{digits}g}\,\mathrm{{s}}"
            return f"t >= {self.min_dwell_s:.{digits}g} s"
        if len(self.terms) == 1:
            w, t = float(self.weights[0]), self.terms[0]
            level = -self.bias / w
            op = (">=" if w > 0 else "<=") if not latex else (r"\geq" if w > 0 else r"\leq")
            lhs = sympy.latex(sympy.Symbol(t), symbol_names=_tex_names(t)) if latex else t
            return f"{lhs} {op} {level:.{digits}g}"
        scale = float(np.max(np.abs(self.weights)))
        expr = Guard(self.source, self.target, self.terms, self.weights / scale, self.bias / scale,
                     self.min_dwell_s).expression(digits)
        if latex:
            names = {}
            for t in self.terms:
                names |= _tex_names(t)
            return rf"{sympy.latex(expr, symbol_names=names)} \geq 0"
        return f"{sympy.sstr(expr)} >= 0"

    def text(self, latex: bool = False, digits: int = 3) -> str:
        """One line: the transition, its condition and dwell (a clock: its time in the source)."""
        if self.clock:
            if latex:
                src, tgt = (n.replace("_", r"\_") for n in (self.source, self.target))
                return rf"\mathrm{{{src}}} \to \mathrm{{{tgt}}}:\ {self.condition(True, digits)}"
            return f"{self.source} -> {self.target}: after {self.min_dwell_s:.{digits}g} s in {self.source}"
        if latex:
            src, tgt = (n.replace("_", r"\_") for n in (self.source, self.target))
            return (rf"\mathrm{{{src}}} \to \mathrm{{{tgt}}}:\ {self.condition(True, digits)} "
                    rf"\quad (t_{{\mathrm{{{src}}}}} \geq {self.min_dwell_s:.3g}\,\mathrm{{s}})")
        return (f"{self.source} -> {self.target}: when {self.condition(False, digits)} "
                f"(after {self.min_dwell_s:.3g} s in {self.source})")

    def to_dict(self) -> dict:
        return {"source": self.source, "target": self.target, "terms": list(self.terms),
                "weights": self.weights.tolist(), "bias": float(self.bias),
                "min_dwell_s": float(self.min_dwell_s), "report": self.report}

    @classmethod
    def from_dict(cls, d: dict, where: str = "guards") -> Guard:
        try:
            return cls(str(d["source"]), str(d["target"]), [str(t) for t in d["terms"]],
                       np.asarray(d["weights"], dtype=float), float(d["bias"]), float(d["min_dwell_s"]),
                       dict(d.get("report", {})))
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"{where}: {e}") from None


def _tex_names(t: str) -> dict:
    i = "".join(c for c in t if c.isdigit())
    base = {"xi": rf"\xi_{{{i}}}", "dxi": rf"\dot{{\xi}}_{{{i}}}", "nu": rf"\nu_{{{i}}}"}[t.rstrip("0123456789")]
    return {sympy.Symbol(t): base}


# ------------------------------------------------------------------ switching
def dwell_ok(k_in: int, dt: float, guard: Guard) -> bool:
    """Whether ``k_in`` samples in the source phase (dt s each) pass the guard's dwell."""
    return k_in * dt + EPS_T >= guard.min_dwell_s


def sequence_targets(sequence: tuple[int, ...], stage: int) -> frozenset[int] | None:
    """The phase indices a switch may go to from ``stage`` of ``sequence`` (phase indices):
    those later in it (none at its end); None (any) at stage -1."""
    if stage < 0:
        return None
    return frozenset(sequence[stage + 1:])


def advance(sequence: tuple[int, ...], stage: int, target: int) -> int:
    """The stage after a switch into phase ``target`` from ``stage``: its first place after
    ``stage`` in ``sequence`` (-1 stays -1)."""
    if stage < 0:
        return -1
    return stage + 1 + sequence[stage + 1:].index(target)


def first_stage(sequence: tuple[int, ...], phase: int) -> int:
    """The stage of a path starting in ``phase``: its first place in ``sequence``, -1 if it
    has none (then every guard may fire)."""
    return sequence.index(phase) if phase in sequence else -1


def stage_along(sequence: tuple[int, ...], phases: np.ndarray) -> int:
    """The stage after a path's phases (n,) so far: its first phase's place, advanced at each
    change; -1 if the path leaves the sequence (no sequence, or a phase out of its order)."""
    phases = np.asarray(phases)
    if phases.size == 0:
        return -1
    stage = first_stage(sequence, int(phases[0]))
    for k in np.flatnonzero(np.diff(phases)) + 1:
        allowed = sequence_targets(sequence, stage)
        if allowed is None or int(phases[k]) not in allowed:
            return -1
        stage = advance(sequence, stage, int(phases[k]))
    return stage


def switch(guards: list[Guard], phase_names: list[str], phase: int, k_in: int, dt: float,
           z: np.ndarray, targets: frozenset[int] | None = None) -> int:
    """The phase index after sample z (3l,) in phase ``phase`` entered ``k_in`` samples ago:
    the target of the firing guard of ``phase`` with the largest g, or ``phase``; only guards
    into ``targets`` (phase indices; None: any) may fire."""
    best, best_g = phase, -np.inf
    name = phase_names[phase]
    for g in guards:
        if g.source != name or not dwell_ok(k_in, dt, g):
            continue
        if targets is not None and phase_names.index(g.target) not in targets:
            continue
        v = float(g.value(z))
        if v >= 0 and v > best_g:
            best, best_g = phase_names.index(g.target), v
    return best


def first_switch(guards: list[Guard], phase_names: list[str], phase: int, k_enter: int, dt: float,
                 Z: np.ndarray, start: int, targets: frozenset[int] | None = None) -> tuple[int, int] | None:
    """Along a path Z (n, 3l) held in ``phase`` (entered at sample ``k_enter``), the first
    sample k >= ``start`` at which a guard of ``phase`` into ``targets`` (None: any) fires and
    the target it switches to (largest g), or None. The vectorised form of ``switch``."""
    name = phase_names[phase]
    mine = [g for g in guards if g.source == name
            and (targets is None or phase_names.index(g.target) in targets)]
    if not mine or start >= len(Z):
        return None
    k = np.arange(start, len(Z))
    G = np.full((len(mine), k.size), -np.inf)
    for i, g in enumerate(mine):
        ok = (k - k_enter) * dt + EPS_T >= g.min_dwell_s
        with np.errstate(invalid="ignore"):
            G[i, ok] = g.value(Z[k[ok]])
    G[~np.isfinite(G)] = -np.inf
    fired = (G >= 0).any(axis=0)
    if not fired.any():
        return None
    at = int(np.flatnonzero(fired)[0])
    return int(k[at]), phase_names.index(mine[int(np.argmax(G[:, at]))].target)
