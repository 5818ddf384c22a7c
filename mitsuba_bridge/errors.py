"""The project's user errors: what a user can act on, as opposed to bugs.

Every error whose message tells a user what is wrong with *their* input (a
parameter, a file, a mesh, the machine's memory or devices) derives from
:class:`ScratchUserError`.  The add-on turns exactly these into one report
(``addon.operators.editing.USER_ERRORS``) and the command line into one line on
stderr; anything else (a ``ValueError`` or ``TypeError`` from a wrong call) is
a bug and propagates with its traceback.

The subclasses keep their historical built-in base as a second base
(``ScratchFormatError`` is still a ``ValueError``), so that code catching the
built-in type keeps working.
"""
from __future__ import annotations

__all__ = ["ScratchUserError", "ParameterError"]


class ScratchUserError(Exception):
    """Base of the errors a user can fix; the message says what is wrong and, where it can, how to fix it."""


class ParameterError(ScratchUserError, ValueError):
    """A value the user chose cannot work (a distribution with no positive values, a maximum below its minimum)."""
