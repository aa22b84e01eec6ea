"""Small text helpers shared by the report's renderers."""

from __future__ import annotations

from symrom.evaluate.records import ComponentStats, Metrics
from symrom.evaluate.tables import fmt_value as fmt

__all__ = ["DASH", "diverged_text", "fmt", "horizon_label", "ms"]

DASH = "—"
HORIZON_LABELS = {"full": "Full", "0.1": "0.1 s"}


def horizon_label(key: str) -> str:
    """``Full`` or the reset period, e.g. ``0.1 s``."""
    return HORIZON_LABELS.get(key, f"{key} s")


def ms(stats: ComponentStats | None) -> str:
    """``mean±std`` of a component's stats as in the paper (two significant digits)."""
    return f"{fmt(stats.mean)}±{fmt(stats.std)}" if stats else DASH


def diverged_text(metrics: Metrics) -> str:
    """One line naming the diverged jumps per horizon, e.g. 'Full: 0 of 6, 0.1 s: 1 of 6'."""
    return metrics.diverged_text(horizon_label)
