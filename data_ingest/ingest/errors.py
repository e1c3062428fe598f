"""The error that stops the ingestion of one log (the other logs of a run go on)."""


class LogError(Exception):
    """A log that cannot be ingested; the message names the file and what is wrong with it."""
