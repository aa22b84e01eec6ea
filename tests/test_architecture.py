"""Rules of the house, checked on the source: imports only point down; the library never
prints or exits (the command line does)."""

from __future__ import annotations

import ast
import re
import sys
from functools import cache
from pathlib import Path

import pytest

import symrom

SRC = Path(symrom.__file__).parent

# Layers from the ground floor up (docs/design.md, "Layout"): a module may import its own
# layer and those below it.
LAYERS: dict[str, int] = {
    "names": 0, "atomic": 0, "motions": 0, "execution": 0,
    "robots": 1,
    "data": 2,
    "sim": 3, "rollout": 3, "compiled": 3,
    "model": 4, "baselines": 4,
    "learn": 5, "testing": 5, "evaluate": 5, "plan": 5, "export": 5,
    "experiments": 6,
    "report": 7,
    "cli": 8,
    "__main__": 9,  # ``python -m symrom``: the command line
}
# Inside a package (or a subpackage, dotted), the same rule between its modules (or subpackages).
PACKAGE_LAYERS: dict[str, dict[str, int]] = {
    # compiled execution: the descriptions it reads, then its kernels and generated code
    "compiled": {"dynamics": 0, "batch": 0, "codec": 0, "table_kernels": 0, "kernel": 1, "codegen": 1},
    # the fitted model: its terms, the expressions, the guards, then the model, its file
    "model": {"autoencoder": 0, "library": 0, "provenance": 0, "expressions": 1, "guards": 1,
              "hybrid": 2, "path": 2, "persistence": 3},
    # learning: the guards' compiled losses, the shooting and guard fitting, the problem and its
    # regressors, the encoders, the estimator, then what drives it
    "learn": {"compiled": 0, "audit": 0, "calibrate": 0, "guards": 0, "shooting": 0, "regressors": 1, "adam": 2,
              "encoders": 2, "plugins": 3, "estimator": 4, "finetune": 5, "training": 5},
    # export: the tables, then one writer per target
    "export": {"tables": 0, "to_c": 1, "to_casadi": 1, "to_python": 1},
    # planning: the models and guards, the problem, its real-time re-planning, its execution, the
    # jump that uses them
    "plan": {"config": 0, "dynamics": 0, "guards": 0, "inputs": 0, "problem": 1, "bias": 2, "replan": 2, "execute": 3,
             "jump": 4},
    # simulation by job: the engines; the hardware-like variant, on any engine; the controllers and
    # motions; what runs them (generation) and what reads its data (diagnostics)
    "sim": {"engines": 0, "proxy": 1, "controllers": 2, "generation": 3, "diagnostics": 3},
    # the engines: what they share and their compiled reads, then each engine and the registry
    "sim.engines": {"world": 0, "compiled": 0, "bullet": 1, "mujoco": 1, "registry": 1},
    # the controllers: their compiled arithmetic, flights, the body model, the actuator
    # compensation; its URDF source, the MPC, the protocols; the motions
    "sim.controllers": {"compiled": 0, "flight": 0, "body": 0, "actuators": 0, "urdf_body": 1, "mpc": 1, "motion": 1,
                        "pronk": 2, "froggy": 2},
    # generation: the checks, parts, the episode loop and the warm start; the configuration; one
    # checked jump; the whole file
    "sim.generation": {"checks": 0, "parts": 0, "episode": 0, "warm": 0, "preload": 1, "config": 1, "runner": 2,
                       "generate": 3},
    "sim.diagnostics": {"forces": 0, "render": 0},
    # experiments: the resumable grid, what runs on it, the reproduction made of them, the demo that is one
    "experiments": {"grid": 0, "select": 1, "sweep": 1, "finetune": 1, "warm": 2, "reproduce": 2, "demo": 3},
    # the command line: what the commands share, one module per group of commands, the entry points
    "cli": {"common": 0, "data": 1, "learn": 1, "evaluate": 1, "run": 1, "plan": 1, "robot": 1, "__main__": 2},
}
# Known upward imports, each with the change that removes it (none today).
KNOWN: set[tuple[str, str]] = set()


def _resolve(name: str) -> str:
    """The module a dotted name imports: the deepest prefix that is a module or package of SRC."""
    parts = name.split(".")[1:]
    while parts:
        base = SRC.joinpath(*parts)
        if base.with_suffix(".py").is_file() or (base / "__init__.py").is_file():
            return ".".join(["symrom", *parts])
        parts.pop()
    return "symrom"


@cache
def _nodes(path: Path) -> tuple[ast.AST, ...]:
    """Every node of ``path``'s syntax tree, the module first (``ast.walk``'s order); parsed once
    per session, as most rules read every module."""
    return tuple(ast.walk(ast.parse(path.read_text())))


def _type_only(path: Path) -> set[int]:
    """ids of the import nodes under ``if TYPE_CHECKING:`` (never executed)."""
    out: set[int] = set()
    for node in _nodes(path):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            out |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return out


def _imports(path: Path, runtime_only: bool = False) -> list[tuple[str, int]]:
    """The symrom modules ``path`` imports, anywhere in it (also inside functions), with
    their lines; ``runtime_only``: leaving out imports for type checkers only."""
    skip = _type_only(path) if runtime_only else set()
    out = []
    for node in _nodes(path):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "symrom":
            # ``from symrom.a import b`` imports the module symrom.a.b when there is one
            out += [(_resolve(f"{node.module}.{a.name}"), node.lineno) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(_resolve(a.name), node.lineno) for a in node.names if a.name.split(".")[0] == "symrom"]
    return out


def _module_name(rel: Path) -> str:
    parts = list(rel.with_suffix("").parts)
    return ".".join(["symrom", *(parts[:-1] if parts[-1] == "__init__" else parts)])


def _layer(module: str) -> str:
    return module.split(".")[1] if module.count(".") else ""


def _modules():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC)
        yield path, rel, (rel.parts[0][:-3] if len(rel.parts) == 1 else rel.parts[0])


def _package_dir(package: str) -> Path:
    return SRC.joinpath(*package.split("."))


def test_every_module_has_a_layer():
    assert {layer for _, _, layer in _modules()} - {"__init__"} == set(LAYERS)
    for package, table in PACKAGE_LAYERS.items():
        found = {p.stem if p.is_file() else p.name for p in _package_dir(package).iterdir()
                 if (p.suffix == ".py" or (p / "__init__.py").is_file()) and p.name != "__init__.py"}
        assert found == set(table), f"{package}/: modules {sorted(found)}, table {sorted(table)}"


def test_imports_only_point_down():
    upward = []
    for path, rel, layer in _modules():
        if layer == "__init__":
            continue
        for module, line in _imports(path):
            target = _layer(module)  # "" is the package itself (its __version__): the circle test covers it
            if target and LAYERS[target] > LAYERS[layer] and (layer, target) not in KNOWN:
                upward.append(f"{rel}:{line} imports {module}")
    assert not upward, "\n".join(upward)


def test_imports_inside_packages_only_point_down():
    upward = []
    for package, table in PACKAGE_LAYERS.items():
        prefix = ["symrom", *package.split(".")]
        for path in sorted(_package_dir(package).rglob("*.py")):
            rel = path.relative_to(_package_dir(package))
            if rel.parts == ("__init__.py",):
                continue
            own = rel.parts[0].removesuffix(".py")
            for module, line in _imports(path, runtime_only=True):  # a type may name what uses it
                parts = module.split(".")
                if (len(parts) > len(prefix) and parts[:len(prefix)] == prefix
                        and table[parts[len(prefix)]] > table[own]):
                    upward.append(f"{path.relative_to(SRC)}:{line} imports {module}")
    assert not upward, "\n".join(upward)


def test_the_layer_rule_sees_an_upward_import_inside_a_subpackage(tmp_path, monkeypatch):
    """The rule between a subpackage's modules is enforced, not only stated: a planted engine-neutral
    module importing an engine's module (a layer above it) is caught, the import down is not."""
    pkg = tmp_path / "sim" / "engines"
    pkg.mkdir(parents=True)
    for name in PACKAGE_LAYERS["sim.engines"]:
        (pkg / f"{name}.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "bullet.py").write_text("from symrom.sim.engines.world import World\n")  # down: fine
    (pkg / "world.py").write_text("x = 1\n\n\ndef f():\n    from symrom.sim.engines.bullet import p\n")  # up
    here = sys.modules[__name__]
    monkeypatch.setattr(here, "SRC", tmp_path)
    monkeypatch.setattr(here, "PACKAGE_LAYERS", {"sim.engines": PACKAGE_LAYERS["sim.engines"]})
    with pytest.raises(AssertionError) as caught:
        test_imports_inside_packages_only_point_down()
    assert str(caught.value).splitlines()[0] == "sim/engines/world.py:5 imports symrom.sim.engines.bullet"
    assert "bullet.py" not in str(caught.value)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of ``graph`` (module -> modules it imports): its strongly connected
    components of more than one module, or of one that imports itself (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph.get(v, ()):
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle_anywhere():
    """No module imports, directly or through others, itself: at module level, inside
    functions (lazy imports) or through a package's __init__."""
    graph = {}
    for path, rel, _ in _modules():
        graph[_module_name(rel)] = {m for m, _ in _imports(path, runtime_only=True)}
    circles = _cycles(graph)
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


def test_the_library_never_prints_or_exits():
    found = []
    for path, rel, layer in _modules():
        if layer == "cli":
            continue
        for node in _nodes(path):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
                if name in ("print", "exit", "quit", "echo") or (name == "_exit"):
                    found.append(f"{rel}:{node.lineno} calls {name}")
    assert not found, "\n".join(found)


def test_compiled_execution_has_one_entry_point():
    """Outside ``symrom/compiled/`` the compiled execution is reached through the package
    itself (``symrom.compiled``), never through one of its modules."""
    found = []
    for path, rel, layer in _modules():
        if layer == "compiled":
            continue
        for module, line in _imports(path):
            if module.startswith("symrom.compiled."):
                found.append(f"{rel}:{line} imports {module}")
    assert not found, "\n".join(found)


def test_the_compiled_code_knows_no_model():
    """``symrom/compiled/`` reads typed descriptions (``LatentDynamics``, ``TermLibrary``,
    ``LinearMaps``): it names no class of the model's, not even for a type checker."""
    found = []
    for path in sorted((SRC / "compiled").rglob("*.py")):
        found += [f"{path.relative_to(SRC)} names {name}" for name in ("HybridModel", "Library", "LinearAutoencoder")
                  if any(isinstance(n, ast.Name) and n.id == name or isinstance(n, ast.alias) and n.name == name
                         for n in _nodes(path))]
    assert not found, "\n".join(found)


def test_the_rollout_layer_knows_no_model():
    """rollout/ integrates any ``RolloutSystem``: it never names the learned model's drive
    entries (its latent inputs ``nu`` and ``phase``); the model's ``GeneratedCode`` reads them."""
    found = []
    for path in sorted((SRC / "rollout").rglob("*.py")):
        for node in _nodes(path):
            if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) \
                    and node.slice.value in ("nu", "phase"):
                found.append(f"{path.relative_to(SRC)}:{node.lineno} reads [{node.slice.value!r}]")
    assert not found, "\n".join(found)


def test_the_planner_composes_the_simulator_through_public_names():
    """plan/ drives the pronk through its push policy and read-only properties: it subclasses
    nothing of sim/ and reads no private attribute (``obj._name``) of anything but itself."""
    found = []
    for path in sorted((SRC / "plan").rglob("*.py")):
        from_sim = {a.asname or a.name for node in _nodes(path) if isinstance(node, ast.ImportFrom)
                    and (node.module or "").startswith("symrom.sim") for a in node.names}
        for node in _nodes(path):
            if isinstance(node, ast.ClassDef):
                found += [f"{path.name}:{node.lineno} subclasses {b.id}" for b in node.bases
                          if isinstance(b, ast.Name) and b.id in from_sim]
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                    and not (isinstance(node.value, ast.Name) and node.value.id == "self")):
                found.append(f"{path.name}:{node.lineno} reads {ast.unparse(node)}")
    assert not found, "\n".join(found)


FLAG = re.compile(r"(?<![\w-])--[a-z][a-z-]+")
# Messages that name another program's command line, not a parameter of the library.
COMMAND_LINES = ("symrom ", "ray start")


def test_library_messages_name_parameters_not_flags():
    """Library errors name the library's parameters (``split='x'``, ``force=True``); the command
    line maps them to its flags (``symrom.cli.common.flag_text``). Docstrings may name flags."""
    found = []
    for path, rel, layer in _modules():
        if layer == "cli":
            continue
        docs = {id(n.body[0].value) for n in _nodes(path)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and n.body
                and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        texts, parts = [], set()
        for node in _nodes(path):  # an f-string as one text, its constant parts joined
            if isinstance(node, ast.JoinedStr):
                consts = [v for v in node.values if isinstance(v, ast.Constant)]
                parts |= {id(v) for v in consts}
                texts.append((node.lineno, "".join(str(v.value) for v in consts)))
        texts += [(n.lineno, n.value) for n in _nodes(path) if isinstance(n, ast.Constant)
                  and isinstance(n.value, str) and id(n) not in docs | parts]
        found += [f"{rel}:{line}: {text[:80]!r}" for line, text in texts
                  if FLAG.search(text) and not any(c in text for c in COMMAND_LINES)]
    assert not found, "\n".join(found)
