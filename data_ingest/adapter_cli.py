"""The command-line ends shared by the adapters of public datasets (``lanelab-openlane``,
``lanelab-once``): the summary of what became of each folder, and the exit status.

Light imports only: the commands import this before their options are checked.
"""

from __future__ import annotations

import sys
from collections import Counter
from typing import Callable, Sequence, TypeVar

from data_ingest.dataset_adapter import FAILED, FolderResult
from lanelab.json_files import LaneFileError
from lanelab.store import ManifestError

Config = TypeVar("Config")
Result = TypeVar("Result", bound=FolderResult)


def print_summary(results: Sequence[Result], folders: str, output: str) -> list[Result]:
    """Print each failed folder with its error, then the count of each status and the frames in
    ``output`` (``folders``: what the dataset calls them, plural). Returns the results that made it."""
    for result in results:
        if result.status == FAILED:
            print(f"failed: {result.name}: {result.error}")
    done = [r for r in results if r.status != FAILED]
    statuses = Counter(result.status for result in results)
    print(f"{len(results)} {folders}: " + ", ".join(f"{n} {s}" for s, n in sorted(statuses.items()))
          + f"; {sum(r.num_frames for r in done)} frames in {output}")
    return done


def run_or_exit(tool: str, run: Callable[[Config], bool], options: Config) -> None:
    """``run(options)``; exit status 1 when it returns False (a folder failed) or a dataset file or
    the store's manifest cannot be read. A ConfigError passes on, to end as a bad option
    (:func:`~lanelab.config_checks.run_hydra_tool`)."""
    try:
        ok = run(options)
    except (LaneFileError, ManifestError) as err:
        print(f"{tool}: {err}", file=sys.stderr)
        sys.exit(1)
    if not ok:
        sys.exit(1)
