"""Markdown tables in the layout of the paper's Table 2."""

from __future__ import annotations

from symrom.evaluate.records import Metrics
from symrom.names import Q_UNITS, TABLE2_COMPONENTS


def fmt_value(x: float) -> str:
    """Two significant digits as in the paper: 1.3e-2, 0.11."""
    if x == 0:
        return "0"
    a = abs(x)
    return f"{x:.2f}" if 0.1 <= a < 100 else f"{x:.1e}".replace("e-0", "e-").replace("e+0", "e")


def as_metrics(metrics: Metrics | dict) -> Metrics:
    """A ``Metrics`` record, read from a ``metrics.json`` object if it is one."""
    return metrics if isinstance(metrics, Metrics) else Metrics.from_dict(metrics)


def divergence_note(metrics: Metrics | dict) -> str:
    """One sentence on the diverged jumps of the metrics, with when each diverged ('' if
    none), e.g. 'Diverged: Full: jump 4 at 1.438 s; scored up to the divergence (97.1 % of
    the samples).'"""
    m = as_metrics(metrics)
    parts = []
    for key, h in m.horizons.items():
        if not h.diverged_jumps:
            continue
        label = "Full" if key == "full" else f"{key} s"
        when = h.divergence_text() or f"{h.diverged_jumps} jumps"
        share = (f" ({100 * h.scored_samples / h.samples:.1f} % of the samples)"
                 if m.scores_diverged and h.samples and h.scored_samples is not None else "")
        parts.append(f"{label}: {when}; " + (f"scored up to the divergence{share}" if m.scores_diverged
                                             else "left out of the statistics"))
    return ("Diverged: " + "; ".join(parts) + ".") if parts else ""


def drift_note(metrics: Metrics | dict) -> str:
    """One sentence on the drifted jumps of the metrics ('' if none or not checked)."""
    parts = [f"{'Full' if key == 'full' else f'{key} s'}: {h.drift_text()}"
             for key, h in as_metrics(metrics).horizons.items() if h.drifted_jumps]
    return ("Drifted (left the physically possible: below the ground by more than a leg length, or "
            "beyond the jump's range; still scored): " + "; ".join(parts) + ".") if parts else ""


def table2(metrics: Metrics | dict, components: tuple[str, ...] = TABLE2_COMPONENTS, title: str = "") -> str:
    """Signed mean ± std per component and horizon, then MAE and RMSE rows; lines under the
    table say when each diverged jump left its bound and how it was scored, and when each
    drifted jump left the physically possible."""
    m = as_metrics(metrics)
    head = "| horizon | stat | " + " | ".join(f"{c} [{Q_UNITS.get(c, '')}]" for c in components) + " |"
    lines = ([f"**{title}**", ""] if title else []) + [head, "|" + "---|" * (len(components) + 2)]
    for key, h in m.horizons.items():
        label = "Full" if key == "full" else f"{key} s"
        comps = h.components
        if not comps:
            lines.append(f"| {label} | all jumps diverged ({h.diverged_jumps}) |" + " |" * len(components))
            continue
        marks = [f"{h.diverged_jumps} diverged"] if h.diverged_jumps else []
        marks += [f"{h.drifted_jumps} drifted"] if h.drifted_jumps else []
        div = f" ({', '.join(marks)})" if marks else ""
        lines.append(f"| {label}{div} | mean±std | " + " | ".join(
            f"{fmt_value(comps[c].mean)}±{fmt_value(comps[c].std)}" for c in components) + " |")
        for stat in ("mae", "rmse"):
            lines.append(f"| {label} | {stat.upper()} | "
                         + " | ".join(fmt_value(getattr(comps[c], stat)) for c in components) + " |")
    notes = [n for n in (divergence_note(m), drift_note(m)) if n]
    return "\n".join(lines + [x for n in notes for x in ("", n)]) + "\n"
