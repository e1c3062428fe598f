"""Progress of a long loop: tqdm's bar on a terminal, plain lines where the output goes to a file
or a pipe (a bar there is one line of carriage returns, hundreds of KB long).

:class:`Progress` is what lanelab-synth, -ingest and -predict count their work with;
:class:`LineTimer` says when the next plain line is due (each tenth of the work, or
:data:`INTERVAL_S` after the last line), for them and for the training's plain progress lines
(:class:`lanelab.lightning.console.ProgressLines`).
"""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import Callable, TextIO

from tqdm import tqdm

INTERVAL_S = 30.0  # seconds: the longest wait between two plain lines
STEPS = 10  # a plain line each time another 1 / STEPS of the work is done


def is_terminal(stream: TextIO) -> bool:
    """Whether stream is an interactive terminal (a bar redraws in place there)."""
    return bool(getattr(stream, "isatty", lambda: False)())


def countable(total: float | None) -> float | None:
    """total where it counts the work, None where it does not (unknown, 0 or inf: Lightning's
    batch counts where it cannot count them, e.g. an iterable dataset or the last step under
    ``max_time``)."""
    return total if total and total != float("inf") else None


class LineTimer:
    """When a plain progress line is due: the work done has reached the next 1 / :data:`STEPS`
    of total (if known), or interval_s have gone by since the last line."""

    def __init__(self, total: float | None, interval_s: float = INTERVAL_S,
                 clock: Callable[[], float] = time.monotonic) -> None:  # fmt: skip
        self.total = countable(total)
        self.interval_s, self.clock = interval_s, clock
        self._last_time, self._next_step = clock(), 1

    def due(self, done: float) -> bool:
        """True (and the timer restarted) when a line for ``done`` should be printed now."""
        now = self.clock()
        stepped = self.total is not None and done >= self._next_step * self.total / STEPS
        if not stepped and now - self._last_time < self.interval_s:
            return False
        if self.total is not None:
            self._next_step = int(done * STEPS // self.total) + 1
        self._last_time = now
        return True


class Progress:
    """A count of work done out of ``total`` ``unit`` (``unit_scale``: sizes such as 1.2 GB),
    shown on ``stream`` as a bar if it is a terminal, else as lines
    ``<desc>: <done>/<total> <unit> (<percent> %), <seconds> s`` when :class:`LineTimer` says so
    and once at the end. The default stream: stderr where it is a terminal (tqdm's), else stdout
    (the lines join a tool's other output there; stderr keeps its errors alone). A context
    manager; ``n`` is the count so far."""

    def __init__(self, total: float, desc: str, unit: str, unit_scale: bool = False,
                 stream: TextIO | None = None) -> None:  # fmt: skip
        self.total, self.desc, self.unit, self.unit_scale = total, desc, unit, unit_scale
        self.stream = stream if stream is not None else sys.stderr if is_terminal(sys.stderr) else sys.stdout
        self.n = 0
        self._bar = (tqdm(total=total, desc=desc, unit=unit, unit_scale=unit_scale, dynamic_ncols=True, file=self.stream)
                     if is_terminal(self.stream) else None)  # fmt: skip
        self._timer = LineTimer(total)
        self._start, self._printed = time.monotonic(), -1.0

    def update(self, n: float = 1) -> None:
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
        elif self._timer.due(self.n):
            self._line()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        elif self._printed != self.n:
            self._line()

    def _line(self) -> None:
        count = tqdm.format_sizeof if self.unit_scale else lambda value: f"{value:.0f}"
        percent = f" ({100 * self.n / self.total:.0f} %)" if self.total else ""
        print(f"{self.desc}: {count(self.n)}/{count(self.total)} {self.unit}{percent}, "
              f"{time.monotonic() - self._start:.0f} s", file=self.stream, flush=True)  # fmt: skip
        self._printed = self.n

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:  # fmt: skip
        self.close()
