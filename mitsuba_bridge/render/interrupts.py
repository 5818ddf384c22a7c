"""Renders cut short by Ctrl-C (SIGINT): recognised however Mitsuba hands them on, and never used.

Every ``mi.render`` call of the bridge goes through :func:`render_whole` or catches its
``RuntimeError`` with :func:`raise_if_interrupted`, so a cancelled render raises
:class:`RenderInterrupted` instead of returning a partial image.
"""
from __future__ import annotations

import re

__all__ = ["RenderInterrupted", "interruption_in", "raise_if_interrupted", "render_whole"]


class RenderInterrupted(KeyboardInterrupt):
    """Mitsuba stopped a render early (a SIGINT reached it): the result of that call is not used."""


def interruption_in(error: BaseException | None) -> bool:
    """Whether ``error`` is, or was caused by, a Ctrl-C (``KeyboardInterrupt``).

    A SIGINT that arrives while Mitsuba runs Python code raises
    ``KeyboardInterrupt`` there, and Mitsuba hands it on as a ``RuntimeError``:
    inside ``mi.render`` (a Python plugin's callback, traced inside ``dr.custom``)
    with the interrupt as its cause ("error while performing a custom
    differentiable operation"); inside ``mi.load_*`` (a Python plugin's
    constructor) with the plugin's traceback in its message only.
    """
    while error is not None:
        if isinstance(error, KeyboardInterrupt) or _PYTHON_INTERRUPT.search(str(error)):
            return True
        error = error.__cause__
    return False


def raise_if_interrupted(error: BaseException) -> None:
    """Raise :class:`RenderInterrupted` from ``error`` if it is a Ctrl-C in disguise (:func:`interruption_in`);
    for the ``except RuntimeError`` around every ``mi.render`` call."""
    if interruption_in(error):
        raise RenderInterrupted("interrupted while rendering") from error


#: The last line of a Python traceback that Mitsuba's parser copies into its message.
_PYTHON_INTERRUPT = re.compile(r"^KeyboardInterrupt\b", re.MULTILINE)


def render_whole(scene, **arguments):
    """``mi.render(scene, **arguments)``, refused (:class:`RenderInterrupted`) if a SIGINT cut it short.

    While ``mi.render`` runs, Mitsuba replaces the SIGINT handler with its own,
    which cancels the integrator and passes the signal on to the previous
    handler.  Python's raises ``KeyboardInterrupt`` later (or at once inside a
    Python plugin, where Dr.Jit wraps it in a ``RuntimeError``: unwrapped here
    by :func:`interruption_in`), but a process that inherited SIGINT as ignored
    (a background job of a shell script) never hears of it, and the call
    returns as if nothing happened.  The
    integrator's ``should_stop()`` remembers the cancellation until the next
    render (it is also set by an integrator's ``timeout``, which our scenes
    never set): checked here, so that no cancelled render reaches an image.
    """
    import mitsuba as mi

    try:
        image = mi.render(scene, **arguments)
    except RuntimeError as error:
        raise_if_interrupted(error)
        raise
    if scene.integrator().should_stop():
        raise RenderInterrupted("Mitsuba stopped the render early (interrupted)")
    return image
