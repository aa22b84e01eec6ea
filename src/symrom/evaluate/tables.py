"""Markdown tables in the layout of the paper's Table 2."""

from __future__ import annotations

from symrom.names import Q_UNITS, TABLE2_COMPONENTS


def fmt_value(x: float) -> str:
    """Two significant digits as in the paper: 1.3e-2, 0.11."""
    if x == 0:
        return "0"
    a = abs(x)
    return f"{x:.2f}" if 0.1 <= a < 100 else f"{x:.1e}".replace("e-0", "e-").replace("e+0", "e")


def divergence_note(metrics: dict) -> str:
    """One sentence on the diverged jumps of a metrics dict, with when each diverged ('' if
    none), e.g. 'Diverged: Full: jump 4 at 1.438 s; scored up to the divergence (97.1 % of
    the samples).'"""
    parts = []
    scored = metrics.get("format_version", 1) >= 2
    for key, h in metrics["horizons"].items():
        if not h["diverged_jumps"]:
            continue
        label = "Full" if key == "full" else f"{key} s"
        when = ", ".join(f"jump {d['jump']} at {d['t']:.3f} s" for d in h.get("diverged", [])) \
            or f"{h['diverged_jumps']} jumps"
        share = (f" ({100 * h['scored_samples'] / h['samples']:.1f} % of the samples)"
                 if scored and h.get("samples") else "")
        parts.append(f"{label}: {when}; " + (f"scored up to the divergence{share}" if scored
                                             else "left out of the statistics"))
    return ("Diverged: " + "; ".join(parts) + ".") if parts else ""


def drift_text(drifted: list[dict]) -> str:
    """When and how each drifted jump (a horizon's ``drifted`` list) left the physically
    possible, e.g. 'jump 4 at 0.512 s (z -0.91 m past -0.43 m)'."""
    return ", ".join(f"jump {d['jump']} at {d['t']:.3f} s ({d['component']} {d['value']:.2f} m past "
                     f"{d['limit']:.2f} m)" for d in drifted)


def drift_note(metrics: dict) -> str:
    """One sentence on the drifted jumps of a metrics dict ('' if none or not checked)."""
    parts = [f"{'Full' if key == 'full' else f'{key} s'}: {drift_text(h['drifted'])}"
             for key, h in metrics["horizons"].items() if h.get("drifted_jumps")]
    return ("Drifted (left the physically possible: below the ground by more than a leg length, or "
            "beyond the jump's range; still scored): " + "; ".join(parts) + ".") if parts else ""


def table2(metrics: dict, components: tuple[str, ...] = TABLE2_COMPONENTS, title: str = "") -> str:
    """Signed mean ± std per component and horizon, then MAE and RMSE rows; lines under the
    table say when each diverged jump left its bound and how it was scored, and when each
    drifted jump left the physically possible."""
    head = "| horizon | stat | " + " | ".join(f"{c} [{Q_UNITS.get(c, '')}]" for c in components) + " |"
    lines = ([f"**{title}**", ""] if title else []) + [head, "|" + "---|" * (len(components) + 2)]
    for key, h in metrics["horizons"].items():
        label = "Full" if key == "full" else f"{key} s"
        comps = h["components"]
        if not comps:
            lines.append(f"| {label} | all jumps diverged ({h['diverged_jumps']}) |"
                         + " |" * len(components))
            continue
        marks = [f"{h['diverged_jumps']} diverged"] if h["diverged_jumps"] else []
        marks += [f"{h['drifted_jumps']} drifted"] if h.get("drifted_jumps") else []
        div = f" ({', '.join(marks)})" if marks else ""
        lines.append(f"| {label}{div} | mean±std | " + " | ".join(
            f"{fmt_value(comps[c]['mean'])}±{fmt_value(comps[c]['std'])}" for c in components) + " |")
        for stat in ("mae", "rmse"):
            lines.append(f"| {label} | {stat.upper()} | "
                         + " | ".join(fmt_value(comps[c][stat]) for c in components) + " |")
    notes = [n for n in (divergence_note(metrics), drift_note(metrics)) if n]
    return "\n".join(lines + [x for n in notes for x in ("", n)]) + "\n"
