"""Learned contact switching: one sparse symbolic guard per transition of the phase graph.

A guard of the transition ``source -> target`` is an affine function of at
most two features of the latent state and inputs, z = [xi, dxi, nu] (3l):
g(z) = bias + sum_i w_i z_i. While the model is in ``source`` and has stayed
there at least ``min_dwell_s``, the first sample k at which g(z_k) >= 0
switches it to ``target`` (the step from k on is taken in ``target``). When
several guards of one phase fire at the same sample, the largest g wins.

By default a guard reads the latent state only (``fit_guards``' ``use_inputs``
says why). Fitting reads the logged transitions of the training jumps:
every stay in ``source`` is a window of samples from its start plus the dwell
to the jump's end. A candidate guard predicts, on the logged states, the first
sample of each window at which it fires; its loss is the mean timing error
(s) over the windows: |fire - switch| on stays that end in ``target``, firing
before the switch on stays that end in another phase, firing at all on stays
the jump ends in. Candidates are the levels of one feature (either sign, the
level the loss minimiser over a grid of quantiles) and linear boundaries of
two of the best single features (directions every 10 degrees on standardised
features, then the level), scored on at most ``MAX_WINDOWS`` stays per
transition (evenly spaced). The single best on the validation jumps is kept
unless a pair brings the validation loss below ``PAIR_GAIN`` of it (sparsity
first); without validation jumps, the training loss decides. The dwell is half
the shortest training stay ending in the transition: it keeps a condition that
already holds at a phase's start from firing at once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import numpy as np
import sympy

from symrom.model.library import input_names, state_names

PAIR_GAIN = 0.8  # a two-feature guard must bring the validation loss below this share of one feature's
LEVELS = 64  # quantiles of a candidate's values tried as its level
ANGLES = 36  # directions of a two-feature boundary (every 10 degrees)
TOP_SINGLE = 6  # the best single features whose pairs are tried
DWELL_SHARE = 0.5  # min_dwell_s: this share of the shortest training stay ending in the transition
EPS_T = 1e-12  # s, rounding allowance of the dwell test (the same in every export)
MAX_WINDOWS = 200  # stays per transition a candidate is scored on (evenly spaced beyond): bounds the fit's time


def feature_names(l: int) -> list[str]:
    """Names of z = [xi, dxi, nu] (3l): xi1.., dxi1.., nu1.."""
    return state_names(l) + input_names(l)


@dataclass
class Guard:
    """The switch ``source -> target`` (phase names): fires when
    ``bias + sum(weights[i] * z[terms[i]]) >= 0`` after ``min_dwell_s`` (s) in ``source``.
    terms: feature names (``feature_names``), weights (k,) per unit of the feature;
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
        if len(self.terms) != self.weights.size or not self.terms:
            raise ValueError(f"guard {self.source}->{self.target}: {len(self.terms)} terms, "
                             f"{self.weights.size} weights")
        if not (np.isfinite(self.weights).all() and np.isfinite(self.bias) and self.min_dwell_s >= 0):
            raise ValueError(f"guard {self.source}->{self.target}: weights, bias and dwell must be finite "
                             "(dwell >= 0)")

    def indices(self, l: int) -> np.ndarray:
        """Columns of ``terms`` in z (3l)."""
        names = feature_names(l)
        bad = [t for t in self.terms if t not in names]
        if bad:
            raise ValueError(f"guard {self.source}->{self.target}: term {bad[0]!r} is not one of {names}")
        return np.array([names.index(t) for t in self.terms])

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
        """The firing condition as text: ``nu3 <= -12.3`` for one feature, ``... >= 0`` for two."""
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
        """One line: the transition, its condition and dwell."""
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


def switch(guards: list[Guard], phase_names: list[str], phase: int, k_in: int, dt: float,
           z: np.ndarray) -> int:
    """The phase index after sample z (3l,) in phase ``phase`` entered ``k_in`` samples ago:
    the target of the firing guard of ``phase`` with the largest g, or ``phase``."""
    best, best_g = phase, -np.inf
    name = phase_names[phase]
    for g in guards:
        if g.source != name or not dwell_ok(k_in, dt, g):
            continue
        v = float(g.value(z))
        if v >= 0 and v > best_g:
            best, best_g = phase_names.index(g.target), v
    return best


def first_switch(guards: list[Guard], phase_names: list[str], phase: int, k_enter: int, dt: float,
                 Z: np.ndarray, start: int) -> tuple[int, int] | None:
    """Along a path Z (n, 3l) held in ``phase`` (entered at sample ``k_enter``), the first
    sample k >= ``start`` at which a guard of ``phase`` fires and the target it switches to
    (largest g), or None. The vectorised form of ``switch``."""
    name = phase_names[phase]
    mine = [g for g in guards if g.source == name]
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


# ------------------------------------------------------------------ fitting
@dataclass
class _Stay:
    """One logged stay: rows [start, stop) of the stacked z in the source phase, the
    jump's end ``end`` (exclusive) and the phase after it (-1: the jump ended in it)."""

    start: int
    stop: int
    end: int
    after: int


def stays(phase: np.ndarray, bounds: np.ndarray) -> list[_Stay]:
    """Every contiguous run of one phase within the jumps ``bounds`` (J, 2) of ``phase`` (N,)."""
    out = []
    for a, b in bounds:
        p = phase[a:b]
        cut = np.flatnonzero(np.diff(p)) + 1
        starts, stops = np.r_[0, cut], np.r_[cut, b - a]
        for s, e in zip(starts, stops):
            out.append(_Stay(a + int(s), a + int(e), int(b), int(p[e]) if e < b - a else -1))
    return out


def _windows(all_stays: list[_Stay], phase: np.ndarray, src: int, tgt: int, dwell: int
             ) -> list[tuple[int, int, int, int]]:
    """Per stay in ``src``: (first eligible row, end row, switch offset, kind) with kind 0 for
    a stay ending in ``tgt``, 1 for one ending in another phase, 2 for one the jump ends in."""
    out = []
    for s in all_stays:
        if phase[s.start] != src:
            continue
        a = min(s.start + dwell, s.end - 1)
        kind = 0 if s.after == tgt else 2 if s.after < 0 else 1
        out.append((a, s.end, s.stop - a, kind))
    return out


def _thin(windows: list) -> list:
    """At most ``MAX_WINDOWS`` of ``windows``, evenly spaced."""
    if len(windows) <= MAX_WINDOWS:
        return windows
    return [windows[int(i)] for i in np.linspace(0, len(windows) - 1, MAX_WINDOWS)]


def _losses(p: np.ndarray, windows: list, levels: np.ndarray, dt: float) -> np.ndarray:
    """Mean timing loss (s) (len(levels),) of the guard ``p >= level`` on the windows."""
    total = np.zeros(levels.size)
    for a, end, e, kind in windows:
        r = np.maximum.accumulate(p[a:end])
        kf = np.searchsorted(r, levels, side="left")  # first sample with p >= level (len: never)
        L = end - a
        if kind == 0:
            err = np.where(kf < L, np.abs(kf - e), max(L - e, 1))
        elif kind == 1:
            err = np.maximum(e - kf, 0)
        else:
            err = np.where(kf < L, L - kf, 0)
        total += err
    return total * dt / max(len(windows), 1)


def _grid(p: np.ndarray, windows: list) -> np.ndarray:
    """Candidate levels: quantiles of ``p`` at the switch samples and over the windows."""
    at = [a + e for a, end, e, kind in windows if kind == 0 and a + e < end]
    rows = np.concatenate([np.arange(a, end) for a, end, _, _ in windows])
    qs = np.linspace(0, 1, LEVELS)
    vals = np.r_[np.quantile(p[at], qs) if at else [], np.quantile(p[rows], qs)]
    return np.unique(vals[np.isfinite(vals)])


def _fit_level(p: np.ndarray, train: list, val: list, dt: float) -> tuple[float, float, float]:
    """(level, train loss, val loss (nan without val windows)) of the best level of ``p``."""
    levels = _grid(p, train)
    loss = _losses(p, train, levels, dt)
    i = int(np.argmin(loss))
    c = float(levels[i])
    v = float(_losses(p, val, np.array([c]), dt)[0]) if val else float("nan")
    return c, float(loss[i]), v


def fit_guards(Z: np.ndarray, phase: np.ndarray, train_bounds: np.ndarray, val_bounds: np.ndarray,
               phase_names: list[str], dt: float, trained: list[str] | None = None,
               use_inputs: bool = False) -> list[Guard]:
    """One guard per transition seen in the training jumps.

    Z (N, 3l): [xi, dxi, nu] of every row; phase (N,): the model's phase index per row;
    train_bounds, val_bounds (J, 2): ``[start, stop)`` rows of the training and validation
    jumps; dt: s; trained: the phases a guard may switch into (default: all); use_inputs:
    let guards read nu too (off by default: a dataset's wrench is computed with its logged
    contact flags, so on logged data an input feature reads the switch it should predict,
    and a planner's inputs would not carry it).
    """
    l = Z.shape[1] // 3
    names = feature_names(l)
    train_stays, val_stays = stays(phase, train_bounds), stays(phase, val_bounds)
    pairs = sorted({(int(phase[s.start]), s.after) for s in train_stays if s.after >= 0})
    spread = np.maximum(Z[np.concatenate([np.arange(a, b) for a, b in train_bounds])].std(axis=0), 1e-12)
    out = []
    for src, tgt in pairs:
        if trained is not None and phase_names[tgt] not in trained:
            continue
        lengths = [s.stop - s.start for s in train_stays if phase[s.start] == src and s.after == tgt]
        dwell = int(np.floor(DWELL_SHARE * min(lengths)))
        tw = _thin(_windows(train_stays, phase, src, tgt, dwell))
        vw = _thin(_windows(val_stays, phase, src, tgt, dwell))
        single = []  # (val-or-train loss, train loss, val loss, terms idx, weights, level)
        for i in range(3 * l if use_inputs else 2 * l):
            for sign in (1.0, -1.0):
                c, lt, lv = _fit_level(sign * Z[:, i], tw, vw, dt)
                single.append((lv if vw else lt, lt, lv, (i,), np.array([sign]), c))
        single.sort(key=lambda r: (r[0], r[1]))
        best = single[0]
        top = []
        for r in single:
            if r[3][0] not in top:
                top.append(r[3][0])
        pair_best = None
        for i, j in combinations(sorted(top[:TOP_SINGLE]), 2):
            for th in np.arange(ANGLES) * 2 * np.pi / ANGLES:
                w = np.array([np.cos(th) / spread[i], np.sin(th) / spread[j]])
                c, lt, lv = _fit_level(Z[:, [i, j]] @ w, tw, vw, dt)
                cand = (lv if vw else lt, lt, lv, (i, j), w, c)
                if pair_best is None or cand[:2] < pair_best[:2]:
                    pair_best = cand
        chosen = best
        if pair_best is not None and pair_best[0] < PAIR_GAIN * best[0]:
            chosen = pair_best
        _, lt, lv, idx, w, c = chosen
        report = {"train_loss_s": lt, "val_loss_s": None if np.isnan(lv) else lv,
                  "single_loss_s": best[0], "pair_loss_s": None if pair_best is None else pair_best[0],
                  "n_train_switches": len(lengths), "n_val_stays": len(vw),
                  "selected_on": "val" if vw else "train"}
        out.append(Guard(phase_names[src], phase_names[tgt], [names[i] for i in idx], w, -c,
                         dwell * dt, report))
    return out
