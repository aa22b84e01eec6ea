"""Renderers of learned and fine-tuned models: Table 2, a test jump's prediction, equations.

An entry with ``paper`` is set beside the paper's numbers for that row; an entry
that belongs to another (``of``, e.g. the paper-default variant) gets our rows
only, and no figure or equations of its own.
"""

from __future__ import annotations

import textwrap

from symrom.evaluate.paper import PAPER_LABELS, implied_rmse, paper_rmse, paper_row
from symrom.evaluate.records import ManifestEntry, Metrics
from symrom.names import Q_UNITS, TABLE2_COMPONENTS
from symrom.report import figures
from symrom.report.context import Context
from symrom.report.document import Figure, Para, Pre, Table
from symrom.report.format import DASH, diverged_text, fmt, horizon_label, ms
from symrom.report.run import Run

# Table 2 split by group so that each table fits the page.
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("joints", TABLE2_COMPONENTS[:6]), ("base pose", TABLE2_COMPONENTS[6:]))
EQUATION_WIDTH = 96  # characters of a printed equation line before it wraps


def heading(entry: ManifestEntry) -> str:
    title = entry.title if entry.title and entry.title != entry.name else ""
    paper = f"paper row: {PAPER_LABELS[entry.paper]}" if entry.paper in PAPER_LABELS else ""
    return " — ".join(x for x in (entry.name, title, paper) if x)


# --------------------------------------------------------------------------- Table 2
def table2_rows(paper_key: str | None, metrics: Metrics,
                components: tuple[str, ...]) -> tuple[list[list[str]], dict[str, int]]:
    """Rows of the comparison (the paper's beside ours when ``paper_key`` names a row) and,
    per horizon, the count of ``components`` where our RMSE <= the paper's implied RMSE."""
    rows, wins = [], {}
    blank = [""] * (len(components) - 1)
    for key in dict.fromkeys(["full", "0.1", *metrics.horizons]):
        ours, paper = metrics.horizons.get(key), paper_row(paper_key, key) if paper_key else None
        if ours is None and paper is None:
            continue
        lab = horizon_label(key)
        if paper:
            rows.append([lab, "paper mean±std"] + [f"{fmt(paper[c][0])}±{fmt(paper[c][1])}" for c in components])
        if ours is None:
            rows.append([lab, "ours", "not evaluated"] + blank)
            continue
        if not ours.components:
            rows.append([lab, "ours", f"all {ours.diverged_jumps} jumps diverged"] + blank)
            continue
        div = ours.diverged_jumps
        how = "scored up to it" if metrics.scores_diverged else "left out"
        rows.append([lab, f"ours mean±std ({div} diverged, {how})" if div else "ours mean±std"]
                    + [ms(ours.components.get(c)) for c in components])
        if paper:
            rows.append([lab, "paper RMSE √(mean²+std²)"] + [fmt(implied_rmse(*paper[c])) for c in components])
        rmse = [ours.stat(c, "rmse") for c in components]
        rows.append([lab, "ours RMSE"] + [DASH if r is None else fmt(r) for r in rmse])
        if paper:
            marks = ["✓" if r is not None and r <= implied_rmse(*paper[c]) else "✗" for r, c in zip(rmse, components)]
            wins[key] = marks.count("✓")
            rows.append([lab, "ours ≤ paper RMSE"] + marks)
    return rows, wins


def _floor(run: Run, entry: ManifestEntry, metrics: Metrics) -> dict[str, float] | None:
    """The reconstruction floor of the entry's model on its evaluation split."""
    from symrom.evaluate.metrics import reconstruction_floor

    model, ds = run.model(entry), run.dataset(entry)
    return None if model is None or ds is None else reconstruction_floor(model, ds, metrics.split)


def _tables(entry: ManifestEntry, metrics: Metrics, paper_key: str | None, caption: str,
            floor: dict[str, float] | None = None, ours_only: bool = False) -> tuple[list, dict[str, int]]:
    """One table per component group; the wins summed over the groups."""
    blocks, wins = [], {}
    for group, comps in GROUPS:
        rows, w = table2_rows(paper_key, metrics, comps)
        if ours_only:
            rows = [r for r in rows if r[1].startswith("ours")]
        if floor is not None:
            rows.append(["any", "reconstruction floor RMSE"] + [fmt(floor[c]) for c in comps])
        header = ["horizon", "row"] + [f"{c} [{Q_UNITS[c]}]" for c in comps]
        blocks.append(Table(header, rows, caption=f"{caption} — {group}"))
        for k, v in w.items():
            wins[k] = wins.get(k, 0) + v
    return blocks, wins


def _options(entry: ManifestEntry) -> list:
    """One line of the settings the entry's model was trained with (as its manifest states)."""
    cfg = entry.facts.get("config")
    if not isinstance(cfg, dict):
        return []
    names = {"candidates": "candidate models"}  # of the selection (not library terms)
    parts = [f"{names.get(k, k.replace('_', ' '))} {v:g}" if isinstance(v, float)
             else f"{names.get(k, k.replace('_', ' '))} {v}"
             for k, v in cfg.items() if v is not None and not isinstance(v, (dict, list))]
    out = [Para("Settings: " + "; ".join(parts) + ".")]
    if cfg.get("checks") == []:
        out.append(Para("Selected on the validation score alone: its data are too few to judge a model's "
                        "physics by, so no check refused a candidate (the selection table still holds every "
                        "check's numbers).", note=True))
    return out


def table2_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = []
    for e in entries:
        if run.kind == "model folder" and "metrics" not in e.files:
            continue  # not evaluated yet: the run's notes say how
        blocks.append(heading(e))
        metrics = run.metrics(e)
        if metrics is None:
            blocks.append(Para(f"{e.name}: no metrics; skipped.", note=True))
            continue
        floor = _floor(run, e, metrics)
        caption = f"{e.name}, {metrics.split} jumps: {metrics.n_jumps}"
        tables, wins = _tables(e, metrics, e.paper, caption, floor)
        blocks += _options(e) + tables
        if floor is not None:
            rmse = {horizon_label(k): {c: h.stat(c, "rmse") for c in TABLE2_COMPONENTS}
                    for k, h in metrics.horizons.items() if h.components}
            paper = {horizon_label(k): ref for k in metrics.horizons
                     if e.paper and (ref := paper_rmse(e.paper, k)) is not None} or None
            path = ctx.draw(figures.horizon_figure, rmse, floor, ctx.fig_dir / f"horizons_{ctx.slug(e)}.png",
                            title=f"{e.name}: RMSE per component and horizon ({metrics.split} split)",
                            paper=paper)
            beside = (" and the paper's implied RMSE (a bar in the horizon's colour)" if paper else "")
            blocks.append(Figure(path, f"{e.name}: RMSE of each Table 2 component at each horizon beside the "
                                       f"reconstruction floor{beside}; the floor is decode∘encode of the true "
                                       "configurations: a point on it is as close as any latent model with this "
                                       "encoder can get"))
        how = ("; a diverged jump is scored up to the time it diverged" if metrics.scores_diverged
               else "; diverged jumps are left out of the statistics") if metrics.any_diverged else ""
        blocks.append(Para(f"Diverged {metrics.split} jumps — {diverged_text(metrics)}{how}.",
                           note=metrics.any_diverged))
        if wins:
            blocks.append(Para("Ours ≤ paper RMSE in " + ", ".join(
                f"{w} of {len(TABLE2_COMPONENTS)} components ({horizon_label(k)})" for k, w in wins.items()) + "."))
        p = paper_row(e.paper, "0.1") if e.paper else None
        blocked = [c for c in TABLE2_COMPONENTS if floor is not None and p and floor[c] > implied_rmse(*p[c])]
        if blocked:
            blocks.append(Para("The reconstruction floor (decode∘encode of the true configurations, the error "
                               "of a rollout with exact latent dynamics) is above the paper's 0.1 s RMSE for "
                               + ", ".join(blocked) + ": with this encoder no latent model can reach the "
                               "paper's value there.", note=True))
        before = run.metrics(e, "before") if "before" in e.files else None
        if before is not None:
            tables, _ = _tables(e, before, None, f"{e.name} before fine-tuning (the source model on the same "
                                                 f"{before.split} jumps)", ours_only=True)
            blocks += tables
    return blocks


# --------------------------------------------------------------------------- predictions
def predictions_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = []
    for e in entries:
        if e.of is not None:
            continue
        got = ctx.jumps.get(e)
        if got is None and run.kind == "model folder" and "metrics" not in e.files:
            continue  # not evaluated yet: the run's notes say how
        if got is None:
            blocks.append(Para(f"{e.name}: model, data or metrics missing; no prediction figure.", note=True))
            continue
        ds, j, ros = got
        split = str(ds.split[j])
        which = f"{split} jump 0 (dataset jump {j})"
        path = ctx.draw(figures.jump_figure, ds, ros, j, ctx.fig_dir / f"jump_{ctx.slug(e)}.png",
                        title=f"{e.name}: {ds.motion}, {which}")
        blocks.append(Figure(path, f"{e.name}: {which}, truth vs prediction"))
        start = ds.jump_bounds()[j][0]
        div = [f"{horizon_label(k)} diverged at t = {ds.t[start + r.diverged_at[0]]:.3f} s"
               for k, r in ros.items() if r.diverged[0]]
        if div:
            blocks.append(Para(f"{e.name}, jump {j}: " + "; ".join(div) + " (the curve stops there).", note=True))
    return blocks


# --------------------------------------------------------------------------- equations
def wrap_equation(lhs: str, rhs: str, width: int = EQUATION_WIDTH) -> str:
    """``lhs = rhs`` broken between terms into lines of at most ``width`` characters
    (a single longer term keeps its line), continuation lines under the first term."""
    head = f"{lhs} = "
    terms = rhs.replace(" - ", " + -").split(" + ")
    lines, line = [], head + terms[0]
    for t in terms[1:]:
        sign, t = ("- ", t[1:]) if t.startswith("-") else ("+ ", t)
        if len(line) + 1 + len(sign) + len(t) > width:
            lines.append(line)
            line = " " * len(head) + sign + t
        else:
            line += " " + sign + t
    return "\n".join(lines + [line])


def equations_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = [Para("Latent accelerations ddxi_j as sparse combinations of the library Θ(ξ, dξ, ν) "
                         "(xi: latent position, dxi: latent velocity, nu: latent input).")]
    for e in entries:
        if e.of is not None:
            continue
        model = run.model(e)
        if model is None:
            blocks.append(Para(f"{e.name}: no model file; no equations.", note=True))
            continue
        terms = ", ".join(f"{k} {v}" for k, v in model.active_terms().items())
        equations = model.equations(3)
        text = "\n".join(f"[{phase}]\n" + "\n".join(textwrap.indent(wrap_equation(f"ddxi{j}", str(rhs)), "  ")
                                                     for j, rhs in enumerate(eqs, 1))
                         for phase, eqs in equations.items())
        text += "\nlatents, by their largest encoder loadings (per rad or m):\n" + "\n".join(
            "  " + line for line in equations.legend())
        blocks.append(Pre(text, caption=f"{e.name}: l = {model.latent_dim}, p = {model.library.poly_order}, "
                                        f"library terms: {model.library.n_features}; active terms: {terms}"))
        blocks += stability_blocks(e.name, model)
    return blocks


def stability_blocks(name: str, model) -> list:
    """Per phase, the eigenvalues of the latent dynamics linearised at the phase's training
    mean, the growth of the fastest mode over a typical stay, and a warning if it is fast."""
    stab = model.stability()
    if not stab:
        return []
    rows = [[st.phase, ", ".join(f"{z.real:.3g}{z.imag:+.3g}j" if abs(z.imag) > 1e-12 else f"{z.real:.3g}"
                                 for z in sorted(st.eigenvalues, key=lambda z: (-z.real, z.imag))),
             DASH if st.duration_s is None else f"{st.duration_s:.3g}",
             DASH if st.growth is None else f"{st.growth:.3g}", "yes" if st.fast_unstable else "no"]
            for st in stab]
    blocks: list = [Table(["phase", "eigenvalues [1/s]", "typical stay [s]", "growth of the fastest mode",
                           "fast unstable mode"],
                          rows, caption=f"{name}: stability of each phase's dynamics at its training mean")]
    warnings = [st.warning() for st in stab if st.warning()]
    if warnings:
        blocks.append(Para(" ".join(w[0].upper() + w[1:] + "." for w in warnings), note=True))
    return blocks
