"""MkDocs hook: the results page's diagnostic history is ``benchmarks/RESULTS.md`` itself.

``docs/results.md`` holds the numbers of record; below them this hook appends the whole of
``benchmarks/RESULTS.md`` (its headings one level down, under "Diagnostic history") and adds the
pictures it shows to the site, so the history is never a copy that could drift.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "RESULTS.md"
PAGE = "results.md"
PICTURE_DIR = "benchmark_pictures"

_PICTURE = re.compile(r"!\[(?P<alt>[^\]]*)\]\((?P<path>[^)/:]+\.png)\)")


def history_markdown(text: str) -> str:
    """RESULTS.md's text for the results page: its title dropped, every heading one level down,
    its pictures pointed at ``benchmark_pictures/``."""
    lines = text.splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    body, in_code = [], False
    for line in lines:
        if line.startswith("```"):
            in_code = not in_code
        if not in_code and line.startswith("#"):
            line = "#" + line
        body.append(_PICTURE.sub(rf"![\g<alt>]({PICTURE_DIR}/\g<path>)", line))
    return "\n".join(body)


def pictures(text: str) -> list[str]:
    """The file names of the pictures RESULTS.md shows (beside it in benchmarks/)."""
    return sorted({match["path"] for match in _PICTURE.finditer(text)})


def on_files(files: Any, config: Any) -> Any:
    """MkDocs event: add the pictures RESULTS.md shows to the site."""
    from mkdocs.structure.files import File

    for name in pictures(RESULTS.read_text()):
        files.append(File.generated(config, f"{PICTURE_DIR}/{name}", abs_src_path=str(RESULTS.parent / name)))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """MkDocs event: append the history to the results page."""
    if page.file.src_uri != PAGE:
        return markdown
    return (markdown.rstrip() + "\n\n## Diagnostic history\n\n"
            "Everything below is `benchmarks/RESULTS.md` as it stands, section by section in the order the "
            "rounds were run: each names its command, machine and date.\n\n" + history_markdown(RESULTS.read_text()) + "\n")
