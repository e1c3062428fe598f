"""Write a file so that its final name only ever holds a complete file.

Used by every writer in lanelab (drive logs, clip files, manifests, pictures): a crash
or Ctrl-C leaves the previous state, never a half-written file under the final name. The
temporary is named for its process, so that two processes writing the same file never write
into one temporary (the last rename wins, whole); a tool that holds its folder's lock may
delete the temporaries (``.*.partial``) a killed run left there.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator


PARTIAL_GLOB = ".*.partial"  # every temporary of partial_path


def partial_path(path: Path) -> Path:
    """The hidden temporary beside ``path`` that this process's write in progress goes to."""
    return path.with_name(f".{path.name}.{os.getpid()}.partial")


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path to write; on success fsync it and rename it to ``path``.

    On any exception (KeyboardInterrupt included) the temporary is removed and the
    exception propagates; a file already at ``path`` is left untouched.
    """
    final = Path(path)
    tmp = partial_path(final)
    try:
        yield tmp
        with open(tmp, "rb+") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, final)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
