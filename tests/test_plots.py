"""Jump figures: drawn over the figure a process keeps, each is the file a new figure gives."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from symrom.data.dataset import Dataset
from symrom.evaluate import plots

N = 400  # rows per jump, 2 ms apart


def _dataset() -> Dataset:
    """Three jumps of three phases (contact, partial, flight, contact), every component moving."""
    k = np.arange(N)
    jump = np.repeat(np.arange(3), N).astype(np.int32)
    t = np.tile(k * 0.002, 3)
    q = np.sin(np.outer(t, np.arange(1, 19)) * 3.0 + jump[:, None]) * 0.3
    phase = np.tile(np.select([k < 120, k < 160, k < 280], [0, 1, 2], 0), 3).astype(np.int8)
    zeros = np.zeros((3 * N, 18))
    return Dataset("a1", "froggy", "sim", ["contact", "partial", "flight"], jump, t, q, zeros, zeros,
                   np.zeros((3 * N, 12)), np.ones((3 * N, 4), np.uint8), zeros, phase,
                   np.array(["train", "val", "test"]))


def _rollouts(ds, jump: int, horizons: tuple[str, ...]) -> dict:
    a, b = ds.jump_bounds()[jump]
    wave = np.sin(7.0 * ds.t[a:b])[:, None]
    return {h: SimpleNamespace(jumps=np.array([jump]), q_pred=[ds.q[a:b] + 0.02 * (i + 1) * wave])
            for i, h in enumerate(horizons)}


# jump, horizons, title, components: each case leaves the kept figure in another state
CASES = [(0, ("full", "0.1"), "", None), (1, ("full",), "jump 1 of the test split", None),
         (2, ("full", "0.1", "0.2"), "", ("x", "z", "pitch", "fl_kn")), (1, ("full", "0.1"), "", None)]


def _draw(path, case) -> None:
    jump, horizons, title, components = case
    ds = _dataset()
    kw = {} if components is None else {"components": components}
    plots.plot_jump(ds, _rollouts(ds, jump, horizons), jump, path, title=title, **kw)


def test_a_jump_drawn_over_the_kept_figure_is_the_file_of_a_new_figure(tmp_path):
    for k, case in enumerate(CASES):
        _draw(tmp_path / f"kept_{k}.png", case)
    # the last case again, first in a new process: the kept figure left nothing of the others
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from pathlib import Path; import test_plots as t; "
            f"t._draw(Path(sys.argv[2]), t.CASES[{len(CASES) - 1}])")
    subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent), str(tmp_path / "new.png")],
                   check=True)
    assert (tmp_path / "new.png").read_bytes() == (tmp_path / f"kept_{len(CASES) - 1}.png").read_bytes()
    assert (tmp_path / "kept_0.png").read_bytes() != (tmp_path / "kept_3.png").read_bytes()


def test_changed_matplotlib_settings_build_the_figure_anew(tmp_path):
    import matplotlib

    case = CASES[0]
    _draw(tmp_path / "a.png", case)
    with matplotlib.rc_context({"axes.facecolor": "#ffeedd"}):
        _draw(tmp_path / "b.png", case)
    _draw(tmp_path / "c.png", case)
    assert (tmp_path / "a.png").read_bytes() != (tmp_path / "b.png").read_bytes()
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "c.png").read_bytes()


def test_an_unknown_component_leaves_the_kept_figure_clear(tmp_path):
    _draw(tmp_path / "a.png", CASES[0])
    with pytest.raises(ValueError):
        _draw(tmp_path / "bad.png", (0, ("full",), "", ("x", "no_such_component")))
    assert not (tmp_path / "bad.png").exists()
    _draw(tmp_path / "b.png", CASES[0])
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
