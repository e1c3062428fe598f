"""Errors raised in DataLoader worker processes, as users should read them.

PyTorch re-raises a worker's exception in the main process as the same type, with the worker's
traceback in its message ("Caught ClipFileError in DataLoader worker process 0. Original
Traceback ..."). The CLIs print one line: the original message, which the traceback's last line
holds after the exception's type.
"""

from __future__ import annotations

_WRAPPED = "in DataLoader worker process"


def error_message(err: BaseException) -> str:
    """err's own message, on one line also when a DataLoader worker raised it."""
    text = str(err)
    if not (text.startswith("Caught ") and _WRAPPED in text.split("\n", 1)[0]):
        return text
    last = text.rstrip().splitlines()[-1]
    kind, _, message = last.partition(": ")
    return message if message and kind.endswith(type(err).__name__) else last
