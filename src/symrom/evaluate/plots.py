"""Plots of true vs predicted joint angles and base pose for one jump (PNG)."""

from __future__ import annotations

import os
import threading

import numpy as np

from symrom.atomic import write_with
from symrom.data.dataset import Dataset
from symrom.names import Q_NAMES, Q_UNITS
from symrom.rollout.integrate import Rollout

JOINT_PANELS = ("fl_hx", "fl_hy", "fl_kn", "rr_hx", "rr_hy", "rr_kn")
BASE_PANELS = ("x", "y", "z", "roll", "pitch", "yaw")
_PHASE_COLOURS = ("#ffffff", "#dde8f6", "#f6e3cf", "#e2f0da")
_NCOL = 3  # panels per row


def shade_phases(ax, t: np.ndarray, phase: np.ndarray, names: list[str], seen: set) -> None:
    edges = np.flatnonzero(np.r_[True, np.diff(phase) != 0, True])
    for a, b in zip(edges[:-1], edges[1:]):
        k = int(phase[a])
        if k == 0:
            continue
        label = names[k] if names[k] not in seen else None
        seen.add(names[k])
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color=_PHASE_COLOURS[k % len(_PHASE_COLOURS)],
                   alpha=0.9, lw=0, label=label, zorder=0)


class _Panels:
    """The figure of one panel layout, kept by the process and drawn over for each jump.

    Most of a jump figure's time is matplotlib building its axes and their ticks. Drawn over
    (its curves, spans, legend and title replaced), the kept figure gives the same bytes as a
    new one in about two thirds of the time. A change of matplotlib's settings (``rcParams``)
    builds it anew."""

    _kept: dict[tuple[str, ...], _Panels] = {}
    lock = threading.Lock()  # one jump at a time on a kept figure, whatever the thread

    def __init__(self, components: tuple[str, ...], rc):
        from matplotlib.figure import Figure

        self.rc = rc
        nrow = int(np.ceil(len(components) / _NCOL))
        self.height = 2.5 * nrow  # in
        self.fig = Figure(figsize=(4.2 * _NCOL, self.height))
        self.axes = self.fig.subplots(nrow, _NCOL, sharex=True, squeeze=False)
        for ax in self.axes.ravel()[:len(components)]:
            ax.grid(alpha=0.3)
        for ax in self.axes[-1]:
            ax.set_xlabel("time [s]")
        for ax in self.axes.ravel()[len(components):]:
            ax.axis("off")

    @classmethod
    def of(cls, components: tuple[str, ...]) -> _Panels:
        """The kept figure for ``components``, built anew under changed ``rcParams``."""
        import matplotlib

        rc = matplotlib.rcParams.copy()
        kept = cls._kept.get(components)
        if kept is None or kept.rc != rc:
            kept = cls._kept[components] = cls(components, rc)
        return kept

    def clear(self) -> None:
        """Remove the last jump's curves, spans, legend and title; each panel's limits then
        follow what is drawn next, as a new panel's do."""
        for ax in self.axes.ravel():
            for artist in [*ax.lines, *ax.patches]:
                artist.remove()
            ax.relim()
        for legend in list(self.fig.legends):
            legend.remove()
        if self.fig.get_suptitle():
            self.fig.suptitle("")  # an empty title draws nothing


def plot_jump(ds: Dataset, rollouts: dict[str, Rollout], jump: int, path: str | os.PathLike,
              components: tuple[str, ...] = JOINT_PANELS + BASE_PANELS, title: str = "") -> None:
    """One panel per component: truth and each rollout (keyed by horizon) for ``jump``.

    Writes a PNG atomically; shaded spans mark the non-default phases.
    """
    components = tuple(components)
    with _Panels.lock:
        panels = _Panels.of(components)
        try:
            _draw(panels, ds, rollouts, jump, path, components, title)
        finally:
            panels.clear()


def _draw(panels: _Panels, ds: Dataset, rollouts: dict[str, Rollout], jump: int, path: str | os.PathLike,
          components: tuple[str, ...], title: str) -> None:
    fig, axes, height = panels.fig, panels.axes, panels.height
    a, b = ds.jump_bounds()[jump]
    t, phase = ds.t[a:b], ds.phase[a:b]
    # The full horizon is drawn dashed on top of a wide, pale reset line, so that where the
    # two agree both stay visible.
    styles = {"full": dict(color="C3", ls="--", lw=1.3, zorder=4)}
    reset_style = dict(ls="-", lw=2.6, alpha=0.55, zorder=3)
    seen: set = set()
    for ax, comp in zip(axes.ravel(), components):
        c = Q_NAMES.index(comp)
        shade_phases(ax, t, phase, ds.phase_names, seen)
        ax.plot(t, ds.q[a:b, c], color="k", lw=1.4, label="true", zorder=5)
        for i, (key, ro) in enumerate(rollouts.items()):
            idx = np.flatnonzero(ro.jumps == jump)
            if idx.size == 0:
                continue
            style = styles.get(key, dict(color="C0" if i <= 1 else f"C{i}", **reset_style))
            label = "predicted, full horizon" if key == "full" else f"predicted, {key} s resets"
            ax.plot(t, ro.q_pred[idx[0]][:, c], label=label, **style)
        ax.set_title(f"{comp} [{Q_UNITS[comp]}]", fontsize=10, y=1.0)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    for ax in axes.ravel()[1:]:
        for h, l in zip(*ax.get_legend_handles_labels()):
            if l not in labels:
                handles.append(h)
                labels.append(l)
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=9, frameon=False)
    if title:
        fig.suptitle(title)
    # Margins fixed in inches (the legend and the time axis below, the titles above): tight_layout
    # would draw the whole figure once more to measure it, as long as drawing it.
    fig.subplots_adjust(left=0.075, right=0.99, bottom=0.85 / height, top=1 - (0.7 if title else 0.4) / height,
                        wspace=0.3, hspace=0.32)
    write_with(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
