"""The data flows one way (DESIGN.md, "Layout"): drive log -> clip store -> samplers -> model
-> predictions -> metrics. A module imports only what lies upstream of it; these checks fail on
an import that runs backwards, wherever it is written (module level or inside a function)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# package (a folder) -> the lanelab packages it must never import
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


def backward_imports(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    found = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        allowed = ALLOWED.get(str(path.relative_to(ROOT)), ())
        for name in imported_modules(path):
            if any(name == bad or name.startswith(bad + ".") for bad in forbidden) and not any(
                    name == ok or name.startswith(ok + ".") for ok in allowed):
                found.append(f"{path.relative_to(ROOT)} imports {name}")
    return found


@pytest.mark.parametrize("folder", sorted(FORBIDDEN))
def test_no_import_runs_backwards(folder):
    assert (ROOT / folder).is_dir(), f"{folder} is gone: update FORBIDDEN"
    assert backward_imports(folder, FORBIDDEN[folder]) == []


def test_the_check_sees_a_backward_import(tmp_path, monkeypatch):
    bad = tmp_path / "pkg"
    bad.mkdir()
    (bad / "mod.py").write_text("def f():\n    from lanelab.metrics import openlane\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert backward_imports("pkg", ("lanelab.metrics",)) == ["pkg/mod.py imports lanelab.metrics"]


@pytest.mark.parametrize("module", ["lanelab.lanes", "lanelab.store", "lanelab.openlane"])
def test_stages_before_the_model_load_no_torch(module):
    code = f"import sys, {module}; sys.exit('torch' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0, f"{module} imports torch"
