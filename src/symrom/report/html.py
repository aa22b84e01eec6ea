"""``build_report``: one self-contained HTML page and its Markdown twin for a run directory.

The HTML embeds every figure as a base64 PNG and inlines its CSS (no external
resource); the Markdown file sits next to it and links the same figures as PNG
files in ``<stem>_files/`` (``report_files/`` for ``report.html``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

from symrom import __version__
from symrom.atomic import OutputExistsError, atomic_dir, check_writable, write_text_atomic
from symrom.execution import check_workers
from symrom.report.common import data_blocks, experiments_blocks, run_blocks
from symrom.report.context import Context, Drawing
from symrom.report.document import Para, Section, render_html, render_markdown
from symrom.report.headline import headline_blocks
from symrom.report.roles import build_sections
from symrom.report.run import load_run
from symrom.report.sim2real import sim2real_blocks


def report_paths(out_html: str | os.PathLike) -> tuple[Path, Path, Path]:
    """(html, markdown, figure folder) for ``out_html``: report.html -> report.md, report_files/."""
    html = Path(out_html)
    return html, html.with_suffix(".md"), html.with_name(f"{html.stem}_files")


def build_report(run_dir: str | os.PathLike, out_html: str | os.PathLike | None = None, force: bool = True,
                 progress: Callable[[str], None] | None = None, workers: int = 1) -> tuple[Path, Path]:
    """Build the report of ``run_dir`` into ``out_html`` (an ``.html`` file; default
    ``run_dir/report.html``) and its Markdown twin; their paths.

    The report shows what the run's manifest lists, each experiment by its role
    (``symrom.report.roles``). Existing outputs are replaced atomically; with
    ``force=False`` ``OutputExistsError`` is raised instead if any exists. Refused before
    any work: ``run_dir`` not a directory (``FileNotFoundError``), ``out_html`` not an
    ``.html`` file or in a place that cannot be written. Missing or unreadable files of
    the run are noted in the report. ``workers``: processes drawing the figures (this one and
    ``workers - 1`` more; the report is the same).
    """
    check_workers(workers)
    if not Path(run_dir).is_dir():
        raise FileNotFoundError(f"{run_dir}: no such run directory")
    out_html = Path(run_dir) / "report.html" if out_html is None else Path(out_html)
    if out_html.suffix.lower() not in (".html", ".htm"):
        raise ValueError(f"out={out_html}: expected an .html file")
    check_writable(out_html)
    html_path, md_path, files_dir = report_paths(out_html)
    if not force:
        for p in (html_path, md_path, files_dir):
            if p.exists():
                raise OutputExistsError(f"{p} exists; pass force=True to overwrite it")
    say = progress or (lambda msg: None)
    drawing = Drawing(workers)  # its processes start while the run is read
    try:
        return _build(run_dir, html_path, md_path, files_dir, say, drawing)
    finally:
        drawing.close()


def _build(run_dir, html_path: Path, md_path: Path, files_dir: Path, say, drawing: Drawing) -> tuple[Path, Path]:
    run = load_run(run_dir)
    title = "symrom report: symbolic reduced-order models of quadruped jumping"
    with atomic_dir(files_dir, force=True) as fig_dir:
        say("headline")
        head = headline_blocks(run)
        secs = [Section("headline", "Headline").add(*head)] if head else []
        say("experiments")
        try:
            secs += build_sections(run, Context(run, fig_dir, drawing))
        finally:  # every figure is in the folder before it is kept (or dropped with it)
            drawing.finish()
        targets = run.summary.get("sim2real", {}).get("targets")
        if targets:
            secs.append(Section("sim2real", "Sim-to-real: logged, repaired and fine-tuned").add(
                *sim2real_blocks(targets)))
        say("data and provenance")
        secs += [Section("experiments", "Experiments of this run and their files").add(
                     *experiments_blocks(run, html_path.parent)),
                 Section("data", "Data summary").add(*data_blocks(run, html_path.parent)),
                 Section("run", "Commands, versions and seeds").add(*run_blocks(run))]
        built = f"Built {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} by symrom {__version__}."
        if run.kind == "model folder":
            intro = [Para(f"Model folder: {run.dir.resolve()}. {built} The model's errors on its evaluated "
                          "split (as in the paper's Table 2, our rows only), a predicted jump, its equations "
                          "and their stability.")]
        else:
            intro = [Para(f"Run directory: {run.dir.resolve()}. {built} Reproduces arXiv 2508.06538 (Buriani, "
                          "Liu et al.): Table 2, the aSLIP comparison, the latent-dimension trade-off and the "
                          "learned equations, for whatever experiments this run holds.")]
        intro += [Para(n, note=True) for n in run.notes]
        write_text_atomic(md_path, render_markdown(title, intro, secs, files_dir.name))
        write_text_atomic(html_path, render_html(title, intro, secs))
    return html_path, md_path
