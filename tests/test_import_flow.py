"""The data flows one way (DESIGN.md, "Layout"): drive log -> clip store -> samplers -> model
-> predictions -> metrics. A module imports only what lies upstream of it; these checks fail on
an import that runs backwards, wherever it is written (module level, inside a function or under
``TYPE_CHECKING``), and on any loop among the project's modules.

Within the models (docs/concepts/layout.md): the contract (``models/api.py``, ``categories.py``)
knows no model; the parts both detectors share (``models/parts``) know neither detector; the
detectors (``models/sparselanestp``, ``models/bi2lane``) do not know each other; the run-time
machinery (``lanelab.runtime``: CUDA graphs, the operator log, the recorded picks) lies below the
models and knows none; ``lanelab.deploy`` (the exported explicit state among it) lies above them."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

DETECTORS = ("lanelab.models.sparselanestp", "lanelab.models.bi2lane")
# package (a folder, or one module) -> the lanelab packages it must never import
FORBIDDEN = {
    "src/lanelab": ("data_ingest", "log_predict"),  # lanelab never imports the ingestor, nor lanelab-predict
    "data_ingest": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                    "lanelab.metrics", "lanelab.evaluation", "lanelab.deploy", "log_predict"),
    "src/lanelab/store": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                          "lanelab.metrics", "lanelab.evaluation", "data_ingest"),
    "src/lanelab/openlane": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                             "lanelab.metrics", "lanelab.evaluation", "data_ingest"),
    "src/lanelab/once": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                         "lanelab.metrics", "lanelab.evaluation", "data_ingest"),
    "src/lanelab/data": ("lanelab.models", "lanelab.lightning", "lanelab.experiment", "lanelab.metrics",
                         "lanelab.evaluation", "data_ingest"),
    "src/lanelab/models": ("lanelab.data", "lanelab.lightning", "lanelab.experiment", "lanelab.metrics",
                           "lanelab.evaluation", "lanelab.deploy", "data_ingest", "lightning", "hydra", "omegaconf"),
    "src/lanelab/models/api.py": ("lanelab.models.parts", *DETECTORS, "lanelab.runtime"),
    "src/lanelab/models/categories.py": ("lanelab.models.parts", *DETECTORS, "lanelab.runtime"),
    "src/lanelab/models/parts": DETECTORS,
    "src/lanelab/models/sparselanestp": ("lanelab.models.bi2lane",),
    "src/lanelab/models/bi2lane": ("lanelab.models.sparselanestp",),
    "src/lanelab/runtime": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                            "lanelab.metrics", "lanelab.evaluation", "lanelab.deploy", "data_ingest", "lightning",
                            "hydra", "omegaconf"),
    "src/lanelab/metrics": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                            "lanelab.evaluation", "data_ingest"),
    "src/lanelab/evaluation": ("lanelab.data", "lanelab.models", "lanelab.lightning", "lanelab.experiment",
                               "data_ingest"),
    "src/lanelab/geometry": ("lanelab.store", "lanelab.data", "lanelab.models", "lanelab.lightning",
                             "lanelab.experiment", "lanelab.metrics", "lanelab.evaluation", "data_ingest"),
}  # fmt: skip
# The exceptions, each a file and what it may import against the flow, and why.
ALLOWED = {
    # The auto-labeler's quality report scores labels against labels before they are stored:
    # with the OpenLane metric and in lanelab's report and pictures, not with copies of them.
    "data_ingest/autolabel/quality.py": ("lanelab.metrics", "lanelab.evaluation"),
}


def imported_modules(path: Path) -> set[str]:
    """Every module an `import` or `from ... import` in the file names (relative ones resolved
    against the file's package)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the file's package
                package = path.relative_to(ROOT / "src" if path.is_relative_to(ROOT / "src") else ROOT).parent.parts
                base = ".".join(package[: len(package) - node.level + 1])
                names.add(f"{base}.{node.module}" if node.module else base)
            elif node.module:
                names.add(node.module)
    return names


# the installed packages: top folder -> the folder its package lives in (see pyproject's package-dir)
PACKAGES = {"src/lanelab": ROOT / "src", "data_ingest": ROOT, "log_predict": ROOT}


def module_name(path: Path, base: Path) -> str:
    """``base/a/b/c.py`` -> ``a.b.c``; a package's ``__init__.py`` is the package itself."""
    parts = path.relative_to(base).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(packages: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the project modules it imports. ``from pkg import name`` is an edge to the module
    ``pkg.name`` when there is one, else to ``pkg`` (its ``__init__``); parent packages that Python
    runs on the way are not edges (a package's ``__init__`` importing its own modules is no loop)."""
    files = {module_name(path, base): path
             for folder, base in packages.items() for path in (ROOT / folder).rglob("*.py")}
    graph = {}
    for module, path in files.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                edges.update(alias.name for alias in node.names if alias.name in files)
            elif isinstance(node, ast.ImportFrom):
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1]) if node.level else ""
                target = ".".join(filter(None, (base, node.module)))
                for alias in node.names:
                    if f"{target}.{alias.name}" in files:
                        edges.add(f"{target}.{alias.name}")
                    elif target in files:
                        edges.add(target)
        graph[module] = edges
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The graph's loops: each strongly connected component of more than one module, and each
    module that imports itself (Tarjan's algorithm, iterative: no recursion limit to meet)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, successors = work[-1]
            child = next(successors, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while not component or component[-1] != node:
                    component.append(stack.pop())
                    on_stack.discard(component[-1])
                if len(component) > 1 or node in graph[node]:
                    cycles.append(sorted(component))
    return sorted(cycles)


def backward_imports(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    found = []
    root = ROOT / folder
    for path in [root] if root.is_file() else sorted(root.rglob("*.py")):
        allowed = ALLOWED.get(str(path.relative_to(ROOT)), ())
        for name in imported_modules(path):
            if any(name == bad or name.startswith(bad + ".") for bad in forbidden) and not any(
                    name == ok or name.startswith(ok + ".") for ok in allowed):
                found.append(f"{path.relative_to(ROOT)} imports {name}")
    return found


@pytest.mark.parametrize("folder", sorted(FORBIDDEN))
def test_no_import_runs_backwards(folder):
    assert (ROOT / folder).exists(), f"{folder} is gone: update FORBIDDEN"
    assert backward_imports(folder, FORBIDDEN[folder]) == []


def test_the_check_sees_a_backward_import(tmp_path, monkeypatch):
    bad = tmp_path / "pkg"
    bad.mkdir()
    (bad / "mod.py").write_text("def f():\n    from lanelab.metrics import openlane\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert backward_imports("pkg", ("lanelab.metrics",)) == ["pkg/mod.py imports lanelab.metrics"]


def test_no_import_loop():
    graph = import_graph(PACKAGES)
    assert "data_ingest.ingest.log_result" in graph["data_ingest.ingest.summary"]  # the graph sees the project
    assert import_cycles(graph) == []


def test_the_check_sees_an_import_loop(tmp_path, monkeypatch):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    for name in ("__init__.py", "sub/__init__.py"):
        (package / name).write_text("")
    (package / "a.py").write_text("from pkg.sub import b\n")  # a -> b -> c -> a, c under TYPE_CHECKING
    (package / "sub" / "b.py").write_text("def f():\n    from ..c import g\n")
    (package / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pkg.a\n")
    (package / "d.py").write_text("from . import d\nfrom pkg import a\n")  # d imports itself; d -> a is no loop
    (package / "e.py").write_text("from pkg import sub\n")  # the package's __init__, no loop
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert import_cycles(import_graph({"pkg": tmp_path})) == [["pkg.a", "pkg.c", "pkg.sub.b"], ["pkg.d"]]


@pytest.mark.parametrize("module", ["lanelab.lanes", "lanelab.store", "lanelab.openlane"])
def test_stages_before_the_model_load_no_torch(module):
    code = f"import sys, {module}; sys.exit('torch' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0, f"{module} imports torch"
