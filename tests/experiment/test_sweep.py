"""The sweeps of conf/sweep/ (shipped in the package, so they run from any folder): every
swept value composes; a 2-job multirun of the tiny config (basic launcher) run from a folder
outside the checkout, and its lanelab-sweep-report."""

import csv
import json
import os
import subprocess
import sys
from importlib.resources import files
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from lanelab.experiment.config import load_train_config
from lanelab.experiment.sweep_report import PLOT_PNG, REPORT_CSV, REPORT_MD, f1_figure, main

# The sweeps as the installed package holds them (a wheel's lanelab/conf/sweep/, a checkout's conf/sweep/).
SWEEPS = sorted(path.name.removesuffix(".yaml") for path in (files("lanelab.conf") / "sweep").iterdir()
                if path.name.endswith(".yaml"))  # fmt: skip


def test_the_paper_sweeps_are_shipped() -> None:
    assert {"memory_length", "tca_neighbors", "control_points", "attention"} <= set(SWEEPS)


@pytest.mark.parametrize("sweep", SWEEPS)
def test_every_swept_value_composes_and_validates(sweep: str, tmp_path: Path) -> None:
    """A swept key that does not exist, or a variant file that does not, fails here and not
    in the middle of a multirun."""
    config = yaml.safe_load((files("lanelab.conf") / "sweep" / f"{sweep}.yaml").read_text())
    params = config["hydra"]["sweeper"]["params"]
    assert params, f"conf/sweep/{sweep}.yaml sweeps nothing"
    for key, values in params.items():
        for value in str(values).split(","):
            overrides = [f"sweep={sweep}", f"paths.output_dir={tmp_path}", f"{key}={value}"]  # the sweep on the defaults
            cfg = load_train_config(overrides)
            if not key.startswith("+"):  # a key of the config (else a group of variant files)
                assert OmegaConf.select(cfg, key) == yaml.safe_load(value)


@pytest.mark.slow
def test_multirun_from_another_folder_and_report(tiny_store: Path, tmp_path: Path) -> None:
    multirun, elsewhere = tmp_path / "multirun", tmp_path / "elsewhere"
    elsewhere.mkdir()
    command = [
        sys.executable, "-m", "lanelab.experiment.train", "--multirun", "sweep=memory_length",
        "experiment=tiny", f"data.store={tiny_store}", "logger=none",
        "trainer.max_epochs=1", "trainer.limit_train_batches=2", "trainer.limit_val_batches=1",
        "model.net.num_memory_frames=0,2", f"hydra.sweep.dir={multirun}",
    ]  # fmt: skip
    # Absolute import paths, so that the folder the command runs in (not the checkout) plays no part.
    paths = [str(Path(p).resolve()) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}
    result = subprocess.run(command, check=False, capture_output=True, text=True, timeout=300, cwd=elsewhere, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    for job in ("0", "1"):  # the sweep's own settings: streaming, one frame a sample
        config = yaml.safe_load((multirun / job / ".hydra" / "config.yaml").read_text())
        assert config["data"]["num_frames"] == 1 and "Stream" in config["sampler"]["train"]["_target_"]
    assert list(elsewhere.iterdir()) == []  # nothing written where it ran

    main([str(multirun)])
    with (multirun / REPORT_CSV).open() as f:
        rows = list(csv.DictReader(f))
    assert [row["model.net.num_memory_frames"] for row in rows] == ["0", "2"]
    assert {"f1", "precision", "recall", "x_error_close", "x_error_far", "z_error_close", "z_error_far"} <= set(rows[0])
    markdown = (multirun / REPORT_MD).read_text()
    assert "| model.net.num_memory_frames | F1 (%) |" in markdown
    assert "No blind prior row: the jobs' metrics.json hold none" in markdown  # they ran no evaluation
    assert (multirun / PLOT_PNG).stat().st_size > 0


def fake_job(multirun: Path, number: int, value: str, store: str, f1: float, prior_f1: float | None) -> None:
    """A finished job folder as lanelab-train leaves it: overrides, composed config, metrics."""
    hydra = multirun / str(number) / ".hydra"
    hydra.mkdir(parents=True)
    (hydra / "overrides.yaml").write_text(yaml.safe_dump([f"model.net.num_points={value}", f"data.store={store}"]))
    config = {"data": {"store": store, "splits": {"train": "train", "val": "val", "test": "test", "predict": "test"}}}
    (hydra / "config.yaml").write_text(yaml.safe_dump(config))
    metrics = {"test/f1": f1, "test/precision": f1, "test/recall": f1, "test/x_error_close": 0.2}
    if prior_f1 is not None:
        metrics.update({"blind_prior/f1": prior_f1, "blind_prior/precision": 0.3, "blind_prior/recall": 0.5,
                        "blind_prior/x_error_close": 0.6, "blind_prior/num_frames": 300.0})  # fmt: skip
    (multirun / str(number) / "metrics.json").write_text(json.dumps(metrics))


@pytest.mark.parametrize("stores, prior_f1s, expected", [
    (["s", "s"], [0.4, 0.4], "| blind prior | 40.0 | 30.0 | 50.0 | 0.600 |"),
    (["s", "s"], [0.4, None], "| blind prior | 40.0 | 30.0 | 50.0 | 0.600 |"),
    (["s", "t"], [0.4, 0.35], "No blind prior row: the jobs train on different stores (s, t)."),
    (["s", "s"], [0.4, 0.35], "No blind prior row: the jobs scored different blind priors"),
    (["s", "s"], [None, None], "No blind prior row: the jobs' metrics.json hold none"),
])  # fmt: skip
def test_the_report_shows_the_blind_prior_of_a_shared_store(stores, prior_f1s, expected, tmp_path: Path) -> None:
    for number, (store, prior_f1) in enumerate(zip(stores, prior_f1s)):
        fake_job(tmp_path, number, str(10 * (number + 1)), store, 0.5 + 0.1 * number, prior_f1)
    main([str(tmp_path)])
    markdown = (tmp_path / REPORT_MD).read_text()
    assert expected in markdown
    rows = [line for line in markdown.splitlines() if line.startswith(("| 10 |", "| 20 |"))]
    assert [row.split(" | ")[-4] for row in rows] == ["50.0", "60.0"]  # the jobs' F1, whatever the key columns
    if expected.startswith("| blind prior"):
        assert markdown.index("| 20 | 60.0 |") < markdown.index("| blind prior")  # the reference closes the table
        assert "the mean lane layout of the train split of s, straight and flat" in markdown
        assert "scored on the test split" in markdown
    with (tmp_path / REPORT_CSV).open() as f:
        assert [row["model.net.num_points"] for row in csv.DictReader(f)] == ["10", "20"]  # the jobs alone
    assert (tmp_path / PLOT_PNG).stat().st_size > 0


def test_the_plot_names_its_axes_and_labels_every_value() -> None:
    figure = f1_figure("model.net.num_points", ["10", "20", "30"], [41.25, 55.0, float("nan")], prior_f1=30.0)
    (axes,) = figure.axes
    assert axes.get_title() == "Sweep: F1 against model.net.num_points"
    assert (axes.get_xlabel(), axes.get_ylabel()) == ("model.net.num_points", "F1 (%)")
    assert [text.get_text() for text in axes.texts] == ["41.2", "55.0"]  # a job without F1 gets no label
    assert [text.get_text() for text in axes.get_legend().get_texts()] == ["jobs", "blind prior (30.0)"]
