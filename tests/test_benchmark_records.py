"""The committed records under benchmarks/results/ say how they were made, and the README's
results say which command gives them.

Each record carries ``command`` (a benchmark script of this repository, or a ``symrom``
command, with options that script or command has) and ``commit`` (the commit whose code made
it). ``benchmarks/provenance.py`` writes both into every new record.
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RECORDS = sorted((ROOT / "benchmarks" / "results").glob("*.json"))
COMMIT = re.compile(r"^[0-9a-f]{40}(\+dirty)?$")


def _cli_options(words: list[str]) -> set[str] | None:
    """The options of the ``symrom`` command that ``words`` name (a command, or a group and its
    command; later words are its arguments), or None if there is no such command."""
    import typer.main

    from symrom.cli import app

    cmd = typer.main.get_command(app)
    for w in words:
        subs = getattr(cmd, "commands", None)
        if not subs:
            break
        if w not in subs:
            return None
        cmd = subs[w]
    if getattr(cmd, "commands", None):  # a group named without its command
        return None
    return {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}


def check_command(command: str) -> str | None:
    """Why ``command`` names no existing script or command of this repository (None: it does)."""
    words = shlex.split(command)
    while words and re.match(r"^[A-Z_][A-Z0-9_]*=", words[0]):  # VAR=value before the command
        words.pop(0)
    if len(words) >= 2 and re.fullmatch(r"python(3(\.\d+)?)?", words[0]):
        script = ROOT / words[1]
        if not (words[1].startswith("benchmarks/") and script.is_file()):
            return f"{words[1]}: no such script under benchmarks/"
        text = script.read_text()
        missing = [w.split("=")[0] for w in words[2:] if w.startswith("--")
                   and f'"{w.split("=")[0]}"' not in text]
        return f"{words[1]} has no option {missing}" if missing else None
    if words and words[0] == "symrom":
        names = [w for w in words[1:] if not w.startswith("-")][:2]
        opts = _cli_options(names)
        if opts is None:
            return f"symrom has no command {' '.join(names)!r}"
        missing = [w.split("=")[0] for w in words[1:] if w.startswith("--") and w.split("=")[0] not in opts]
        return f"symrom {names[0]} has no option {missing}" if missing else None
    return "neither `python benchmarks/...` nor `symrom ...`"


def test_there_are_records():
    assert len(RECORDS) >= 10


@pytest.mark.parametrize("path", RECORDS, ids=[p.name for p in RECORDS])
def test_each_record_carries_its_command_and_commit(path):
    record = json.loads(path.read_text())
    assert isinstance(record.get("command"), str), f"{path.name}: no command"
    assert check_command(record["command"]) is None, f"{path.name}: {check_command(record['command'])}"
    commit = record.get("commit")
    assert isinstance(commit, str) and COMMIT.match(commit), f"{path.name}: commit {commit!r}"
    git = subprocess.run(["git", "cat-file", "-e", commit.removesuffix("+dirty") + "^{commit}"], cwd=ROOT,
                         capture_output=True)
    shallow = subprocess.run(["git", "rev-parse", "--is-shallow-repository"], cwd=ROOT, capture_output=True,
                             text=True).stdout.strip()
    if shallow == "false":  # a full clone holds every commit a record names
        assert git.returncode == 0, f"{path.name}: commit {commit} is not in this repository's history"


def test_the_command_check_refuses_what_does_not_exist():
    assert check_command("python benchmarks/bench_sim.py --jumps 6 --out x.json") is None
    assert check_command("OMP_NUM_THREADS=1 python benchmarks/bench_jump.py --model m.json") is None
    assert check_command("symrom reproduce --out runs/paper --quick --workers 2") is None
    assert "no such script" in check_command("python benchmarks/bench_gone.py --out x.json")
    assert "no option" in check_command("python benchmarks/bench_sim.py --warp 9")
    assert "no command" in check_command("symrom teleport --out x")
    assert check_command("symrom robot init model.xml --out r.toml") is None
    assert "no command" in check_command("symrom robot --out r.toml")
    assert "no option" in check_command("symrom reproduce --out x --faster")


def test_provenance_names_the_script_and_the_commit(tmp_path):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from provenance import command, commit
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    assert command([str(ROOT / "benchmarks" / "bench_sim.py"), "--jumps", "6", "--out", "a b.json"]) == \
        "python benchmarks/bench_sim.py --jumps 6 --out 'a b.json'"
    assert COMMIT.match(commit()) or commit() == "unknown"


# ----------------------------------------------------------------- the README's results
def _results_section() -> str:
    text = (ROOT / "README.md").read_text()
    return text.split("## Results", 1)[1].split("\n## ", 1)[0]


WALL_TIME = re.compile(r"\b\d+ (?:h \d+ min|min \d+ s|min|s)\b")


def readme_result_problems(section: str) -> list[str]:
    """What the Results section of a README lacks: every command it names exists and is given
    with its wall time in the same sentence; every bullet that reports numbers names its command
    or a page that does, and the section names at least one command."""
    problems = []
    commands = re.findall(r"`((?:OMP_NUM_THREADS=\d+ )?(?:symrom|python benchmarks/)[^`]*)`", section)
    runs = [c for c in commands if check_command(c) is None and (c.startswith("python") or " --out " in f" {c} ")]
    if not runs:
        problems.append("no command that makes a result")
    for c in commands:
        why = check_command(c)
        if why:
            problems.append(f"`{c}`: {why}")
    # a command that writes results: its wall time after it, before the next such command
    # (or the end of its paragraph or bullet)
    for part in re.split(r"\n\s*\n|\n- ", section):
        found = list(re.finditer(r"`((?:symrom \w+ [^`]*--out|python benchmarks/)[^`]*)`", part))
        for k, m in enumerate(found):
            after = part[m.end():found[k + 1].start() if k + 1 < len(found) else len(part)]
            if not WALL_TIME.search(after):
                problems.append(f"`{m.group(1)}`: no wall time after it")
    for bullet in re.findall(r"^- (.*(?:\n  .*)*)", section, flags=re.M):
        if re.search(r"\d", bullet) and not re.search(r"`(?:symrom|python benchmarks/)|\(docs/\w+\.md", bullet):
            problems.append(f"a result without its command: {bullet[:60]}...")
    return problems


def test_readme_results_name_their_commands_and_wall_times():
    assert readme_result_problems(_results_section()) == []


def test_the_readme_check_catches_a_result_without_its_command():
    good = ("The numbers come from `symrom reproduce --out runs/paper` (seed 0). It took 29 min 43 s.\n\n"
            "- **SIM Go1: 12 of 12** ([docs/results.md](docs/results.md)).\n")
    assert readme_result_problems(good) == []
    assert any("wall time" in p for p in readme_result_problems(good.replace("It took 29 min 43 s.", "")))
    assert any("without its command" in p for p in readme_result_problems(good + "- **A1: 10 of 12**.\n"))
    assert any("no option" in p for p in readme_result_problems(good.replace("--out", "--outt")))
