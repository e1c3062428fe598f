"""The ingest tests' fixtures: small synthetic drive logs (:mod:`log_fixtures`)."""

from log_fixtures import drive, synth_log  # noqa: F401 (fixtures)
