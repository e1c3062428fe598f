from collections.abc import Iterator
from pathlib import Path

import pytest
import torch
from tiny_store import build_store


@pytest.fixture(scope="session")
def tiny_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("tiny_store"))


@pytest.fixture(autouse=True)
def restore_torch_threads() -> Iterator[None]:
    """The tiny experiment sets cpu_threads=1 for its process; later tests get theirs back."""
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)
