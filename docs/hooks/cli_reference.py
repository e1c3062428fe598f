"""MkDocs hook: the CLI reference, one page per console script, generated from ``conf/``.

Each Hydra tool's page is its config composed as the tool composes it (the same yaml, schema and
defaults list), flattened to ``key = default`` rows with the comment the yaml gives each key, so
the reference cannot drift from the options the tools take. ``lanelab-sweep-report`` takes plain
arguments; its page is its ``--help``. Registered in ``mkdocs.yml`` under ``hooks:``; the pages
are generated files of the build (nothing is written into ``docs/``).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"
PAGE_DIR = "reference/cli"


@dataclass(frozen=True)
class HydraTool:
    """A console script that composes ``conf/<config_name>.yaml`` (with ``overrides``)."""

    command: str
    config_name: str
    schema_module: str  # the module holding SCHEMA_NAME and the schema dataclass
    schema_class: str
    overrides: tuple[str, ...] = ()


HYDRA_TOOLS = (
    HydraTool("lanelab-synth", "synth", "data_ingest.synth.config", "SynthConfig"),
    HydraTool("lanelab-ingest", "ingest", "data_ingest.ingest.config", "IngestConfig"),
    HydraTool("lanelab-openlane", "openlane", "data_ingest.openlane.config", "OpenLaneAdapterConfig"),
    HydraTool("lanelab-once", "once", "data_ingest.once.config", "OnceAdapterConfig"),
    HydraTool("lanelab-train", "train", "lanelab.experiment.config", "TrainConfig"),
    HydraTool("lanelab-demo", "train", "lanelab.experiment.config", "TrainConfig", ("experiment=demo",)),
    HydraTool("lanelab-eval", "eval", "lanelab.evaluation.config", "EvalConfig"),
    HydraTool("lanelab-predict", "predict", "log_predict.config", "PredictConfig"),
    HydraTool("lanelab-export", "export", "lanelab.deploy.config", "ExportConfig"),
)

@dataclass(frozen=True)
class ToolConfig:
    """A tool's composed config (unresolved, without ``hydra``), the yaml comment of each dotted
    key, its config groups' choices (group -> option) and its ``--help`` header."""

    values: dict[str, Any]
    comments: dict[str, str]
    choices: dict[str, str | None]
    header: str


_KEY_LINE = re.compile(r"^(?P<indent> *)(?P<key>[A-Za-z_][\w@-]*):(?P<rest>.*)$")
_COMMENT_LINE = re.compile(r"^(?P<indent> *)#(?P<text>.*)$")


def yaml_comments(text: str) -> dict[str, str]:
    """Each key's comment in one yaml file, by dotted path relative to the file's package.

    A key's comment is the ``#`` text after its value, continued by the comment-only lines below
    it that start right of the key's name, or else the block of comment lines right above the key.
    """
    comments: dict[str, str] = {}
    stack: list[tuple[int, str]] = []
    above: list[str] = []
    last_key, key_end = None, -1
    for line in text.splitlines():
        comment = _COMMENT_LINE.match(line)
        if comment:
            if last_key is not None and line.index("#") > key_end:  # right of the key: its comment goes on
                comments[last_key] += " " + comment["text"].strip()
            elif not comment["text"].startswith(" @package"):
                above.append(comment["text"].strip())
            continue
        match = _KEY_LINE.match(line)
        if not match:  # a list item, a block scalar's text or a blank line ends a comment block
            above, last_key = [], None
            continue
        indent = len(match["indent"])
        while stack and stack[-1][0] >= indent:
            stack.pop()
        stack.append((indent, match["key"]))
        path = ".".join(key for _, key in stack)
        value, hash_sign, inline = _split_comment(match["rest"])
        text_of_key = inline.strip() if hash_sign else " ".join(above)
        last_key, key_end = (path if hash_sign else None), indent + len(match["key"])
        if text_of_key:
            comments[path] = text_of_key
        above = []
    return comments


def _split_comment(rest: str) -> tuple[str, str, str]:
    """``value``, ``#`` or ``""``, and the comment of what follows a key's colon (``#`` inside
    quotes is part of the value)."""
    quote = None
    for i, char in enumerate(rest):
        if char in "'\"" and quote in (None, char):
            quote = None if quote else char
        elif char == "#" and quote is None and (i == 0 or rest[i - 1] in " \t"):
            return rest[:i], "#", rest[i + 1:]
    return rest, "", ""


def compose_tool(tool: HydraTool) -> ToolConfig:
    """The tool's config composed as the tool composes it, with the comments of every yaml it was
    composed from."""
    from hydra import compose, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import RunMode

    from lanelab.config_checks import register_schema

    module = importlib.import_module(tool.schema_module)
    register_schema(module.SCHEMA_NAME, getattr(module, tool.schema_class))
    with initialize_config_module(config_module="lanelab.conf", version_base="1.3"):
        cfg = compose(config_name=tool.config_name, overrides=list(tool.overrides), return_hydra_config=True)
        defaults = GlobalHydra.instance().config_loader().compute_defaults_list(
            tool.config_name, list(tool.overrides), RunMode.RUN)
    comments: dict[str, str] = {}
    for default in defaults.defaults:  # in composition order: a later file's comment wins, as its value does
        path = CONF_DIR / f"{default.config_path}.yaml"
        if default.config_path is None or not path.is_file() or default.package.startswith("hydra"):
            continue
        prefix = f"{default.package}." if default.package else ""
        for key, text in yaml_comments(path.read_text()).items():
            if not key.startswith(("defaults", "hydra")):
                comments[prefix + key] = text
    choices = {group: choice for group, choice in cfg.hydra.runtime.choices.items() if not group.startswith("hydra")}
    header = OmegaConf.select(cfg, "hydra.help.header", default="") or ""
    values = OmegaConf.to_container(cfg, resolve=False, throw_on_missing=False)
    values.pop("hydra")
    return ToolConfig(values, comments, choices, header)


def flatten(values: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """``(dotted key, value)`` of every leaf of a config container; an empty dict or list is a leaf."""
    if isinstance(values, dict) and values:
        rows = []
        for key, value in values.items():
            rows += flatten(value, f"{prefix}{key}.")
        return rows
    return [(prefix[:-1], values)]


def _cell(value: Any) -> str:
    if value == "???":
        text = "required"
    elif value is None:
        text = "null"
    elif isinstance(value, bool):
        text = str(value).lower()
    else:
        text = json.dumps(value) if isinstance(value, (dict, list)) else str(value)
    return "`" + text.replace("|", "\\|").replace("`", "'") + "`"


def _comment_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def tool_page(tool: HydraTool) -> str:
    """The markdown of one Hydra tool's reference page."""
    composed = compose_tool(tool)
    yaml_name = f"conf/{tool.config_name}.yaml"
    lines = [f"# `{tool.command}`", "",
             f"Generated from `{yaml_name}` and the files its defaults list names, composed as "
             f"`{tool.command}` composes them" + (f" (with `{' '.join(tool.overrides)}`)" if tool.overrides else "")
             + ". Every option is a `key=value` override on the command line; a bad one is named in one line "
             "(exit status 2).", ""]
    if composed.header:
        lines += ["```text", composed.header.rstrip(), "```", ""]
    groups = {group: choice for group, choice in composed.choices.items() if group}
    if groups:
        lines += ["## Config groups", "", "Chosen with `group=option` (the options are the files under `conf/<group>/`).", "",
                  "| group | default | options |", "|---|---|---|"]
        for group, choice in groups.items():
            options = ", ".join(f"`{name}`" for name in group_options(group))
            lines.append(f"| `{group}` | {_cell(choice)} | {options} |")
        lines.append("")
    lines += ["## Options", "", "| option | default | what it sets |", "|---|---|---|"]
    described: set[str] = set()
    for key, value in flatten(composed.values):
        parts = key.split(".")
        for depth in range(1, len(parts)):  # a section's comment (the block above `autolabel:`) once, above its keys
            section = ".".join(parts[:depth])
            if section in composed.comments and section not in described:
                described.add(section)
                lines.append(f"| `{section}.*` | | {_comment_cell(composed.comments[section])} |")
        lines.append(f"| `{key}` | {_cell(value)} | {_comment_cell(composed.comments.get(key, ''))} |")
    return "\n".join(lines) + "\n"


def group_options(group: str) -> list[str]:
    """The options of a config group: the yaml files (and sub-folders of variants) under ``conf/<group>/``."""
    folder = CONF_DIR / group.split("@")[0]
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.yaml"))


def sweep_report_page() -> str:
    """The markdown of ``lanelab-sweep-report``'s page: its ``--help``."""
    from lanelab.experiment.sweep_report import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
        main(["--help"])
    return ("# `lanelab-sweep-report`\n\nGenerated from the command's own `--help` (it takes plain arguments, "
            "not Hydra overrides).\n\n```text\n" + out.getvalue().rstrip() + "\n```\n")


def cli_pages() -> dict[str, str]:
    """Every generated page, by its path under ``docs/``."""
    pages = {f"{PAGE_DIR}/{tool.command}.md": tool_page(tool) for tool in HYDRA_TOOLS}
    pages[f"{PAGE_DIR}/lanelab-sweep-report.md"] = sweep_report_page()
    return pages


def on_files(files: Any, config: Any) -> Any:
    """MkDocs event: add the generated pages to the site's files."""
    from mkdocs.structure.files import File

    for path, content in cli_pages().items():
        files.append(File.generated(config, path, content=content))
    return files
