"""lanelab-sweep-report lays a paper's ablation sweep out as the paper's table: rows in the paper's
order, ours (mean ± std over seeds) beside the paper's numbers; and the sweeps hold the rest of the
setting as the paper ran it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from lanelab.experiment.config import load_train_config
from lanelab.experiment.paper_tables import PAPER_TABLES
from lanelab.experiment.sweep_report import REPORT_MD, write_report


def job(multirun: Path, number: int, overrides: list[str], metrics: dict[str, float]) -> None:
    folder = multirun / str(number)
    (folder / ".hydra").mkdir(parents=True)
    (folder / ".hydra" / "overrides.yaml").write_text("".join(f"- {o}\n" for o in overrides))
    (folder / "metrics.json").write_text(json.dumps(metrics))


def test_an_attention_sweep_with_seeds_as_the_papers_table_2(tmp_path: Path) -> None:
    # Run out of the paper's order, two seeds for two rows, one row not run.
    runs = [("sla_pna_tca", 1, 0.50), ("global", 1, 0.40), ("sla_pna_tca", 2, 0.56), ("global", 2, 0.44), ("sla", 1, 0.42)]
    for number, (variant, seed, f1) in enumerate(runs):
        job(tmp_path, number, ["sweep=attention", f"+sweep/attention={variant}", f"seed={seed}"],
            {"val/f1": f1, "val/x_error_close": 0.3})  # fmt: skip
    write_report(tmp_path, tmp_path)
    report = (tmp_path / REPORT_MD).read_text()
    section = report[report.index("## As in the paper: SparseLaneSTP Table 2"):]
    lines = [line for line in section.splitlines() if line.startswith("| ")][1:]
    assert [line.split(" | ")[0] for line in lines] == ["| Global", "| SLA", "| PNA", "| SLA + PNA", "| SLA + PNA + TCA"]
    assert lines[0] == "| Global | global | 2 | 42.0 ± 2.8 | 62.9 |"
    assert lines[1] == "| SLA | sla | 1 | 42.0 | 62.8 |"
    assert lines[2] == "| PNA | pna | 0 | – | 63.5 |"
    assert lines[4] == "| SLA + PNA + TCA | sla_pna_tca | 2 | 53.0 ± 4.2 | 65.0 |"
    assert "Ours: validation metrics" in section


def test_a_bi2lane_sweep_shows_the_papers_errors_too(tmp_path: Path) -> None:
    for number, value in enumerate(["true", "false"]):
        job(tmp_path, number, ["sweep=bi2lane_alignment", f"model.net.temporal_alignment={value}"],
            {"test/f1": 0.5, "test/x_error_close": 0.25, "test/x_error_far": 0.5,
             "test/z_error_close": 0.1, "test/z_error_far": 0.2})  # fmt: skip
    write_report(tmp_path, tmp_path)
    section = (tmp_path / REPORT_MD).read_text().split("## As in the paper: ")[1]
    rows = [line for line in section.splitlines() if line.startswith("| ")]
    assert rows[0].startswith("| row | model.net.temporal_alignment | jobs | F1 (%) ours | F1 (%) paper | x err. close (m) ours")
    assert rows[1] == "| Bi²Lane (w/o) | false | 1 | 50.0 | 59.6 | 0.250 | 0.258 | 0.500 | 0.274 | 0.100 | 0.098 | 0.200 | 0.126 |"
    assert rows[2].startswith("| Bi²Lane | true | 1 | 50.0 | 60.0 |")


def test_a_sweep_no_paper_ran_has_no_paper_section(tmp_path: Path) -> None:
    for number, value in enumerate([10, 20]):
        job(tmp_path, number, ["sweep=control_points", f"model.net.num_points={value}"], {"val/f1": 0.5})
    write_report(tmp_path, tmp_path)
    assert "As in the paper" not in (tmp_path / REPORT_MD).read_text()


@pytest.mark.parametrize("name", sorted(PAPER_TABLES))
def test_each_paper_row_is_a_value_its_sweep_runs(name: str, tmp_path: Path) -> None:
    """Every row of a paper table composes as a job of its sweep (the same key and value)."""
    table = PAPER_TABLES[name]
    for row in table.rows:
        cfg = load_train_config([f"sweep={name}", "experiment=tiny", f"paths.output_dir={tmp_path}", f"{table.key}={row.value}"])
        if not table.key.startswith("+"):  # a key of the config (else a group of variant files)
            assert OmegaConf.select(cfg, table.key) == yaml.safe_load(row.value)
        if not name.startswith("bi2lane"):  # SparseLaneSTP's ablations: the lighter model of §5.3
            assert cfg.model.net.num_layers == 2


@pytest.mark.parametrize("variant", ["global", "sla", "pna", "sla_pna", "sla_pna_tca"])
def test_table_2_runs_without_regularisation_and_with_memory_only_for_tca(variant: str, tmp_path: Path) -> None:
    cfg = load_train_config(["sweep=attention", f"+sweep/attention={variant}", "experiment=openlane_ablation",
                             f"paths.output_dir={tmp_path}"])  # fmt: skip
    weights = cfg.model.criterion.detection.weights
    assert (weights.parallel, weights.surface, weights.curvature, weights.temporal) == (0.0, 0.0, 0.0, 0.0)
    assert cfg.model.net.num_layers == 2
    assert cfg.model.net.num_memory_frames == (3 if cfg.model.net.use_tca else 0)


def test_table_1_adds_one_contribution_per_row(tmp_path: Path) -> None:
    rows = []
    for variant in ("discrete", "continuous", "sta", "regularisation"):
        cfg = load_train_config(["sweep=contributions", f"+sweep/contributions={variant}", "experiment=openlane_ablation",
                                 f"paths.output_dir={tmp_path}"])  # fmt: skip
        net, weights = cfg.model.net, cfg.model.criterion.detection.weights
        rows.append((net.representation, net.attention, net.use_tca, net.num_memory_frames, weights.temporal))
    assert rows == [("discrete", "global", False, 0, 0.0), ("catmull_rom", "global", False, 0, 0.0),
                    ("catmull_rom", "auto", True, 3, 0.0), ("catmull_rom", "auto", True, 3, 0.1)]
