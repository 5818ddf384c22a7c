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

import contextlib
import threading

__all__ = ["ScratchUserError", "ParameterError", "raised_in_plugin", "plugin_user_errors"]

_plugin = threading.local()


class ScratchUserError(Exception):
    """Base of the errors a user can fix; the message says what is wrong and, where it can, how to fix it."""


class ParameterError(ScratchUserError, ValueError):
    """A value the user chose cannot work (a distribution with no positive values, a maximum below its minimum)."""


def raised_in_plugin(error: ScratchUserError) -> None:
    """Note ``error``, which a Python plugin's constructor is about to raise into Mitsuba's loader (on this
    thread), for :func:`plugin_user_errors` to hand on."""
    _plugin.error = error


@contextlib.contextmanager
def plugin_user_errors():
    """Around a Mitsuba load: a :class:`ScratchUserError` raised by a Python plugin comes out as itself.

    Mitsuba's parser turns a plugin's exception into a ``RuntimeError`` whose message embeds the whole
    Python traceback, with no ``__cause__``: Blender's F12 and the viewport would show that traceback for
    an error the user can fix (a scratch set whose tables cannot fit).  The user error is raised instead,
    from Mitsuba's.  Loads nest (a plugin may load others): the innermost error noted wins.
    """
    _plugin.error = None
    try:
        yield
    except Exception as error:
        noted, _plugin.error = getattr(_plugin, "error", None), None
        if noted is None or noted is error:
            raise
        # Raised without its own traceback (Mitsuba's message, its cause, quotes it): the plugin's frames hold the
        # half-built BSDF, which must go now, not at the next garbage collection (a cycle through this frame
        # would keep it): Dr.Jit calls every live BSDF of the variant, so the next render would call it.
        try:
            raise noted.with_traceback(None) from error
        finally:
            noted = None
