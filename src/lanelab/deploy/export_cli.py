"""``lanelab-export``: a trained SparseLaneSTP's or Bi²Lane's streaming step as an ONNX or
torch.export file, its memory as explicit inputs and outputs (layout: :mod:`lanelab.deploy.explicit_state`).

    lanelab-export checkpoint=FILE format=onnx|torch out=FILE [batch_size=1] [check.frames=20] [check.tolerance=1e-3]

Options are Hydra overrides of ``conf/export.yaml``. The file is written only once it has run
over a clip beside the eager model (:func:`lanelab.deploy.export.export_checkpoint`); prints
the inputs, outputs, the ONNX opset and the check's largest differences (lane points in metres,
other tensors relative to their scale: :func:`lanelab.deploy.export.difference`). Exits with
status 1 when the checkpoint cannot be used (one line naming it) or the check fails (one line
naming the ways on: a larger ``check.tolerance``, or ``format=torch``), 2 on a bad option.
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig

from lanelab.config_checks import ConfigError, options_or_exit, register_schema, run_hydra_tool
from lanelab.deploy.config import SCHEMA_NAME, ExportConfig, validate

register_schema(SCHEMA_NAME, ExportConfig)
NAME = "lanelab-export"


def run(cfg: ExportConfig) -> int:
    """Export with validated options; the exit status."""
    # Heavy imports (torch, the model) only once the options are good.
    from lanelab.deploy.export import ExportError, export_checkpoint
    from lanelab.deploy.trained import load_trained
    from lanelab.finite import NonFiniteError

    try:
        trained = load_trained(cfg.checkpoint, "cpu")
        exported, differences = export_checkpoint(trained, cfg.format, cfg.out, cfg.batch_size, cfg.check.frames,
                                                  cfg.check.tolerance)  # fmt: skip
    except (ConfigError, NonFiniteError, ExportError) as err:
        print(f"{NAME}: {err}", file=sys.stderr)
        return 1
    meta = exported.metadata
    opset = f", ONNX opset {exported.opset}" if exported.opset is not None else ""
    print(f"{NAME}: wrote {exported.path} ({meta['model']}, {exported.format}{opset}, {meta['batch']} stream(s) "
          f"of {meta['image_size'][0]}x{meta['image_size'][1]} images)")
    print(f"  inputs:  {', '.join(meta['inputs'])}")
    print(f"  outputs: {', '.join(meta['outputs'])}")
    for name, tensor in meta["state"].items():
        print(f"  state {name}: {tensor['dtype']} (B, {', '.join(map(str, tensor['shape']))})")
    if differences:
        print(f"  check over {cfg.check.frames} frames against step(), largest difference (lane points in metres, "
              f"the others relative to their scale; tolerance {cfg.check.tolerance:g}):")
        for name, value in differences.items():
            print(f"    {name:<24}{value:.3g}")
    return 0


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="export")
def _run(cfg: DictConfig) -> None:
    options = options_or_exit(NAME, cfg, ExportConfig, validate)
    sys.exit(run(options))


def main() -> None:
    run_hydra_tool(NAME, _run)


if __name__ == "__main__":
    main()
