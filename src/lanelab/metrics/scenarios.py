"""Per-scenario tables: the OpenLane metric over subsets of frames.

A scenario is a named set of frame ids, in a column group of the table. Two sources:

- lists: OpenLane's six test cases (``up_down``, ``curve``, ``extreme_weather``, ``night``,
  ``intersection``, ``merge_split``), whose official lists are text files of frame paths.
  :func:`list_scenarios` takes them as a mapping name -> frame ids; read a list file with
  :func:`lanelab.openlane.lists.read_test_list` to get the ids that
  :func:`lanelab.metrics.openlane.evaluate_frames` uses, or a folder of them with
  :func:`lanelab.openlane.lists.read_scenario_lists` and pass it to :func:`scenarios_of`.
- tags: the clip store's per-frame ``tags`` (environment, daytime, weather, curvature,
  slope, merge_split, occlusion... free strings). :func:`tag_scenarios` makes one scenario
  per value of each tag key, as SparseLaneSTP's Table 7 (Environment, Daytime / Weather,
  Curvature) and Bi²Lane's Table II do. Clip frames are best identified as
  ``"<clip_id>/<timestamp_ns>"``; any string works if results and tags use the same one.

:func:`scenario_rows` scores each scenario with :func:`~lanelab.metrics.openlane.summarize`
(counts summed over its frames) and :func:`markdown_table` prints the rows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Mapping, Sequence

from lanelab.metrics.openlane import RATE_KEYS, FrameResult, summarize
from lanelab.openlane.lists import OPENLANE_SCENARIOS, frame_key

# Tag key -> column group of SparseLaneSTP's Table 7 (daytime and weather share a group).
TABLE7_GROUPS = {
    "environment": "Environment",
    "daytime": "Daytime / Weather",
    "weather": "Daytime / Weather",
    "curvature": "Curvature",
}
# Tag key -> column group of the tags a store made from OpenLane gives its frames: the test
# cases of their scenario lists (``curve: Curve``, SparseLaneSTP's Table 4), then scene.json's
# (Table 7).
OPENLANE_TAG_GROUPS = {**{case: "OpenLane" for case in OPENLANE_SCENARIOS}, **TABLE7_GROUPS}
# Table 7's groups and the synthetic drives' own tags (occlusion by traffic, slopes, merges).
SCENARIO_GROUPS = {**TABLE7_GROUPS, "occlusion": "Occlusion", "slope": "Slope", "merge_split": "Merge / split"}


@dataclass(frozen=True)
class Scenario:
    """A named set of frame ids in a column group of a scenario table."""

    group: str
    name: str
    frames: frozenset[str]


def list_scenarios(
    lists: Mapping[str, Iterable[str]],
    group: str = "OpenLane",
    labels: Mapping[str, str] = OPENLANE_SCENARIOS,
) -> list[Scenario]:
    """One scenario per list (name -> frame ids), labelled by `labels` (else by its name),
    in the order of `lists`."""
    return [Scenario(group, labels.get(name, name), frozenset(ids)) for name, ids in lists.items()]


def scenarios_of(lists: Mapping[str, frozenset[str]], frame_ids: Iterable[str]) -> list[Scenario]:
    """The scenarios of scenario lists (case name -> frame keys, as
    :func:`~lanelab.openlane.lists.read_scenario_lists` reads them) over frame_ids (test-list
    ids, as evaluate_frames names frames): each holds the ids whose frame_key its list names;
    labelled as in the papers."""
    frame_ids = list(frame_ids)
    return list_scenarios({
        name: [frame for frame in frame_ids if frame_key(frame) in keys] for name, keys in lists.items()
    })


def tag_scenarios(
    frame_tags: Mapping[str, Mapping[str, str]],
    groups: Mapping[str, str] = TABLE7_GROUPS,
) -> list[Scenario]:
    """Scenarios from per-frame tags (frame id -> {tag key: value}).

    For each tag key of `groups`, in its order, one scenario per value seen (sorted), in the
    column group groups[key] and named by the value. Frames without the key are in none of
    its scenarios; keys not in `groups` are ignored.
    """
    scenarios = []
    for key, group in groups.items():
        by_value: dict[str, set[str]] = {}
        for frame, tags in frame_tags.items():
            if key in tags:
                by_value.setdefault(tags[key], set()).add(frame)
        for value in sorted(by_value):
            scenarios.append(Scenario(group, value, frozenset(by_value[value])))
    return scenarios


def scenario_rows(
    results: Mapping[str, FrameResult], scenarios: Sequence[Scenario]
) -> list[dict[str, str | int | float]]:
    """One row per scenario: group, scenario and the :func:`summarize` keys over those of
    its frames that have a result (num_frames says how many; the others are not scored)."""
    rows = []
    for scenario in scenarios:
        frames = [results[frame] for frame in sorted(scenario.frames) if frame in results]
        rows.append({"group": scenario.group, "scenario": scenario.name, **summarize(frames)})
    return rows


def mean_f1(rows: Sequence[Mapping[str, str | int | float]]) -> float:
    """The unweighted mean of the rows' F1, Bi²Lane's "Mean" over scenarios."""
    return sum(float(row["f1"]) for row in rows) / len(rows) if rows else float("nan")


_TEXT_COLUMNS = ("predictions", "group", "scenario")  # left-aligned
# Fractions shown in percent, as the papers print them.
_PERCENT = {*RATE_KEYS, "vis_iou"}
_LABELS = {
    "predictions": "Predictions",  # a row's name where rows are several predictions (a model, the blind prior)
    "group": "Group",
    "scenario": "Scenario",
    "num_frames": "Frames",
    "f1": "F1 (%)",
    "recall": "R (%)",
    "precision": "P (%)",
    "category_accuracy": "Cat. acc. (%)",
    "vis_iou": "Vis-IoU (%)",
}


def markdown_table(
    rows: Sequence[Mapping[str, object]],
    columns: Sequence[str] = ("group", "scenario", "num_frames", "f1", "precision", "recall"),
) -> str:
    """A Markdown table of the rows' `columns`: fractions in percent with one decimal,
    errors (x_error_close, ...) in metres with three, NaN or a missing value as "–"."""
    align = ["---" if column in _TEXT_COLUMNS else "---:" for column in columns]
    lines = ["| " + " | ".join(_label(column) for column in columns) + " |",
             "|" + "|".join(align) + "|"]
    for row in rows:
        cells = [_cell(column, row.get(column, float("nan"))) for column in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _label(column: str) -> str:
    if column in _LABELS:
        return _LABELS[column]
    if column.startswith(("x_error_", "z_error_")):  # x_error_100_150 -> x err. 100-150 (m)
        return f"{column[0]} err. {column[8:].replace('_', '-')} (m)"
    return column


def _cell(column: str, value: object) -> str:
    if isinstance(value, float):
        if value != value:  # NaN: no pair had a value
            return "–"
        return f"{100 * value:.1f}" if column in _PERCENT else f"{value:.3f}"
    return str(value)
