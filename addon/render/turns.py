"""F12 and the Rendered viewports take turns on Mitsuba (docs/rendering.md, Rendered viewport).

Cycles lets F12 and viewports render at once.  Here all of them run Dr.Jit in
one process, and Dr.Jit traces a call through a BSDF pointer for *every* BSDF
alive in the process: a viewport pass traced while F12 built its scene traced
the final render's half-made BSDF (an AttributeError that ended the viewport
session), and F12's frozen passes fell back to tracing; two viewports in
Rendered shading meet the same way.  So one viewport step (a build, an update,
a strip or pass) runs at a time, in the order they asked (first come, first
served: two viewports alternate); a final render waits for the step in
progress, and no viewport step starts while it renders.  On a 2-core CPU
running both at once only halved each.

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
_working = False  #: a viewport step is running
_next_ticket = 0  #: the ticket the next viewport step draws
_serving = 0  #: the ticket whose step runs (or may run) now


@contextlib.contextmanager
def viewports_paused(waiting=None):
    """Around a final render's Mitsuba work: no viewport step runs meanwhile.

    Waits for the step in progress to end; ``waiting()`` is called once first if one is (the engine
    shows it in the status bar)."""
    global _final_renders
    with _condition:
        _final_renders += 1
        if _working and waiting is not None:
            waiting()
        while _working:
            _condition.wait()
    try:
        yield
    finally:
        with _condition:
            _final_renders -= 1
            _condition.notify_all()


@contextlib.contextmanager
def viewport_turn():
    """Around one viewport step: waits for the steps asked for before it and while a final render runs."""
    global _working, _next_ticket, _serving
    with _condition:
        ticket = _next_ticket
        _next_ticket += 1
        while _final_renders or _serving != ticket:
            _condition.wait()
        _working = True
    try:
        yield
    finally:
        with _condition:
            _working = False
            _serving += 1
            _condition.notify_all()


def state() -> dict:
    """``final_renders``, ``viewports_working`` (0 or 1) and ``viewports_waiting`` now (tests)."""
    with _condition:
        return {"final_renders": _final_renders, "viewports_working": int(_working),
                "viewports_waiting": _next_ticket - _serving - int(_working)}
