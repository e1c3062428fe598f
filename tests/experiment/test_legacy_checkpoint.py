"""Checkpoints written before LaneDetectionModule still load and score as they did.

data/legacy_sparselanestp.ckpt was written by lanelab-train at commit fe47476 (the tiny
experiment, a model shrunk further, two steps on tiny_store.build_store's store), stripped to
its state dict and run config. That config names ``lanelab.lightning.SparseLaneSTPModule``
with the old keys (criterion, mask_criterion, lr, warmup_steps, num_pictures, ...) and has
``data.control_points`` and eval samplers without ``flip``. OLD_SCORES is what ``lanelab-eval
checkpoint=... store=... split=test`` reported for it at that commit, except the far x / z
errors: since the OpenLane round trip (issue 16) the evaluation's ground truth is the store's
labels as stored, no longer their resampling on data.y_grid, which moved them by 0.3 mm and
3.5 µm (were 1.0551151755269494 and 0.0011331096395704265); every count and rate is as it was.

data/<model>_7337d6f.ckpt were written by lanelab-train at commit 7337d6f, the last before the
models were laid out by model (issue 41): the tiny experiment with ``model=<model>``, shrunk
further (backbone_width=2, embed_dim=8, ...: see their run configs), one epoch of two steps on
tiny_store.build_store's store, stripped to their state dict and run config, which names the
``_target_`` classes of then (``lanelab.models.SparseLaneSTP``, ``lanelab.models.losses.*``, ...), which
:data:`lanelab.experiment.build.MOVED_TARGETS` maps to today's.
Beside each: what ``lanelab-eval`` scored for it then on the test split (``_scores.json``) and
the outputs of its ``step`` on the first three frames of the first test clip (``_steps.pt``),
rebuilt as lanelab-predict rebuilds it (:func:`lanelab.deploy.trained.load_trained`).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from hydra.utils import instantiate
from omegaconf import OmegaConf

from lanelab.deploy.trained import load_trained
from lanelab.experiment.build import CONFIG_KEY, MOVED_TARGETS, read_checkpoint
from lanelab.experiment.config import load_train_config
from lanelab.experiment.evaluate import evaluate_checkpoint
from lanelab.experiment.targets import check_targets
from lanelab.lightning import LaneDetectionModule
from lanelab.models.sparselanestp import SparseLaneSTPCriterion
from lanelab.store import ClipStore

DATA = Path(__file__).parent / "data"
LEGACY = DATA / "legacy_sparselanestp.ckpt"
OLD_SCORES = {
    "f1": 0.33333333333333337, "recall": 0.2777777777777778, "precision": 0.4166666666666667,
    "category_accuracy": 0.0, "x_error_close": 0.8544904265413719, "x_error_far": 1.055409502601451,
    "z_error_close": 0.0013740737127443184, "z_error_far": 0.0011366280683371434, "num_frames": 6,
    "gt_lanes": 18, "pred_lanes": 12, "matched": 6, "recall_tp": 5, "precision_tp": 5, "category_correct": 0,
}  # fmt: skip


def test_an_old_model_config_builds_the_module_that_loads_its_weights():
    content = read_checkpoint(LEGACY)
    model = OmegaConf.create(content[CONFIG_KEY]["model"])
    assert model._target_ == "lanelab.lightning.SparseLaneSTPModule" and "mask_criterion" in model
    assert model.criterion._target_ == "lanelab.models.sparselanestp.SparseLaneSTPLoss"  # was lanelab.models.SparseLaneSTPLoss
    check_targets(model)
    module = instantiate(model)
    assert isinstance(module, LaneDetectionModule) and isinstance(module.criterion, SparseLaneSTPCriterion)
    assert module.criterion.instance_mask.dice_weight == model.mask_criterion.dice_weight
    optimizer = module.optimizer_factory(module.net)
    assert optimizer.defaults["lr"] == model.lr and optimizer.defaults["weight_decay"] == model.weight_decay
    assert module.pictures["num_frames"] == model.num_pictures and module.nms_distance == model.nms_distance
    # The same parameters and buffers under the same names: a strict load leaves nothing out.
    module.load_state_dict(content["state_dict"], strict=True)
    loaded = module.state_dict()
    assert all(torch.equal(loaded[key], value) for key, value in content["state_dict"].items())


def test_an_old_checkpoint_scores_as_it_did(tiny_store: Path, tmp_path: Path) -> None:
    options = {"split": "test", "accelerator": "cpu", "num_pictures": 1, "picture_height": 96, "blind_prior": False,
               "prior_store": None}  # fmt: skip
    report = evaluate_checkpoint(LEGACY, tiny_store, tmp_path, **options)
    assert report["overall"] == pytest.approx(OLD_SCORES, rel=1e-6, abs=1e-6)  # a micrometre: float rounding of reordered sums


def test_a_bi2lane_checkpoint_from_before_offset_hidden_dim_builds_its_offset_heads(tmp_path):
    """Bi²Lane's offset heads (eq. 2) had the class / x / z heads' hidden width until
    model.net.offset_hidden_dim was split off; a run config without the key builds them so."""
    cfg = load_train_config(["experiment=tiny", "model=bi2lane", "model.net.head_hidden_dim=48",
                             "model.net.offset_hidden_dim=48", f"paths.output_dir={tmp_path}"])  # fmt: skip
    old = OmegaConf.to_container(cfg, resolve=True)
    del old["model"]["net"]["offset_hidden_dim"]
    weights = instantiate(cfg.model.net).state_dict()
    torch.save({CONFIG_KEY: old, "state_dict": weights}, tmp_path / "old.ckpt")
    net = read_checkpoint(tmp_path / "old.ckpt")[CONFIG_KEY]["model"]["net"]
    assert net["offset_hidden_dim"] == 48
    instantiate(OmegaConf.create(net)).load_state_dict(weights)  # strict: every shape as trained


@pytest.mark.parametrize("model", ["sparselanestp", "bi2lane"])
def test_a_checkpoint_of_the_flat_models_folder_scores_and_steps_as_it_did(model, tiny_store, tmp_path):
    checkpoint = DATA / f"{model}_7337d6f.ckpt"
    then = torch.load(checkpoint, map_location="cpu", weights_only=False)[CONFIG_KEY]["model"]
    assert then["net"]["_target_"] in MOVED_TARGETS and then["criterion"]["_target_"] in MOVED_TARGETS  # the old names
    options = {"split": "test", "accelerator": "cpu", "num_pictures": 0, "picture_height": 96, "blind_prior": False,
               "prior_store": None}  # fmt: skip
    report = evaluate_checkpoint(checkpoint, tiny_store, tmp_path, **options)
    scores = json.loads((DATA / f"{model}_7337d6f_scores.json").read_text())
    unscored = {key for key, value in scores.items() if value is None}  # no lane matched in that range
    assert {key for key, value in report["overall"].items() if value is None} == unscored
    assert {key: value for key, value in report["overall"].items() if key not in unscored} == pytest.approx(
        {key: value for key, value in scores.items() if key not in unscored}, rel=1e-6, abs=1e-6)

    trained = load_trained(checkpoint)
    store = ClipStore(tiny_store)
    records = store.read_frames(store.clips_in("test")[0].clip_id, 0, 3)
    with torch.no_grad():
        steps = [trained.net.step({**trained.model_input(record), "reset": torch.tensor([i == 0])})
                 for i, record in enumerate(records)]  # fmt: skip
    for outputs, before in zip(steps, torch.load(DATA / f"{model}_7337d6f_steps.pt"), strict=True):
        for key, value in before.items():
            torch.testing.assert_close(outputs[key], value)
