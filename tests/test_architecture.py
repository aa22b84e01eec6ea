"""Rules of the house, checked on the source: imports only point down; the library never
prints or exits (the command line does)."""

from __future__ import annotations

import ast
from pathlib import Path

import symrom

SRC = Path(symrom.__file__).parent

# Layers from the ground floor up (docs/design.md, "Layout"): a module may import its own
# layer and those below it.
LAYERS: dict[str, int] = {
    "names": 0, "atomic": 0, "motions": 0, "execution": 0,
    "robots": 1,
    "data": 2,
    "sim": 3, "rollout": 3,
    "model": 4, "baselines": 4,
    "testing": 5, "evaluate": 5,
    "experiments": 6,
    "report": 7,
    "cli": 8,
}
# Known upward imports, each with the change that removes it (none today).
KNOWN: set[tuple[str, str]] = set()


def _layer(module: str) -> str:
    return module.split(".")[1] if module.count(".") else ""


def _imports(path: Path) -> list[tuple[str, int]]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("symrom."):
            out.append((node.module, node.lineno))
        elif isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names if a.name.startswith("symrom.")]
    return out


def _modules():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC)
        yield path, rel, (rel.parts[0][:-3] if len(rel.parts) == 1 else rel.parts[0])


def test_every_module_has_a_layer():
    assert {layer for _, _, layer in _modules()} - {"__init__"} == set(LAYERS)


def test_imports_only_point_down():
    upward = []
    for path, rel, layer in _modules():
        if layer == "__init__":
            continue
        for module, line in _imports(path):
            target = _layer(module)
            if LAYERS[target] > LAYERS[layer] and (layer, target) not in KNOWN:
                upward.append(f"{rel}:{line} imports {module}")
    assert not upward, "\n".join(upward)


def test_the_library_never_prints_or_exits():
    found = []
    for path, rel, layer in _modules():
        if layer == "cli":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
                if name in ("print", "exit", "quit", "echo") or (name == "_exit"):
                    found.append(f"{rel}:{node.lineno} calls {name}")
    assert not found, "\n".join(found)
