"""The import graph of src/imupipe, read with `ast` (no module is imported): every module sits in a layer and
imports only modules of its own layer or below ("no upward import"), and no chain of imports comes back to
where it started (no cycle). Imports inside functions count as well: a deferred import is still a dependency.

Layers, bottom up: files, units and containers; estimators and the noise model; what builds on the model;
identification and stationarity; bounding and the Kalman filter; figures.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "imupipe"

LAYERS = [
    {"__init__", "_kernels", "units", "io", "labelled", "search"},
    {"models", "allan", "spectra", "simulate", "merge", "readers", "lines", "outliers", "summary"},
    {"avcov", "specsheet"},
    {"identify", "stationarity"},
    {"bound", "kf", "kalibr"},
    {"verify", "plot"},
    {"api", "cli", "__main__"},
]
LAYER_OF = {name: i for i, layer in enumerate(LAYERS) for name in layer}


def modules() -> dict[str, list[Path]]:
    """Top-level modules of imupipe, each with its files: a package (a folder with __init__.py) is one node
    made of all its files."""
    found = {p.stem: [p] for p in sorted(PACKAGE.glob("*.py"))}
    found |= {p.name.split(".")[0]: [p] for p in PACKAGE.glob("_kernels*.c")}
    found |= {d.name: sorted(d.rglob("*.py")) for d in sorted(PACKAGE.iterdir())
              if d.is_dir() and (d / "__init__.py").exists()}
    return found


def imports_of(path: Path, package: tuple[str, ...] = ()) -> set[str]:
    """Names of the top-level imupipe modules that the Python file `path` imports (at any depth of the file).

    `package` is the dotted place of the file's folder below imupipe (``("bound",)`` for bound/engine.py), so
    that relative imports resolve; the file's own top-level module is left out.
    """
    if path.suffix != ".py":
        return set()
    tree = ast.parse(path.read_text(), filename=str(path))
    here = ("imupipe", *package)
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "imupipe" and len(parts) > 1:
                    found.add(parts[1])
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from . import x / from .x import y / from ..x import y
                base = list(here[:len(here) - node.level + 1])
                parts = base + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == "imupipe":
                parts = node.module.split(".")
            else:
                continue
            found |= {parts[1]} if len(parts) > 1 else {a.name for a in node.names}
    own = package[0] if package else path.stem
    return found - {own}


def graph() -> dict[str, set[str]]:
    return {name: set().union(*(imports_of(p, p.relative_to(PACKAGE).parent.parts) for p in paths))
            for name, paths in modules().items()}


def test_every_module_has_a_layer():
    missing = sorted(set(modules()) - set(LAYER_OF))
    assert not missing, f"modules without a layer in tests/test_import_graph.py: {missing}"


def test_the_graph_is_read():
    # the parser sees known edges (guards against a test that passes because it reads nothing)
    g = graph()
    assert "models" in g["specsheet"] and "_kernels" in g["allan"] and "io" in g["labelled"]


def test_no_upward_import():
    upward = [f"{mod} (layer {LAYER_OF[mod]}) imports {dep} (layer {LAYER_OF[dep]})"
              for mod, deps in graph().items() for dep in sorted(deps)
              if dep in LAYER_OF and mod in LAYER_OF and LAYER_OF[dep] > LAYER_OF[mod]]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_no_import_cycle():
    g = graph()
    state, cycles = {}, []

    def visit(node, stack):
        state[node] = "open"
        for dep in sorted(g.get(node, ())):
            if state.get(dep) == "open":
                cycles.append(" -> ".join(stack[stack.index(dep):] + [dep]))
            elif dep not in state:
                visit(dep, stack + [dep])
        state[node] = "done"

    for name in sorted(g):
        if name not in state:
            visit(name, [name])
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


@pytest.mark.parametrize("source, expected", [
    ("import imupipe.models\n", {"models"}),
    ("from imupipe import units as u\n", {"units"}),
    ("def f():\n    from imupipe.spectra import psd\n", {"spectra"}),
    ("from . import allan\nfrom .io import read_yaml\n", {"allan", "io"}),
    ("import numpy\nfrom scipy import signal\n", set()),
])
def test_imports_of_reads_every_form(tmp_path, source, expected):
    path = tmp_path / "mod.py"
    path.write_text(source)
    assert imports_of(path) == expected


@pytest.mark.parametrize("source, expected", [
    ("from .engine import bound_psd\n", set()),  # inside its own package
    ("from ..models import NoiseModel\n", {"models"}),
    ("from imupipe.bound.report import x\nfrom imupipe.units import SI_UNITS\n", {"units"}),
])
def test_imports_of_resolves_inside_a_package(tmp_path, source, expected):
    path = tmp_path / "mod.py"
    path.write_text(source)
    assert imports_of(path, ("bound",)) == expected


def test_packages_are_nodes():
    g = graph()
    assert {"bound", "readers"} <= set(g) and "units" in g["readers"] and "models" in g["bound"]
