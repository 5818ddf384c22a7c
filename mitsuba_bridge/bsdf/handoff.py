"""The window search of ``eval_pdf`` handed on to the ``sample`` call that follows it at the same point.

Mitsuba's path tracers ask a BSDF for two things at every vertex: ``eval_pdf``
towards the light they sampled and ``sample`` of the next direction
(``BSDF::eval_pdf_sample``, whose default calls one after the other; Python
BSDFs cannot override it in Mitsuba 3.9).  Both need the same search of the
shading point's coherence window (its periodic family, the pieces in it): the
search depends on the point, not on the directions.  ``eval_pdf`` leaves its
search here, and ``sample`` takes it instead of searching again when it is
certainly the same search, in the same traced program:

* the same plugin, the same ``active`` mask and the same lobes asked for;
* the same Dr.Jit variables for every field of the interaction that the search
  reads (``uv``, ``dp_du``, ``dp_dv``, the shading frame) and for ``wi`` (the
  search's mask reads ``wi.z``); the slot holds them, so their indices cannot be
  reused by other variables meanwhile;
* no basic block boundary in between (the Dr.Jit *scope*, :func:`drjit.detail.scope`, unchanged since
  ``eval_pdf`` returned): a loop, a branch or a virtual call traced in between changes it, so the
  search's variables are always visible where ``sample`` uses them.

Anything else (``sample`` alone, ``eval_pdf`` alone, another point) searches
as before.  Taken or not, the slot is emptied by the next ``sample``; what is
taken changes no result, only the time (docs/bsdf.md, Performance).  Only traced
calls (inside a symbolic loop, branch or virtual call, as a render's) leave their
search: there its variables are code, not memory, where an evaluated call's would
hold some twenty arrays of every lane until the next call.
"""
from __future__ import annotations

import atexit
import threading

import drjit as dr

__all__ = ["traced", "leave", "take", "clear", "statistics"]

_slot = threading.local()  #: per tracing thread: ``entry`` = (key, held arrays, search), or None
_counts = {"left": 0, "taken": 0, "refused": 0}


def _fields(si) -> tuple:
    """The interaction's arrays that a window search reads (and ``wi``)."""
    frame = si.sh_frame
    # (si.t: the footprint filter's search reaches as far as the sample's footprint, docs/model.md §11)
    return (si.uv.x, si.uv.y, *si.dp_du, *si.dp_dv, *frame.s, *frame.t, *si.wi, si.t)


def _indices(arrays) -> tuple | None:
    """Their Dr.Jit variable indices, or None when one is not a JIT variable (0: a plain value)."""
    indices = tuple(int(getattr(array, "index", 0)) for array in arrays)
    return None if 0 in indices else indices


def _mask_key(active):
    index = getattr(active, "index", None)
    return ("variable", int(index)) if index is not None else ("value", bool(active))


def _scope(fields) -> int:
    return dr.detail.scope(dr.backend_v(fields[0]))


def traced() -> bool:
    """Whether the calls are being traced into a symbolic region (where ``eval_pdf`` leaves its search)."""
    return bool(dr.flag(dr.JitFlag.SymbolicScope))


def leave(owner, si, active, lobes: tuple, search) -> None:
    """``eval_pdf`` of ``owner`` searched the window of ``si`` (``active``, ``lobes``): keep ``search``."""
    fields = _fields(si)
    indices = _indices(fields)
    if indices is None:
        clear()
        return
    key = (id(owner), indices, _mask_key(active), tuple(lobes), _scope(fields))
    # (the arrays themselves are held: while held, no other variable can take their indices)
    _slot.entry = (key, (fields, active), search)
    _counts["left"] += 1


def take(owner, si, active, lobes: tuple):
    """The search ``eval_pdf`` left for this very ``sample`` call (see the module docstring), or None."""
    entry = getattr(_slot, "entry", None)
    if entry is None:
        return None
    _slot.entry = None
    key, _held, search = entry
    fields = _fields(si)
    indices = _indices(fields)
    if indices is None or key != (id(owner), indices, _mask_key(active), tuple(lobes), _scope(fields)):
        _counts["refused"] += 1
        return None
    _counts["taken"] += 1
    return search


def clear() -> None:
    """Drop this thread's slot (its variables with it)."""
    _slot.entry = None


def statistics() -> dict:
    """``left``, ``taken`` and ``refused`` searches since the start (all threads)."""
    return dict(_counts)


# A slot left by an eval_pdf without a sample still holds Dr.Jit variables: released before Dr.Jit shuts down.
atexit.register(clear)
