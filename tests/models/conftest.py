"""The model tests' shared settings (loss_setup: the matcher and loss settings of
conf/model/sparselanestp.yaml), importable from every folder below: the matcher's tests under
parts/, the losses' under sparselanestp/."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
