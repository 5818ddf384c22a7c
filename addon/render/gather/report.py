"""Problems met while gathering: warnings shown once each, and errors that stop the render."""
from __future__ import annotations

from ....mitsuba_bridge.errors import ScratchUserError

__all__ = ["GatherError", "Warnings"]


class GatherError(ScratchUserError, RuntimeError):
    """The scene cannot be rendered at all (no camera, unsupported camera...); the message says how to fix it."""


class Warnings:
    """Collects warnings for the render report, each distinct message once.

    ``key`` groups messages that should appear only once (e.g. one warning per
    material, however many objects use it).
    """

    def __init__(self):
        self._messages: list[str] = []
        self._keys: set = set()

    def warn(self, message: str, *, key=None) -> None:
        key = message if key is None else key
        if key not in self._keys:
            self._keys.add(key)
            self._messages.append(message)

    def __iter__(self):
        return iter(self._messages)

    def __len__(self):
        return len(self._messages)

    def as_tuple(self) -> tuple[str, ...]:
        return tuple(self._messages)
