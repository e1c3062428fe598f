"""Where does a detector's F1 go? Fix one kind of error at a time with the ground truth.

    python benchmarks/error_budget.py EVAL_DIR [--max-distance 2.0]

EVAL_DIR is what ``lanelab-eval`` and ``bench_learning.py`` write for a checkpoint (``heldout/``:
``ground_truth/``, ``predictions/``, ``test_list.txt``). Prints the F1 of the predictions as they
are and with each fix of ``lanelab.metrics.error_budget`` (near positions, far positions, extents,
missed lanes, false lanes), scored with the project's OpenLane metric.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from lanelab.lightning.openlane_writer import GROUND_TRUTH, PREDICTIONS, TEST_LIST
from lanelab.metrics.error_budget import budget_counts, budget_table, error_budget_of_files


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("eval_dir", type=Path)
    parser.add_argument(
        "--max-distance", type=float, default=2.0, help="metres: the loosest association of a prediction with a lane"
    )
    args = parser.parse_args()
    start = time.perf_counter()
    d = args.eval_dir
    budget = error_budget_of_files(d / GROUND_TRUTH, d / PREDICTIONS, d / TEST_LIST, max_distance=args.max_distance)
    print(budget_table(budget))
    print(budget_counts(budget))
    print(f"{budget['as predicted']['num_frames']} frames, {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
