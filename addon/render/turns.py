"""Final renders and Rendered viewports take turns on Mitsuba (docs/rendering.md, Rendered viewport).

Cycles lets F12 and the viewport render at once.  Here both run Dr.Jit in one
process, and Dr.Jit traces a call through a BSDF pointer for *every* BSDF alive
in the process: a viewport pass traced while F12 builds its scene traced the
final render's half-made BSDF (an AttributeError that ended the viewport
session), and F12's frozen passes fell back to tracing.  So a final render
waits for the viewport pass in progress, viewports wait while it renders, and
resume where they were.  On a 2-core CPU running both at once only halved each.

Pure Python (``threading``), no bpy: the engine's F12 path holds
:func:`viewports_paused`; each viewport worker wraps its Mitsuba work in
:func:`viewport_turn`.
"""
from __future__ import annotations

import contextlib
import threading

__all__ = ["viewports_paused", "viewport_turn", "state"]

_condition = threading.Condition()
_final_renders = 0  #: final renders holding viewports_paused()
_viewports_working = 0  #: viewport workers inside viewport_turn()


@contextlib.contextmanager
def viewports_paused(waiting=None):
    """Around a final render's Mitsuba work: no viewport pass runs meanwhile.

    Waits for the passes in progress to end; ``waiting()`` is called once first if any is (the engine
    shows it in the status bar)."""
    global _final_renders
    with _condition:
        _final_renders += 1
        if _viewports_working and waiting is not None:
            waiting()
        while _viewports_working:
            _condition.wait()
    try:
        yield
    finally:
        with _condition:
            _final_renders -= 1
            _condition.notify_all()


@contextlib.contextmanager
def viewport_turn():
    """Around one viewport step (a build, an update, a pass): waits while a final render runs."""
    global _viewports_working
    with _condition:
        while _final_renders:
            _condition.wait()
        _viewports_working += 1
    try:
        yield
    finally:
        with _condition:
            _viewports_working -= 1
            _condition.notify_all()


def state() -> dict:
    """``final_renders`` and ``viewports_working`` now (tests)."""
    with _condition:
        return {"final_renders": _final_renders, "viewports_working": _viewports_working}
