"""Frame numbers and frame-numbered paths, as Blender's command line writes them.

``parse_frames("1-3,7")`` → ``[1, 2, 3, 7]`` (Blender's ``1..3`` also works);
``frame_path("out/frame_####.exr", 7)`` → ``out/frame_0007.exr``: every run of
``#`` becomes the frame number padded to that many digits, and a path without
``#`` gets four digits before its suffix (as Blender appends them).
"""
from __future__ import annotations

import re
from pathlib import Path

from ..errors import ParameterError

__all__ = ["parse_frames", "frame_path", "FrameSpecError"]

#: More frames than this in one command is a typo (``1-100000000``), refused before anything starts.
MAX_FRAMES = 1_000_000


class FrameSpecError(ParameterError):
    """A frame list that cannot be read (says what was expected)."""


def parse_frames(text: str) -> list[int]:
    """The frames of ``text``: numbers and ranges (``1-240``, ``1..240``, ``1-9:2`` for every second one),
    separated by commas, in the order given, each once."""
    frames: list[int] = []
    for item in str(text).replace(" ", "").split(","):
        match = re.fullmatch(r"(-?\d+)(?:(?:-|\.\.)(-?\d+)(?::(\d+))?)?", item)
        if not match:
            raise FrameSpecError(f"frames {text!r}: expected numbers and ranges such as 1-240 or 1,5,10-12")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        step = int(match.group(3) or 1)
        if last < first or step < 1:
            raise FrameSpecError(f"frames {text!r}: the range {item} is empty")
        if (last - first) // step + 1 + len(frames) > MAX_FRAMES:
            raise FrameSpecError(f"frames {text!r}: more than {MAX_FRAMES:,} frames")
        frames += [frame for frame in range(first, last + 1, step) if frame not in frames]
    return frames


def frame_path(pattern, frame: int) -> Path:
    """``pattern`` with its runs of ``#`` replaced by ``frame`` (zero-padded to the run's length); without
    any ``#``, four digits are added before the suffix."""
    pattern = str(pattern)
    if "#" not in pattern:
        path = Path(pattern)
        return path.with_name(f"{path.stem}{frame:04d}{path.suffix}")
    sign = "-" if frame < 0 else ""
    return Path(re.sub(r"#+", lambda run: f"{sign}{abs(frame):0{len(run.group()) - len(sign)}d}", pattern))
