"""A checkpoint that cannot serve a run is one line naming the option and the file (a ConfigError,
status 2), before anything is trained or predicted: unreadable (empty, truncated, text), a plain
state dict, another model's weights (ckpt_path of lanelab-train, checkpoint of lanelab-eval), a
training state past max_epochs."""

from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf
from tiny_store import tiny_overrides
from train_command import run, train_command

from lanelab.config_checks import ConfigError
from lanelab.evaluation.config import load_eval_config
from lanelab.experiment import eval_cli
from lanelab.experiment.build import CONFIG_KEY
from lanelab.experiment.config import load_train_config
from lanelab.experiment.train import train


def bad_file(kind: str, trained: Path, folder: Path) -> Path:
    path = folder / f"{kind}.ckpt"
    if kind == "empty":
        path.touch()
    elif kind == "truncated":
        path.write_bytes(trained.read_bytes()[: trained.stat().st_size // 2])
    elif kind == "text":
        path.write_text("not a checkpoint\n")
    else:  # the weights alone, as torch.save(model.state_dict()) writes them
        torch.save(torch.load(trained, weights_only=False)["state_dict"], path)
    return path


@pytest.mark.parametrize("kind, message", [
    ("empty", "an empty file, not a checkpoint"),
    ("truncated", r"not a readable checkpoint \(truncated, or not written by torch.save\)"),
    ("text", r"not a readable checkpoint \(truncated, or not written by torch.save\)"),
    ("state_dict", r"a plain state dict \(\d+ tensors\), not a checkpoint of lanelab-train"),
])  # fmt: skip
def test_a_ckpt_path_that_is_no_checkpoint_is_named(kind: str, message: str, trained_checkpoint: Path,
                                                    tiny_store: Path, tmp_path: Path) -> None:  # fmt: skip
    path = bad_file(kind, trained_checkpoint, tmp_path)
    with pytest.raises(ConfigError, match=f"ckpt_path={path}: {message}"):  # old code: torch's and Lightning's tracebacks
        train(load_train_config(tiny_overrides(tiny_store, tmp_path / "run", f"ckpt_path={path}")))
    assert not (tmp_path / "run" / "checkpoints").exists()


@pytest.mark.slow
def test_lanelab_train_names_a_truncated_ckpt_path_in_one_line(trained_checkpoint: Path, tiny_store: Path,
                                                               tmp_path: Path) -> None:  # fmt: skip
    path = bad_file("truncated", trained_checkpoint, tmp_path)
    result = run(train_command(tiny_store, tmp_path / "run", f"ckpt_path={path}"))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [f"lanelab-train: bad option: ckpt_path={path}: not a readable "
                                                  "checkpoint (truncated, or not written by torch.save)"]  # fmt: skip


def test_a_checkpoint_past_max_epochs_is_named(trained_checkpoint: Path, tiny_store: Path, tmp_path: Path) -> None:
    overrides = tiny_overrides(tiny_store, tmp_path, f"ckpt_path={trained_checkpoint}", "trainer.max_epochs=1")
    with pytest.raises(ConfigError, match=rf"ckpt_path={trained_checkpoint}: the checkpoint is at epoch 2 "
                                          r"\(step 6\), past trainer.max_epochs=1; give trainer.max_epochs=2 or more"):
        train(load_train_config(overrides))  # old code: Lightning's MisconfigurationException


def another_models_weights(trained: Path, folder: Path) -> Path:
    """The trained checkpoint with Bi²Lane's model in its run config: its weights are another model's."""
    content = torch.load(trained, weights_only=False)
    bi2lane = load_train_config(["experiment=tiny", "model=bi2lane", f"paths.output_dir={folder}"])
    content[CONFIG_KEY]["model"] = OmegaConf.to_container(bi2lane.model, resolve=True)
    path = folder / "mixed.ckpt"
    torch.save(content, path)
    return path


def test_lanelab_eval_names_a_checkpoint_whose_weights_are_another_models(trained_checkpoint: Path,
                                                                          tiny_store: Path, tmp_path: Path) -> None:  # fmt: skip
    mixed = another_models_weights(trained_checkpoint, tmp_path)
    options = load_eval_config([f"checkpoint={mixed}", f"store={tiny_store}", f"out={tmp_path / 'out'}"])
    with pytest.raises(ConfigError, match=rf"checkpoint={mixed}: its weights are not those of its run config's model "
                                          r"\(Bi2Lane\): \d+ tensors \(.*\) missing; \d+ tensors \(.*\) not in the model"):
        eval_cli.run(options)  # old code: load_state_dict's traceback, after the store was read
    assert not (tmp_path / "out").exists()


def test_lanelab_train_names_a_ckpt_path_of_another_model(trained_checkpoint: Path, tiny_store: Path,
                                                          tmp_path: Path) -> None:  # fmt: skip
    overrides = tiny_overrides(tiny_store, tmp_path, "model=bi2lane", f"ckpt_path={trained_checkpoint}")
    with pytest.raises(ConfigError, match=rf"ckpt_path={trained_checkpoint}: its weights are not those of this run's "
                                          r"model \(Bi2Lane\)"):
        train(load_train_config(overrides))
