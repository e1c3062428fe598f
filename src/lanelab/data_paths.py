"""Paths that data names, kept inside the folder they belong in.

A log's ``openlane.file_path`` tag, a store's frame, a prediction file or a test list line
name where a file goes, relative to an output folder. They are data, not options: one that is
absolute or climbs out of its folder (``..``, or a link below the folder pointing elsewhere)
must never decide where a file is written. :func:`path_problem` says what is wrong with such
a path (the ingestors check tags with it), :func:`path_inside` joins one under its folder or
raises :class:`UnsafePathError`.
"""

from __future__ import annotations

import os
from pathlib import Path, PurePosixPath, PureWindowsPath


class UnsafePathError(ValueError):
    """A path named by data that would lead outside the folder it is to be written in."""


def path_problem(relative: str) -> str:
    """What makes ``relative`` unfit as a path below a folder: "" if nothing."""
    if not relative:
        return "is empty"
    if "\0" in relative:
        return "holds a NUL character"
    if PurePosixPath(relative).is_absolute() or PureWindowsPath(relative).is_absolute():
        return "is absolute"
    if ".." in PurePosixPath(relative.replace("\\", "/")).parts:
        return "climbs out of its folder ('..')"
    return ""


def path_inside(root: str | os.PathLike[str], relative: str, what: str | None = None) -> Path:
    """``root / relative``, where ``relative`` comes from data; ``what`` names it in the
    message (default: the path itself, quoted).

    Raises UnsafePathError when ``relative`` is absolute, holds ``..``, or resolves (links
    followed) outside ``root``.
    """
    problem = path_problem(relative)
    path = Path(root) / relative
    # A link below root may still point elsewhere: compare where both really are.
    if not problem and not Path(os.path.realpath(path)).is_relative_to(os.path.realpath(root)):
        problem = "resolves outside its folder through a link"
    if problem:
        raise UnsafePathError(f"{what or repr(relative)} {problem}: refused (files are written only inside {root})")
    return path
