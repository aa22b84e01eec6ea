"""Fitting the contact guards (``symrom.model.guards``) to the logged transitions.

By default a guard reads the latent state only (``fit_guards``' ``use_inputs``
says why). Fitting reads the logged transitions of the training jumps:
every stay in ``source`` is a window of samples from its start plus the dwell
to the jump's end. A candidate guard predicts, on the logged states, the first
sample of each window at which it fires; its loss is the mean timing error
(s) over the windows: |fire - switch| on stays that end in ``target``, firing
before the switch on stays that end in another phase, firing at all on stays
the jump ends in. Candidates are the levels of one feature (either sign, the
level the loss minimiser over a grid of quantiles, over at most ``GRID_ROWS``
rows) and linear boundaries of
two of the best single features (directions every 10 degrees on standardised
features, then the level), scored on at most ``MAX_WINDOWS`` stays per
transition (evenly spaced). The single best on the validation jumps is kept
unless a pair brings the validation loss below ``PAIR_GAIN`` of it (sparsity
first); without validation jumps, the training loss decides. The dwell is half
the shortest training stay ending in the transition: it keeps a condition that
already holds at a phase's start from firing at once. The losses of many levels
come from one pass per window (``symrom.learn.compiled.timing_losses``).

A switch between two stance phases may be the controller's, on its own clock
(the froggy's front feet lift a set time after the push begins), and no state
marks it. Where a transition's stays are known by their place in the motion's
sequence (``symrom.learn.estimator.free_path_guards``), its finalists also hold
the clock (``CLOCK``: the time in the source phase, a ``Guard`` of no terms),
levelled like any feature and kept only if its validation loss is below the
state guard's.

A model predicts from its own states, not the logged ones, and its path drifts
from the logged one (a height a few millimetres off moves a touchdown by tens
of milliseconds). ``refit_guards`` therefore levels the finalists of the first
fit (``GuardFit.finalists``) again on the model's own rollouts of the same
jumps (the estimator does, ``symrom.learn.estimator``): the guard of the path
the model will follow.
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
GRID_ROWS = 8192  # rows whose quantiles are a candidate's levels (evenly spaced beyond): bounds the fit's time
REFIT_ROWS = 4096  # the same for a refit's finalists


CLOCK: tuple[tuple[int, ...], np.ndarray] = ((), np.zeros(0))  # the finalist that reads the time in the source


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


def clock(phase: np.ndarray, bounds: np.ndarray, dt: float, source: int) -> np.ndarray:
    """Per row (N,) of ``phase`` (N,), the time (s) since the last stay in phase ``source``
    began within its jump of ``bounds`` (J, 2): in a stay of ``source`` its time there, and past
    its end the time it would have had, had the model stayed (what a window reads beyond its
    logged switch); rows before any such stay, or outside every jump: 0."""
    out = np.zeros(phase.shape[0])
    mine = [s for s in stays(phase, bounds) if phase[s.start] == source]
    for s, nxt in zip(mine, mine[1:] + [None]):
        stop = nxt.start if nxt is not None and nxt.end == s.end else s.end  # the next such stay of its jump
        out[s.start:stop] = np.arange(stop - s.start) * dt
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


def _arrays(windows: list) -> tuple[np.ndarray, ...]:
    """The windows (a, end, switch offset, kind) as four int64 arrays, the kernel's layout."""
    if not windows:
        return tuple(np.zeros(0, dtype=np.int64) for _ in range(4))
    return tuple(np.ascontiguousarray(c, dtype=np.int64) for c in np.array(windows, dtype=np.int64).T)


def _grid(P: np.ndarray, windows: list, max_rows: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Candidate levels of every feature of P (F, N): the unique finite quantiles of the feature
    at the switch samples and over the windows' rows (at most ``max_rows`` of them, evenly
    spaced), ascending in the first n[f] entries of row f of levels (F, K) (the rest +inf);
    returns levels, n."""
    at = [a + e for a, end, e, kind in windows if kind == 0 and a + e < end]
    rows = np.concatenate([np.arange(a, end) for a, end, _, _ in windows])
    if max_rows is not None and rows.size > max_rows:
        rows = rows[np.linspace(0, rows.size - 1, max_rows).round().astype(int)]
    qs = np.linspace(0, 1, LEVELS)
    # Sorted first: the quantiles are the same numbers, and partitioning sorted rows is fast.
    vals = np.quantile(np.sort(P[:, rows], axis=1), qs, axis=1)  # (LEVELS, F)
    if at:
        vals = np.r_[np.quantile(np.sort(P[:, at], axis=1), qs, axis=1), vals]
    cols = [np.unique(v[np.isfinite(v)]) for v in vals.T]
    n = np.array([c.size for c in cols], dtype=np.int64)
    levels = np.full((len(cols), max(int(n.max()), 1)), np.inf)
    for f, c in enumerate(cols):
        levels[f, :c.size] = c
    return levels, n


def _losses(P: np.ndarray, windows: tuple, levels: np.ndarray, n: np.ndarray, dt: float) -> np.ndarray:
    """Mean timing loss (s) (F, K) of the guards ``P[f] >= levels[f, k]`` on the windows
    (``_arrays``); entries beyond n[f] are +inf."""
    from symrom.learn.compiled import timing_losses

    total = np.zeros(levels.shape, dtype=np.int64)
    timing_losses(np.ascontiguousarray(P), *windows, np.ascontiguousarray(levels), n, total)
    loss = total * dt / max(windows[0].size, 1)
    loss[np.arange(levels.shape[1])[None, :] >= n[:, None]] = np.inf
    return loss


def _fit_levels(P: np.ndarray, train: list, val: list, dt: float) -> list[tuple[float, float, float]]:
    """Per feature of P (F, N): (level, train loss, val loss (nan without val windows)) of its
    best level (the first of the smallest train loss)."""
    levels, n = _grid(P, train, GRID_ROWS)
    loss = _losses(P, _arrays(train), levels, n, dt)
    best = np.argmin(loss, axis=1)
    c = levels[np.arange(levels.shape[0]), best]
    lt = loss[np.arange(levels.shape[0]), best]
    if val:
        lv = _losses(P, _arrays(val), c[:, None], np.ones(c.size, dtype=np.int64), dt)[:, 0]
    else:
        lv = np.full(c.size, np.nan)
    return [(float(a), float(b), float(v)) for a, b, v in zip(c, lt, lv)]


@dataclass
class GuardFit:
    """The guards ``fit_guards`` chose and, per transition (source, target) as phase indices,
    its finalists: the features of the chosen guard, of the ``TOP_SINGLE`` best single features
    and of each pair's best direction, as (columns of z, weights): what ``refit_guards`` levels
    again on another path of the same jumps."""

    guards: list[Guard]
    finalists: dict[tuple[int, int], list[tuple[tuple[int, ...], np.ndarray]]]


def fit_guards(Z: np.ndarray, phase: np.ndarray, train_bounds: np.ndarray, val_bounds: np.ndarray,
               phase_names: list[str], dt: float, trained: list[str] | None = None,
               use_inputs: bool = False) -> list[Guard]:
    """One guard per transition seen in the training jumps (``guard_fit``'s guards)."""
    return guard_fit(Z, phase, train_bounds, val_bounds, phase_names, dt, trained, use_inputs).guards


def guard_fit(Z: np.ndarray, phase: np.ndarray, train_bounds: np.ndarray, val_bounds: np.ndarray,
              phase_names: list[str], dt: float, trained: list[str] | None = None,
              use_inputs: bool = False, barred: np.ndarray | None = None) -> GuardFit:
    """One guard per transition seen in the training jumps, and its finalists.

    Z (N, 3l): [xi, dxi, nu] of every row; phase (N,): the model's phase index per row;
    train_bounds, val_bounds (J, 2): ``[start, stop)`` rows of the training and validation
    jumps; dt: s; trained: the phases a guard may switch into (default: all); use_inputs:
    let guards read nu too (off by default: a dataset's wrench is computed with its logged
    contact flags, so on logged data an input feature reads the switch it should predict,
    and a planner's inputs would not carry it); barred (3l,) bool: columns of Z no guard may
    read (the latent positions that say where the robot stands, for a model held invariant
    to it).
    """
    l = Z.shape[1] // 3
    barred = np.zeros(3 * l, dtype=bool) if barred is None else np.asarray(barred, dtype=bool)
    names = feature_names(l)
    train_stays, val_stays = stays(phase, train_bounds), stays(phase, val_bounds)
    pairs = sorted({(int(phase[s.start]), s.after) for s in train_stays if s.after >= 0})
    spread = np.maximum(Z[np.concatenate([np.arange(a, b) for a, b in train_bounds])].std(axis=0), 1e-12)
    out, finalists = [], {}
    for src, tgt in pairs:
        if trained is not None and phase_names[tgt] not in trained:
            continue
        lengths = [s.stop - s.start for s in train_stays if phase[s.start] == src and s.after == tgt]
        dwell = int(np.floor(DWELL_SHARE * min(lengths)))
        tw = _thin(_windows(train_stays, phase, src, tgt, dwell))
        vw = _thin(_windows(val_stays, phase, src, tgt, dwell))
        single = []  # (val-or-train loss, train loss, val loss, terms idx, weights, level)
        cand = [(i, sign) for i in range(3 * l if use_inputs else 2 * l) if not barred[i] for sign in (1.0, -1.0)]
        fits = _fit_levels(np.stack([sign * Z[:, i] for i, sign in cand]), tw, vw, dt)
        for (i, sign), (c, lt, lv) in zip(cand, fits):
            single.append((lv if vw else lt, lt, lv, (i,), np.array([sign]), c))
        single.sort(key=lambda r: (r[0], r[1]))
        best = single[0]
        top = []
        for r in single:
            if r[3][0] not in top:
                top.append(r[3][0])
        pair_best, pair_each = None, []
        for i, j in combinations(sorted(top[:TOP_SINGLE]), 2):
            ws = [np.array([np.cos(th) / spread[i], np.sin(th) / spread[j]])
                  for th in np.arange(ANGLES) * 2 * np.pi / ANGLES]
            Zij = Z[:, [i, j]]
            P = np.empty((ANGLES, Z.shape[0]))
            for k, w in enumerate(ws):
                P[k] = Zij @ w
            fits = _fit_levels(P, tw, vw, dt)
            this = None
            for w, (c, lt, lv) in zip(ws, fits):
                cand = (lv if vw else lt, lt, lv, (i, j), w, c)
                if pair_best is None or cand[:2] < pair_best[:2]:
                    pair_best = cand
                if this is None or cand[:2] < this[:2]:
                    this = cand
            pair_each.append(this)
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
        finalists[(src, tgt)] = [(idx, w)] + [(r[3], r[4]) for r in single[:TOP_SINGLE]] + \
            [(r[3], r[4]) for r in pair_each]
    return GuardFit(out, finalists)


def refit_guards(fit: GuardFit, Z: np.ndarray, phase: np.ndarray, train_bounds: np.ndarray,
                 val_bounds: np.ndarray, phase_names: list[str], dt: float, source: str) -> list[Guard]:
    """The guards of ``fit`` fitted again on another path of the same jumps (``source`` names
    it in their reports: a model's own rollouts).

    Z (N, 3l), phase (N,), bounds, dt: as ``guard_fit``'s, the logged phases with the other
    path's states. Per transition, each finalist gets the level the timing loss on the new
    path's training stays likes best (candidate levels: ``LEVELS`` quantiles over at most
    ``REFIT_ROWS`` of its rows); the single best on the validation stays is kept unless a pair
    brings the loss below ``PAIR_GAIN`` of it, a finalist ``CLOCK`` (the time in the source phase)
    replaces that if its loss is lower, and the first fit's guard stays if it is as good on the
    new path. The dwell is the first fit's (a clock's: its level)."""
    l = Z.shape[1] // 3
    names = feature_names(l)
    train_stays, val_stays = stays(phase, train_bounds), stays(phase, val_bounds)
    every = np.r_[train_bounds, np.reshape(val_bounds, (-1, 2))]
    out = []
    for g in fit.guards:
        src, tgt = phase_names.index(g.source), phase_names.index(g.target)
        # each row's time in the source, if the guard or a finalist reads it
        t_in = clock(phase, every, dt, src) if g.clock or any(not idx for idx, _ in fit.finalists[(src, tgt)]) else None
        dwell = int(round(g.min_dwell_s / dt))
        tw = _thin(_windows(train_stays, phase, src, tgt, dwell))
        vw = _thin(_windows(val_stays, phase, src, tgt, dwell))
        if not any(kind == 0 for _, _, _, kind in tw):  # the new path holds none of its switches
            out.append(g)
            continue
        cands = fit.finalists[(src, tgt)]
        P = np.stack([Z[:, list(idx)] @ w if idx else t_in for idx, w in cands])
        levels, n = _grid(P, tw, REFIT_ROWS)
        loss = _losses(P, _arrays(tw), levels, n, dt)
        best = np.argmin(loss, axis=1)
        c = levels[np.arange(len(cands)), best]
        lt = loss[np.arange(len(cands)), best]
        use = vw if vw else tw
        lv = _losses(P, _arrays(use), c[:, None], np.ones(len(cands), dtype=np.int64), dt)[:, 0]
        # the first fit's guard, as it is, on the new path
        first = _losses((t_in if g.clock else Z[:, g.indices(l)] @ g.weights)[None], _arrays(use),
                        np.array([[g.min_dwell_s if g.clock else -g.bias]]), np.ones(1, dtype=np.int64), dt)[0, 0]
        order = sorted(range(len(cands)), key=lambda k: (lv[k], lt[k]))
        single = next((k for k in order if len(cands[k][0]) == 1), None)
        pair = next((k for k in order if len(cands[k][0]) == 2), None)
        k = single if single is not None else pair
        if pair is not None and single is not None and lv[pair] < PAIR_GAIN * lv[single]:
            k = pair
        ticking = next((k for k in order if not cands[k][0]), None)  # the clock, if offered
        if ticking is not None and (k is None or lv[ticking] < lv[k]):
            k = ticking
        if not lv[k] < first:
            out.append(g)
            continue
        idx, w = cands[k]
        report = {**g.report, "refit_on": source, "refit_train_loss_s": float(lt[k]),
                  "refit_val_loss_s": float(lv[k]) if vw else None, "first_fit_loss_s": float(first),
                  "selected_on": f"val ({source})" if vw else f"train ({source})"}
        if not idx:  # the clock: it fires at its level of time in the source
            out.append(Guard(g.source, g.target, [], [], 0.0, max(float(c[k]), g.min_dwell_s), report))
            continue
        out.append(Guard(g.source, g.target, [names[i] for i in idx], w, -float(c[k]), g.min_dwell_s, report))
    return out
