"""The errors of an ingest: one that stops the ingestion of one log (the other logs of a run go
on), and the interrupt that stops the run."""


class LogError(Exception):
    """A log that cannot be ingested; the message names the file and what is wrong with it."""


class IngestInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a run; the message says how many logs it recorded and that a re-run resumes."""
