"""Clips without ego motion given to a temporal model: refused, or run single-frame.

A store lists the clips whose frames have no pose (identity ``T_world_lane``) under its manifest's
``clips_without_pose`` (:data:`lanelab.store.WITHOUT_POSE`: ``lanelab-once`` without ``poses=``,
OpenLane before v1.2). A temporal model relates frames through their poses, so on such a clip it
would take the ego as standing still. A run is temporal when it reads several frames per sample
(``data.num_frames`` > 1) or streams (a ``StreamSampler`` carries the model's memory from frame to
frame). The run config's ``without_ego_motion`` decides:

- ``refuse``: a ConfigError naming the store, the clips and both ways out;
- ``single_frame``: ``data.num_frames=1`` and the window sampler (every sample resets the
  memory), so each frame is detected alone; the change is written into the run config, and so into
  its checkpoints.
"""

from __future__ import annotations

from importlib.resources import files

from omegaconf import DictConfig, OmegaConf, open_dict

from lanelab.config_checks import ConfigError
from lanelab.store import ManifestError, clips_without_pose, read_manifest

STREAM_SAMPLER = "lanelab.data.samplers.StreamSampler"


def is_temporal(cfg: DictConfig) -> bool:
    """Whether the run relates frames: several frames per sample, or a streaming sampler."""
    samplers = (OmegaConf.select(cfg, "sampler.train._target_"), OmegaConf.select(cfg, "sampler.eval._target_"))
    return OmegaConf.select(cfg, "data.num_frames", default=1) > 1 or STREAM_SAMPLER in samplers


def apply_ego_motion_policy(cfg: DictConfig, stages: list[str]) -> None:
    """Refuse, or make single-frame (in place), a temporal run whose stages read clips without ego
    motion; nothing for other runs. A store that cannot be read is left to the datamodule's check."""
    if not is_temporal(cfg):
        return
    try:
        manifest = read_manifest(cfg.data.store)
    except ManifestError:
        return
    splits = {OmegaConf.select(cfg, f"data.splits.{stage}") for stage in stages}
    without = sorted(clip.clip_id for clip in manifest.clips
                     if clip.split in splits and clip.clip_id in clips_without_pose(manifest))  # fmt: skip
    if not without:
        return
    named = ", ".join(without[:3]) + (f" and {len(without) - 3} more" if len(without) > 3 else "")
    if cfg.without_ego_motion == "refuse":
        raise ConfigError(f"data.store={cfg.data.store}: {len(without)} clips have no ego motion ({named}; listed as "
                          "clips_without_pose) and this model relates frames through their poses: give the store "
                          "ego poses (lanelab-once poses=...), or run it single-frame (without_ego_motion=single_frame)")
    window = OmegaConf.load(str(files("lanelab.conf") / "sampler" / "window.yaml"))
    with open_dict(cfg):
        cfg.data.num_frames = 1
        if STREAM_SAMPLER in (cfg.sampler.train._target_, cfg.sampler.eval._target_):
            cfg.sampler.train, cfg.sampler.eval = window.train, window.eval
    print(f"note: {len(without)} clips of data.store={cfg.data.store} have no ego motion ({named}): "
          "running single-frame (data.num_frames=1, window sampler)")
