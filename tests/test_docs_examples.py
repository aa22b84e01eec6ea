"""The README's and docs/*.md's Python examples run as written: every ```python block of a file,
in order, in one namespace (as ``__main__``), in a folder where ``data/go1.h5`` is a small planted
dataset of Go1 jumps."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from symrom.data.io import write_dataset
from symrom.names import Q_NAMES
from symrom.testing import make_planted_dataset

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```$", re.S | re.M)


def blocks(path: Path) -> list[str]:
    return BLOCK.findall(path.read_text())


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """``data/go1.h5``: planted jumps dressed as Go1's (the robot's mass and legs for the
    baselines and the input map; the base at least 0.15 m up)."""
    root = tmp_path_factory.mktemp("docs")
    ds, _ = make_planted_dataset(n_jumps=10, n_samples=200, embedding="block", noise=1e-4, seed=5)
    z = Q_NAMES.index("z")
    q = ds.q.copy()
    q[:, z] += 0.15 - q[:, z].min()
    (root / "data").mkdir()
    write_dataset(replace(ds, robot="go1", q=q), root / "data" / "go1.h5")
    return root


def test_the_documents_hold_examples():
    assert len(blocks(ROOT / "README.md")) == 2 and len(blocks(ROOT / "docs" / "design.md")) == 2


@pytest.mark.parametrize("path", [p for p in DOCS if blocks(p)], ids=lambda p: p.name)
def test_examples_run(path, folder, monkeypatch, capsys):
    monkeypatch.chdir(folder)
    namespace = {"__name__": "__main__"}
    for k, code in enumerate(blocks(path)):
        try:
            exec(compile(code, f"{path.name}[python block {k}]", "exec"), namespace)
        except Exception as e:  # noqa: BLE001 - name the block that failed
            raise AssertionError(f"{path.name}, python block {k}: {e!r}") from e
    assert capsys.readouterr().out.strip(), "the examples print what they show"
