"""What the project ships besides its code: the Apache-2.0 LICENSE its metadata names, a
CHANGELOG, ``py.typed`` in every package, and a version that follows the git tags
(setuptools-scm; a tree without git metadata builds as the fallback version)."""

from __future__ import annotations

import email
import importlib.metadata
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import lanelab

ROOT = Path(__file__).resolve().parents[1]
FALLBACK_VERSION = "0.1.0.dev0"  # pyproject.toml [tool.setuptools_scm] fallback_version
GIT = ["git", "-c", "user.name=test", "-c", "user.email=test@example.com", "-c", "commit.gpgsign=false",
       "-c", "tag.gpgsign=false", "-c", "init.defaultBranch=main"]


def copy_of_the_sources(to: Path) -> Path:
    """The working tree's files as git sees them (tracked, and new ones it does not ignore), without .git."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            check=True, capture_output=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        if (ROOT / name).is_file():  # a file deleted but not yet committed is listed too
            (to / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, to / name)
    return to


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> zipfile.ZipFile:
    """The wheel setuptools builds from a copy of the sources without git metadata."""
    sources = copy_of_the_sources(tmp_path_factory.mktemp("sources"))
    out = tmp_path_factory.mktemp("wheel")
    build = "import sys; from setuptools import build_meta; build_meta.build_wheel(sys.argv[1])"
    subprocess.run([sys.executable, "-c", build, str(out)], cwd=sources, check=True, capture_output=True)
    (path,) = out.glob("*.whl")
    with zipfile.ZipFile(path) as built:
        yield built


def wheel_metadata(wheel: zipfile.ZipFile) -> email.message.Message:
    (name,) = [n for n in wheel.namelist() if n.endswith(".dist-info/METADATA")]
    return email.message_from_bytes(wheel.read(name))


def test_the_license_is_apache_2_and_ships_in_the_wheel(wheel):
    text = (ROOT / "LICENSE").read_text()
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    assert lines[:3] == ["Apache License", "Version 2.0, January 2004", "http://www.apache.org/licenses/"]
    for section in ("1. Definitions.", "2. Grant of Copyright License.", "3. Grant of Patent License.",
                    "4. Redistribution.", "5. Submission of Contributions.", "6. Trademarks.",
                    "7. Disclaimer of Warranty.", "8. Limitation of Liability.",
                    "9. Accepting Warranty or Additional Liability.", "END OF TERMS AND CONDITIONS"):
        assert section in text, f"LICENSE: no {section!r}"
    assert wheel_metadata(wheel)["License-Expression"] == "Apache-2.0"
    (shipped,) = [n for n in wheel.namelist() if n.endswith(".dist-info/licenses/LICENSE")]
    assert wheel.read(shipped).decode() == text


def test_every_package_in_the_wheel_is_typed(wheel):
    tops = {name.split("/")[0] for name in wheel.namelist() if "/" in name and ".dist-info/" not in name}
    assert tops == {"lanelab", "data_ingest", "log_predict"}
    for top in sorted(tops):
        assert f"{top}/py.typed" in wheel.namelist(), f"the wheel's {top} has no py.typed"
    assert "lanelab/conf/train.yaml" in wheel.namelist()  # package-data beside py.typed still ships


def test_sources_without_git_build_as_the_fallback_version(wheel):
    assert wheel_metadata(wheel)["Version"] == FALLBACK_VERSION


def test_the_version_follows_the_git_tags(tmp_path):
    repo = copy_of_the_sources(tmp_path)

    def version() -> str:
        return subprocess.run([sys.executable, "-m", "setuptools_scm"], cwd=repo, check=True, capture_output=True,
                              text=True).stdout.strip().splitlines()[-1]

    def git(*args: str) -> str:
        return subprocess.run(GIT + list(args), cwd=repo, check=True, capture_output=True, text=True).stdout.strip()

    def dev_of_head(release: str, distance: int) -> bool:
        """Is the version ``<release>.dev<distance>+g<abbreviated HEAD>``?"""
        match = re.fullmatch(rf"{re.escape(release)}\.dev{distance}\+g([0-9a-f]{{7,}})", version())
        return match is not None and git("rev-parse", "HEAD").startswith(match[1])

    git("init", "-q")
    git("add", "-A")
    git("commit", "-q", "-m", "first")
    assert dev_of_head("0.1.0", 1), version()  # no tag yet
    git("tag", "v1.2.3")
    assert version() == "1.2.3"
    git("commit", "-q", "--allow-empty", "-m", "second")
    git("commit", "-q", "--allow-empty", "-m", "third")
    assert dev_of_head("1.2.4", 2), version()


def test_lanelab_version_is_the_installed_distributions():
    assert lanelab.__version__ == importlib.metadata.version("lanelab")


def test_the_changelog_keeps_a_changelog():
    text = (ROOT / "CHANGELOG.md").read_text()
    assert text.startswith("# Changelog\n") and "https://keepachangelog.com" in text
    versions = re.findall(r"^## \[(.+?)\]", text, re.MULTILINE)
    assert versions and versions[0] == "Unreleased", f"CHANGELOG.md: the first section is {versions[:1]}"
    kinds = re.findall(r"^### (.+)$", text, re.MULTILINE)
    assert kinds and set(kinds) <= {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}, kinds
