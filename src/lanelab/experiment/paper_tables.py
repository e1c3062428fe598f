"""The papers' ablation tables, as ``lanelab-sweep-report`` lays out a sweep of ``conf/sweep/``:
the rows in the paper's order and the paper's numbers beside ours.

A :class:`PaperTable` belongs to one sweep (``sweep=<name>`` among the jobs' overrides) and names
the override the sweep varies; each row is one of its values, the paper's label for it and the
paper's numbers (F1 in percent, errors in metres) under the metric names of
:mod:`lanelab.metrics.openlane`. SparseLaneSTP reports F1 alone (Tables 1-3, OpenLane, L = 2);
Bi²Lane F1 and the x / z errors (Tables III-VII, OpenLane validation, ResNet-18).
"""

from __future__ import annotations

from dataclasses import dataclass

ERRORS = ("x_error_close", "x_error_far", "z_error_close", "z_error_far")


@dataclass(frozen=True)
class PaperRow:
    value: str  # the swept override's value that runs this row
    label: str  # the paper's name of the row
    numbers: dict[str, float]  # metric -> the paper's number (f1 in percent)


@dataclass(frozen=True)
class PaperTable:
    title: str
    key: str  # the override the sweep varies, as typed (a group's with its +)
    rows: tuple[PaperRow, ...]

    @property
    def columns(self) -> tuple[str, ...]:
        """The metrics the paper reports, in the order of ``("f1", *ERRORS)``."""
        reported = {name for row in self.rows for name in row.numbers}
        return tuple(name for name in ("f1", *ERRORS) if name in reported)


def _rows(values: str, columns: tuple[str, ...], rows: list[tuple]) -> tuple[PaperRow, ...]:
    """PaperRows from the swept values (comma-separated) and, per value, (label, *numbers in columns)."""
    return tuple(PaperRow(v, label, dict(zip(columns, numbers, strict=True)))
                 for v, (label, *numbers) in zip(values.split(","), rows, strict=True))  # fmt: skip


_BI2LANE_COLUMNS = ("f1", *ERRORS)
_BI2LANE_FULL = ("Bi²Lane", 60.0, 0.251, 0.251, 0.097, 0.123)  # every Bi²Lane table's last row

PAPER_TABLES: dict[str, PaperTable] = {
    "contributions": PaperTable(
        "SparseLaneSTP Table 1: the contributions", "+sweep/contributions",
        _rows("discrete,continuous,sta,regularisation", ("f1",),
              [("Discrete (baseline)", 61.8), ("Continuous Rep.", 62.9), ("+ STA", 65.0), ("+ Regularization", 65.3)])),
    "attention": PaperTable(
        "SparseLaneSTP Table 2: spatio-temporal attention", "+sweep/attention",
        _rows("global,sla,pna,sla_pna,sla_pna_tca", ("f1",),
              [("Global", 62.9), ("SLA", 62.8), ("PNA", 63.5), ("SLA + PNA", 63.8), ("SLA + PNA + TCA", 65.0)])),
    "memory_length": PaperTable(
        "SparseLaneSTP Table 3: frames in the memory (T)", "model.net.num_memory_frames",
        _rows("0,1,2,3,4,5", ("f1",),
              [(f"T = {t}", f1) for t, f1 in enumerate([63.8, 64.1, 64.6, 65.0, 64.5, 63.9])])),
    "bi2lane_modules": PaperTable(
        "Bi²Lane Table III: the modules", "+sweep/bi2lane_modules",
        _rows("baseline,bdtr,bi2lane", _BI2LANE_COLUMNS, [("Baseline", 55.7, 0.267, 0.292, 0.098, 0.126),
                                                ("+BDTR", 59.8, 0.251, 0.274, 0.097, 0.124),
                                                ("+BLFA (Bi²Lane)", *_BI2LANE_FULL[1:])])),
    "bi2lane_feature_level": PaperTable(
        "Bi²Lane Table IV: the level of feature aggregation", "model.net.aggregation",
        _rows("point,line,bilevel", _BI2LANE_COLUMNS, [("Point-level", 59.8, 0.251, 0.274, 0.097, 0.124),
                                             ("Line-level", 59.7, 0.251, 0.270, 0.098, 0.125),
                                             ("Bi-Level (Bi²Lane)", *_BI2LANE_FULL[1:])])),
    "bi2lane_direction": PaperTable(
        "Bi²Lane Table V: the direction of temporal refinement", "model.net.direction",
        _rows("forward,reverse,bidirectional", _BI2LANE_COLUMNS, [("Forward", 58.8, 0.242, 0.284, 0.098, 0.128),
                                                        ("Reverse", 59.6, 0.261, 0.281, 0.102, 0.129),
                                                        ("Bi-Directional (Bi²Lane)", *_BI2LANE_FULL[1:])])),
    "bi2lane_history_frames": PaperTable(
        "Bi²Lane Table VI: the number of history frames", "model.net.num_history_frames",
        _rows("1,2,3,4,5", _BI2LANE_COLUMNS, [("1", 59.1, 0.256, 0.278, 0.098, 0.126), ("2", 59.2, 0.244, 0.275, 0.098, 0.126),
                                    ("3", *_BI2LANE_FULL[1:]), ("4", 59.3, 0.247, 0.275, 0.092, 0.127),
                                    ("5", 59.3, 0.256, 0.278, 0.097, 0.126)])),
    "bi2lane_alignment": PaperTable(
        "Bi²Lane Table VII: temporal alignment", "model.net.temporal_alignment",
        _rows("false,true", _BI2LANE_COLUMNS, [("Bi²Lane (w/o)", 59.6, 0.258, 0.274, 0.098, 0.126), _BI2LANE_FULL])),
}
