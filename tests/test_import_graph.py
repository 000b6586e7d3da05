"""The import graph of src/imupipe, read with `ast` (no module is imported): every module sits in a layer and
imports only modules of its own layer or below ("no upward import"), and no chain of imports comes back to
where it started (no cycle). Imports inside functions count as well: a deferred import is still a dependency.

Private names (a leading underscore, dunders aside) stay inside their top-level module: the workflow (scripts and
Snakemake rule files) uses the public API only, and a library module does not reach into another's private names
(the compiled kernels `_kernels` excepted: a private module of the whole library, with a NumPy fallback beside
each use).

Layers, bottom up: files, units and containers; estimators and the noise model; what builds on the model;
identification and stationarity; bounding and the Kalman filter; verification and figures; the workflow's stages
(imupipe.stages: one module per rule, calling the layers below); the one-call API, the recording plan (which runs
the identification stage on its expected data) and the command line.
"""

from __future__ import annotations

import ast
import re
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "imupipe"
WORKFLOW = ROOT / "workflow"
#: private modules any library module may import (see the module docstring)
SHARED_PRIVATE = {"_kernels"}

LAYERS = [
    {"__init__", "_kernels", "backend", "units", "io", "labelled", "search", "defaults", "markdown"},
    {"models", "inband", "covariance", "allan", "spectra", "simulate", "merge", "readers", "lines", "outliers",
     "events", "segments", "stretches", "summary", "shown", "verdict", "linewords", "eventwords", "paste",
     "flagtext"},
    {"avcov", "specsheet", "init", "runconfig"},
    {"identify", "stationarity"},
    {"bound", "kf", "kalibr", "biasinit"},
    {"verify", "plot"},
    {"stages"},
    {"api", "cli", "__main__", "plan"},
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


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_uses(tree: ast.AST, package: tuple[str, ...] = ()) -> list[tuple[str, str, int]]:
    """(top-level imupipe module, dotted private name, line) of every private imupipe name the code in `tree`
    imports or reads as an attribute of an imported imupipe module: ``from imupipe.x import _y``,
    ``from imupipe.x._m import y``, ``import imupipe._m``, ``m._y`` after ``from imupipe import m`` or
    ``import imupipe.m as m``. `package` as in :func:`imports_of` (relative imports)."""
    here = ("imupipe", *package)
    found, modules_bound = [], {}  # local name -> dotted imupipe module it stands for
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] != "imupipe":
                    continue
                if any(_private(p) for p in parts[1:]):
                    found.append((parts[1], alias.name, node.lineno))
                modules_bound[alias.asname or "imupipe"] = alias.name if alias.asname else "imupipe"
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = list(here[:len(here) - node.level + 1]) + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == "imupipe":
                parts = node.module.split(".")
            else:
                continue
            for alias in node.names:
                full = [*parts, alias.name]
                top = full[1] if len(full) > 1 else alias.name
                if any(_private(p) for p in full[1:]):
                    found.append((top, ".".join(full), node.lineno))
                modules_bound[alias.asname or alias.name] = ".".join(full)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            root = node.value
            while isinstance(root, ast.Attribute):
                root = root.value
            if isinstance(root, ast.Name) and root.id in modules_bound:
                dotted = f"{modules_bound[root.id]}.{ast.unparse(node)[len(root.id) + 1:]}"
                found.append((dotted.split(".")[1], dotted, node.lineno))
    return found


_SMK_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+imupipe[\w.]*[ \t]+import[ \t]+(?:\([^)]*\)|[^\n]*)"
                         r"|import[ \t]+imupipe[^\n]*)", re.M)


def workflow_private_uses() -> list[str]:
    """Every private imupipe name used by a workflow script (parsed whole) or a rule file (its imupipe import
    statements: a .smk file is not Python)."""
    out = []
    for path in sorted(WORKFLOW.rglob("*.py")):
        out += [f"{path.relative_to(ROOT)}:{line}: {name}" for _, name, line in
                private_uses(ast.parse(path.read_text(), filename=str(path)))]
    for path in sorted([*WORKFLOW.rglob("*.smk"), ROOT / "Snakefile"]):
        text = path.read_text()
        for m in _SMK_IMPORT.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            tree = ast.parse(textwrap.dedent(m.group(0)).strip())
            out += [f"{path.relative_to(ROOT)}:{line}: {name}" for _, name, _ in private_uses(tree)]
    return out


def test_workflow_uses_public_names_only():
    used = workflow_private_uses()
    assert not used, "the workflow imports private imupipe names (make them public in their home):\n" + \
        "\n".join(used)


def test_workflow_check_reads_the_workflow():
    # the scan sees the workflow's known public imports (guards against a check that passes by reading nothing)
    scripts = list((WORKFLOW / "scripts").glob("*.py"))
    assert len(scripts) >= 10
    assert any(m for p in WORKFLOW.rglob("*.smk") for m in _SMK_IMPORT.findall(p.read_text()))


def test_no_private_import_across_modules():
    crossing = []
    for name, paths in modules().items():
        for path in paths:
            if path.suffix != ".py":
                continue
            pkg = path.relative_to(PACKAGE).parent.parts
            for top, dotted, line in private_uses(ast.parse(path.read_text(), filename=str(path)), pkg):
                if top != name and top not in SHARED_PRIVATE:
                    crossing.append(f"{path.relative_to(ROOT)}:{line}: {dotted}")
    assert not crossing, "private names used outside their module:\n" + "\n".join(crossing)


@pytest.mark.parametrize("source, expected", [
    ("from imupipe.bound import _to_spec_units\n", ["imupipe.bound._to_spec_units"]),
    ("def f():\n    from imupipe.readers._common import Key\n", ["imupipe.readers._common.Key"]),
    ("import imupipe._kernels\n", ["imupipe._kernels"]),
    ("from imupipe import bound\nbound._plain(1)\n", ["imupipe.bound._plain"]),
    ("import imupipe.bound as b\nb.report._x\n", ["imupipe.bound.report._x"]),
    ("import imupipe\nimupipe.io._y\n", ["imupipe.io._y"]),
    ("from ..models import _expm1x\n", ["imupipe.models._expm1x"]),
    ("from imupipe import __version__\nfrom imupipe.io import plain\nimport numpy as np\nnp._x\n", []),
])
def test_private_uses_reads_every_form(source, expected):
    assert [d for _, d, _ in private_uses(ast.parse(source), ("bound",))] == expected


def test_smk_scan_reads_a_rule_file_import():
    text = "rule a:\n    run:\n        from imupipe.io import (\n            plain,\n            _hidden)\n"
    stmts = [textwrap.dedent(m).strip() for m in _SMK_IMPORT.findall(text)]
    assert [d for s in stmts for _, d, _ in private_uses(ast.parse(s))] == ["imupipe.io._hidden"]


#: Longest function (lines from its first decorator or ``def`` to its last line, docstring included) and longest
#: module (lines) allowed in src/imupipe: a function over this does several jobs, a module over this several
#: topics (issue 30's limits; split into named steps or modules).
MAX_FUNCTION_LINES, MAX_MODULE_LINES = 150, 1300


def sizes(root: Path = PACKAGE) -> tuple[list[str], list[str]]:
    """(functions over MAX_FUNCTION_LINES, modules over MAX_MODULE_LINES) of the Python files under `root`, each
    as ``path:line name (n lines)``; nested functions and methods count on their own."""
    long_functions, long_modules = [], []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text()
        n = len(text.splitlines())
        where = path.relative_to(root.parent) if root == PACKAGE else path.name
        if n > MAX_MODULE_LINES:
            long_modules.append(f"{where} ({n} lines)")
        for node in ast.walk(ast.parse(text, filename=str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                length = node.end_lineno - first + 1
                if length > MAX_FUNCTION_LINES:
                    long_functions.append(f"{where}:{node.lineno} {node.name} ({length} lines)")
    return long_functions, long_modules


def test_no_function_or_module_over_the_limits():
    long_functions, long_modules = sizes()
    assert not long_functions, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(long_functions)
    assert not long_modules, f"modules over {MAX_MODULE_LINES} lines:\n" + "\n".join(long_modules)


def test_sizes_counts_docstrings_decorators_and_nesting(tmp_path):
    # a 151-line function (decorator and docstring included) and a nested one over the limit are found; a
    # 150-line one is not (guards against a check that passes by reading nothing)
    body = "\n".join(f"    x{k} = {k}" for k in range(MAX_FUNCTION_LINES - 3))
    (tmp_path / "ok.py").write_text(f'def ok():\n    """doc"""\n{body}\n    return 0\n')
    (tmp_path / "long.py").write_text(f'@staticmethod\ndef long():\n    """doc"""\n{body}\n    return 0\n')
    inner = "\n".join(f"        y{k} = {k}" for k in range(MAX_FUNCTION_LINES))
    (tmp_path / "nested.py").write_text(f"def outer():\n    def inner():\n{inner}\n    return inner\n")
    (tmp_path / "big.py").write_text("x = 0\n" * (MAX_MODULE_LINES + 1))
    long_functions, long_modules = sizes(tmp_path)
    assert sorted(f.split(" ")[1] for f in long_functions) == ["inner", "long", "outer"]
    assert long_modules == [f"big.py ({MAX_MODULE_LINES + 1} lines)"]
