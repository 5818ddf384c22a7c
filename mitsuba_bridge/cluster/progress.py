"""Progress of a render on a cluster: a line as chunks complete (at most one a second), or a bar on a terminal."""
from __future__ import annotations

import sys
import time

__all__ = ["ClusterProgress"]

BAR_WIDTH = 30


class ClusterProgress:
    """Reports chunks done out of ``total`` on ``stream``: lines in a log, one redrawn bar on a terminal."""

    def __init__(self, total_chunks: int, *, stream=None, quiet: bool = False, interval_s: float = 1.0,
                 bar: bool | None = None):
        self.total = int(total_chunks)
        self.stream = stream or sys.stdout
        self.quiet = quiet
        self.interval_s = interval_s
        self.bar = self.stream.isatty() if bar is None else bar
        self.started = time.perf_counter()
        self._last: float | None = None
        self._drawn = False

    def grow(self, chunks: int) -> None:
        """More chunks to render (an animation's frames are scheduled as their exports finish)."""
        self.total += int(chunks)

    def update(self, done_chunks: int, note: str = "") -> None:
        """``done_chunks`` of :attr:`total` are rendered; shown when a second has passed, and at the end."""
        if self.quiet:
            return
        now = time.perf_counter()
        finished = done_chunks >= self.total
        if not finished and self._last is not None and now - self._last < self.interval_s:
            return
        self._last = now
        fraction = done_chunks / max(self.total, 1)
        text = f"{done_chunks:6d}/{self.total} chunks  {100 * fraction:5.1f} %  {now - self.started:7.1f} s"
        text += f"  {note}" if note else ""
        if self.bar:
            filled = int(round(BAR_WIDTH * fraction))
            self.stream.write(f"\r  [{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {text}\033[K")
            self._drawn = True
            if finished:
                self.stream.write("\n")
                self._drawn = False
        else:
            self.stream.write(f"  {text}\n")
        self.stream.flush()

    def message(self, text: str) -> None:
        """A line of its own (a lost worker, a finished frame), below the bar."""
        if self.quiet:
            return
        if self._drawn:
            self.stream.write("\n")
            self._drawn = False
        self.stream.write(f"{text}\n")
        self.stream.flush()
