"""One torch thread for the Lightning tests: tiny models gain nothing from more, and on a shared
machine a second spinning thread per process slows every test several-fold."""

from collections.abc import Iterator

import pytest
import torch


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
