"""Facts docs/design.md states that the code defines: file format and generator versions.

Each fact is read from the code and every statement of it in design.md is found by a pattern
that captures the number the text gives, so the test fails when either changes alone: a bumped
constant whose text still says the old number, or a text edited away from the code. Gravity has
one definition (``symrom.names.GRAVITY``): no other module of ``src/`` writes its value.
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DESIGN = (ROOT / "docs" / "design.md").read_text()


def _constants() -> dict[str, object]:
    from symrom.baselines.com import PARAMS_VERSION
    from symrom.data.dataset import SCHEMA_VERSION
    from symrom.data.repair import REPAIR_VERSION
    from symrom.evaluate.metrics import METRICS_VERSION
    from symrom.evaluate.records import METRICS_VERSIONS
    from symrom.experiments.finetune import FINETUNE_VERSION
    from symrom.experiments.reproduce.sim2real import CHOICE_VERSION
    from symrom.experiments.select import SELECTION_VERSION
    from symrom.model.persistence import FORMAT_VERSION, READABLE_VERSIONS
    from symrom.plan.jump import LANDING_FORMAT, TRAJECTORY_FORMAT
    from symrom.robots.description import FORMATS
    from symrom.sim.generation.config import GENERATOR_VERSION
    from symrom.sim.generation.generate import RUN_RECORD_VERSION

    return {
        "model file": FORMAT_VERSION,
        "model files read": tuple(sorted(set(READABLE_VERSIONS) - {FORMAT_VERSION}, reverse=True)),
        "metrics.json": METRICS_VERSION,
        "metrics.json read": METRICS_VERSIONS[-1],
        "generator": GENERATOR_VERSION,
        "dataset schema": SCHEMA_VERSION,
        "robot description": FORMATS,
        "params.json": PARAMS_VERSION,
        "landing.json": LANDING_FORMAT,
        "trajectory.json": TRAJECTORY_FORMAT,
        "selection.json": SELECTION_VERSION,
        "repair record": REPAIR_VERSION,
        "OUT.run.json": RUN_RECORD_VERSION,
        "finetune.json": FINETUNE_VERSION,
        "finetune_choice.json": CHOICE_VERSION,
    }


_NUMS = r"(\d+(?:(?:, | and | or |`? or `)\d+)*)"  # "5", "4, 3, 2 and 1", "1` or `2"

# fact -> patterns of design.md; each captures the number(s) one statement gives.
STATEMENTS: dict[str, tuple[str, ...]] = {
    "model file": (r"## Model file \(JSON, `format_version` (\d+)\)", r"\| `format_version` \| (\d+) \(files of"),
    "model files read": (r"\(files of versions " + _NUMS + r" are still read",),
    "metrics.json": (r"## Metrics file \(`metrics\.json`, `format_version` (\d+)\)",
                     r'\{"format_version": (\d+), "model": "\.\.\."'),
    "metrics.json read": (r"Drift \(version (\d+);",),
    "generator": (r"`generator` \(`symrom\.sim\.generate`\), `version` \((\d+)\)",
                  r"the generator stays\s+version (\d+)"),
    "dataset schema": (r"## Dataset file \(HDF5, `schema_version` (\d+)\)",
                       r"\| attr `schema_version` \| int \| (\d+) \|", r"`schema_version`\s+stays (\d+)"),
    "robot description": (r"## Robot description file \(TOML, `format = " + _NUMS + r"`\)",),
    "params.json": (r"`format_version` (\d+), `model` \(`aslip`, `newton`, `affine_force`\)",),
    "landing.json": (r"`landing\.json` \(`format_version` (\d+)",),
    "trajectory.json": (r"`trajectory\.json` \(`format_version` (\d+)",),
    "selection.json": (r"\(`selection\.json`, version (\d+):",),
    "repair record": (r"`repairs` \(`version` (\d+),", r"`generator\.repairs\.jumps`,\s+`version` (\d+)\)"),
    "OUT.run.json": (r"`OUT\.run\.json` \(version (\d+)\)",),
    "finetune.json": (r"`finetune\.json` \(version (\d+),",),
    "finetune_choice.json": (r"`<target>/finetune_choice\.json` \(version (\d+):",),
}


def _numbers(text: str) -> tuple[int, ...]:
    return tuple(int(n) for n in re.findall(r"\d+", text))


def test_every_fact_has_its_statements():
    assert set(STATEMENTS) == set(_constants())


@pytest.mark.parametrize("fact", sorted(STATEMENTS))
def test_design_states_the_codes_version(fact):
    value = _constants()[fact]
    want = value if isinstance(value, tuple) else (value,)
    for pattern in STATEMENTS[fact]:
        found = [_numbers(m.group(1)) for m in re.finditer(pattern, DESIGN)]
        assert found, f"docs/design.md no longer states the {fact} version where /{pattern}/ finds it"
        for got in found:
            assert got == want, f"docs/design.md gives the {fact} version as {got}; the code says {want}"


def test_the_patterns_catch_a_wrong_statement():
    """A design.md one number off fails (the check is not vacuous)."""
    from symrom.sim.generation.config import GENERATOR_VERSION

    wrong = DESIGN.replace(f"`version` ({GENERATOR_VERSION})", f"`version` ({GENERATOR_VERSION - 1})")
    assert wrong != DESIGN
    got = [_numbers(m.group(1)) for m in re.finditer(STATEMENTS["generator"][0], wrong)]
    assert got == [(GENERATOR_VERSION - 1,)]


# ----------------------------------------------------------------- one gravity constant
def _number_tokens(path: Path) -> list[tuple[int, str]]:
    toks = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
    return [(t.start[0], t.string) for t in toks if t.type == tokenize.NUMBER]


def test_gravity_is_defined_once():
    from symrom.names import GRAVITY

    assert GRAVITY == 9.81
    others = []
    for path in sorted((ROOT / "src" / "symrom").rglob("*.py")):
        text = path.read_text()
        if "scipy.constants" in text:
            others.append(f"{path.relative_to(ROOT)}: scipy.constants")
        for line, number in _number_tokens(path):
            if number in ("9.81", "9.80665") and path.name != "names.py":
                others.append(f"{path.relative_to(ROOT)}:{line}: {number}")
    assert not others, "gravity written outside symrom.names: " + ", ".join(others)
