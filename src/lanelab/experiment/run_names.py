"""How the loggers name a run: OmegaConf resolvers that ``conf/logger/*.yaml`` use.

- ``${run_name:DEFAULT}``: in a ``--multirun`` job, the overrides that the sweep varies
  (``model.net.num_memory_frames=3``), so that the jobs of a sweep read apart in W&B's table;
  else DEFAULT (the task name). The swept keys are those of ``hydra.sweeper.params`` (a sweep
  file) and the command line's sweeps (``key=a,b``); a job that cannot see its command line (a
  launcher in other processes) is named by all its overrides.
- ``${sweep_group:}``: in a ``--multirun`` job, its sweep's folder (``hydra.sweep.dir``), so that
  W&B groups the jobs of one sweep; else null (no group).
- ``${run_id:FOLDER}``: a stable id for the run folder, so that a run resumed in its folder
  (``ckpt_path=last``) logs on as the same W&B run.

Outside a Hydra run (``load_train_config``) there is no sweep: the defaults.
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.types import RunMode
from omegaconf import OmegaConf

RUN_ID_LENGTH = 12  # hex digits of the folder's hash: W&B ids are [a-z0-9]


def _multirun() -> bool:
    return HydraConfig.initialized() and HydraConfig.get().mode == RunMode.MULTIRUN


def swept_keys(argv: list[str], sweeper_params: dict[str, str]) -> set[str]:
    """Keys that a sweep varies: those of the sweeper's params and the sweeps among ``argv``."""
    arguments = [arg for arg in argv if "=" in arg and not arg.startswith("-")]
    try:
        overrides = OverridesParser.create().parse_overrides(arguments)
    except Exception:  # not a Hydra command line (a launcher's own process): the sweeper's keys alone
        overrides = []
    return {key.lstrip("+~") for key in sweeper_params} | \
        {o.get_key_element().lstrip("+~") for o in overrides if o.is_sweep_override()}


def run_name(default: str) -> str:
    if not _multirun():
        return default
    hydra = HydraConfig.get()
    job = list(hydra.overrides.task)
    keys = swept_keys(sys.argv[1:], dict(hydra.sweeper.get("params") or {}))
    chosen = [override for override in job if override.split("=", 1)[0].lstrip("+~") in keys]
    return ",".join(chosen or job) or default


def sweep_group() -> str | None:
    return str(HydraConfig.get().sweep.dir) if _multirun() else None


def run_id(folder: str) -> str:
    return hashlib.sha256(str(Path(folder).resolve()).encode()).hexdigest()[:RUN_ID_LENGTH]


def register_resolvers() -> None:
    """Make the resolvers known to OmegaConf (again: a no-op)."""
    for name, function in (("run_name", run_name), ("sweep_group", sweep_group), ("run_id", run_id)):
        OmegaConf.register_new_resolver(name, function, replace=True)
