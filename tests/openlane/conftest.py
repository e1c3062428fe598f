"""The tiny OpenLane dataset, and the store the adapter makes of it, once per session."""

from __future__ import annotations

from pathlib import Path

import pytest
from openlane_helpers import TinyOpenLane, adapter_config, write_tiny_openlane

from data_ingest.openlane.adapter import adapt


@pytest.fixture(scope="session")
def tiny(tmp_path_factory) -> TinyOpenLane:
    return write_tiny_openlane(tmp_path_factory.mktemp("openlane"))


@pytest.fixture(scope="session")
def store(tiny, tmp_path_factory) -> Path:
    """The store adapted from the tiny dataset (read only: tests that change it make their own)."""
    output = tmp_path_factory.mktemp("store") / "store"
    results = adapt(adapter_config(tiny, output))
    assert [r.status for r in results] == ["written", "written"], [r.error for r in results]
    return output
