"""Fitting the contact guards (``symrom.model.guards``) to the logged transitions.

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

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from symrom.model.guards import Guard, feature_names

PAIR_GAIN = 0.8  # a two-feature guard must bring the validation loss below this share of one feature's
LEVELS = 64  # quantiles of a candidate's values tried as its level
ANGLES = 36  # directions of a two-feature boundary (every 10 degrees)
TOP_SINGLE = 6  # the best single features whose pairs are tried
DWELL_SHARE = 0.5  # min_dwell_s: this share of the shortest training stay ending in the transition
MAX_WINDOWS = 200  # stays per transition a candidate is scored on (evenly spaced beyond): bounds the fit's time


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
