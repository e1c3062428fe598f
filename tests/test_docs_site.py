"""The documentation site's generated parts stay true: the CLI reference lists the options the
tools really take, the results page's numbers are RESULTS.md's, and CITATION.cff is valid."""

import dataclasses
import importlib
import importlib.util
import re
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def _hook(name: str):
    spec = importlib.util.spec_from_file_location(f"docs_hook_{name}", ROOT / "docs" / "hooks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


cli_reference = _hook("cli_reference")
results_history = _hook("results_history")


@pytest.fixture(scope="module")
def pages() -> dict[str, str]:
    return cli_reference.cli_pages()


def _listed_options(page: str) -> list[str]:
    options = page.split("## Options", 1)[1]
    return [key for key in re.findall(r"^\| `([^`]+)` \|", options, flags=re.M) if not key.endswith(".*")]


@pytest.mark.parametrize("tool", cli_reference.HYDRA_TOOLS, ids=lambda tool: tool.command)
def test_cli_reference_lists_exactly_the_composed_options(pages, tool):
    composed = cli_reference.compose_tool(tool)
    page = pages[f"reference/cli/{tool.command}.md"]
    listed = _listed_options(page)
    leaves = [key for key, _ in cli_reference.flatten(composed.values)]
    assert listed == leaves
    top_level = {key.split(".")[0] for key in listed}
    assert top_level == set(composed.values)  # every top-level key of the composed config, none other
    schema = getattr(importlib.import_module(tool.schema_module), tool.schema_class)
    assert top_level == {field.name for field in dataclasses.fields(schema)}  # the keys the tool accepts


def test_cli_reference_shows_defaults_comments_and_groups(pages):
    ingest = pages["reference/cli/lanelab-ingest.md"]
    assert "| `clips.gap_s` | `0.5` | a clip ends where consecutive images are further apart |" in ingest
    assert "| `autolabel.projection_range_m` | `[3.0, 40.0]` |" in ingest
    train = pages["reference/cli/lanelab-train.md"]
    assert re.search(r"^\| `model` \| `sparselanestp` \| .*`bi2lane`", train, flags=re.M)
    demo = pages["reference/cli/lanelab-demo.md"]
    assert re.search(r"^\| `experiment` \| `demo` \|", demo, flags=re.M)
    assert "--out" in pages["reference/cli/lanelab-sweep-report.md"]


def test_yaml_comments_inline_continued_above_and_quoted():
    text = (
        "# file header\n"
        "top: 1            # inline\n"
        "                  # continued\n"
        "# about the section\n"
        "section:\n"
        "  key: 'a # b'    # after a quoted hash\n"
        "  other: 2\n"
    )
    comments = cli_reference.yaml_comments(text)
    assert comments["top"] == "inline continued"
    assert comments["section"] == "about the section"
    assert comments["section.key"] == "after a quoted hash"
    assert "section.other" not in comments


def test_results_numbers_of_record_are_results_md_rows():
    record = (ROOT / "docs" / "results.md").read_text()
    results = set((ROOT / "benchmarks" / "RESULTS.md").read_text().splitlines())
    rows = [line for line in record.splitlines() if line.startswith("|")]
    assert len(rows) > 40
    stale = [row for row in rows if row not in results]
    assert not stale, f"docs/results.md rows no longer in benchmarks/RESULTS.md: {stale[:3]}"


def test_results_history_demotes_headings_and_points_pictures_at_the_site():
    text = "# Title\n\n## Round\n\n```bash\n# a comment\n```\n\n![curves](learning_curves.png)\n"
    history = results_history.history_markdown(text)
    assert "# Title" not in history
    assert "### Round" in history
    assert "\n# a comment\n" in history
    assert "![curves](benchmark_pictures/learning_curves.png)" in history
    assert results_history.pictures(text) == ["learning_curves.png"]
    for name in results_history.pictures(results_history.RESULTS.read_text()):
        assert (ROOT / "benchmarks" / name).is_file(), name


def test_citation_cff_is_valid_and_current():
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = pyproject["project"]
    # the release the tree builds: a static version, or setuptools-scm's for a tree without tags
    release = project.get("version") or pyproject["tool"]["setuptools_scm"]["fallback_version"]
    assert citation["cff-version"] == "1.2.0"
    for key in ("message", "title", "authors"):
        assert citation[key], key
    assert release.startswith(citation["version"])
    assert citation["license"] == project["license"]
    titles = " ".join(reference["title"] for reference in citation["references"])
    assert "SparseLaneSTP" in titles and "Bi²Lane" in titles
