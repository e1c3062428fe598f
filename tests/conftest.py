"""The whole suite's hooks: no process that a test starts outlives the run, Ctrl-C included
(:mod:`descendant_reaper`)."""

from descendant_reaper import pytest_configure  # noqa: F401 (the hook)
