"""What every scratch-editing operator does the same way.

An edit reads the object's scratch set, builds a new one with numpy and writes
it back once, as the last step: any error before that leaves the stored bytes
untouched.  Errors the user can act on become one ``ERROR`` report.
"""
from __future__ import annotations

import math

from ...mitsuba_bridge.errors import ParameterError, ScratchUserError
from ...mitsuba_bridge.scratch import ScratchSet
from .. import storage
from ..geometry import units

__all__ = ["USER_ERRORS", "ObjectModeOperator", "combine", "write", "metres_per_unit", "plural", "fail",
           "warn_relaxed_arcs", "check_numbers"]

#: Exceptions that become a report for the user: the project's user errors (bad parameters, meshes and
#: files, MeshError, SurfaceError, ScratchFormatError, NotEnoughMemory...), the operating system's
#: (a file that cannot be written) and running out of memory (a MemoryError without a message gets
#: one).  Not ValueError or TypeError: those are bugs, and they surface with their traceback.
USER_ERRORS = (ScratchUserError, MemoryError, OSError)


class ObjectModeOperator:
    """Mixin: scratch edits run in Object Mode (the evaluated mesh is then up to date)."""

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Scratches are edited in Object Mode")
            return False
        return True


def check_numbers(operator) -> None:
    """Refuse an operator whose float properties hold NaN.

    Blender clamps infinities and out-of-range values to a property's limits
    (or to the largest float where it has none: those values are refused
    where the numbers become distributions, :mod:`.scatter`), but lets NaN
    through, which no comparison catches later.  Raises ``ValueError`` naming
    the property as the redo panel shows it.
    """
    for prop in operator.properties.bl_rna.properties:
        if prop.type != "FLOAT":
            continue
        value = getattr(operator.properties, prop.identifier)
        values = tuple(value) if prop.is_array else (value,)
        if any(math.isnan(v) for v in values):
            raise ParameterError(f"{prop.name} is not a number (NaN)")


def combine(obj, new: ScratchSet, mode: str) -> ScratchSet:
    """``new`` alone (REPLACE) or appended to the object's scratches (ADD)."""
    if mode == "ADD":
        existing = storage.read_scratches(obj)
        if existing.count:
            return ScratchSet.concatenate([existing, new])
    return new


def write(obj, scratches: ScratchSet) -> bytes:
    """Store ``scratches`` on ``obj`` (the one write of an edit); return the digest of the stored bytes."""
    return storage.write_scratches(obj, scratches)


def metres_per_unit(context) -> float:
    """Metres per scene unit of the context's scene (:func:`..geometry.units.metres_per_unit`)."""
    return units.metres_per_unit(context.scene)


def plural(count: int, word: str = "scratch") -> str:
    """``"1 scratch"``, ``"12,345 scratches"``."""
    noun = word if count == 1 else (word + "es" if word.endswith(("ch", "sh", "s", "x")) else word + "s")
    return f"{count:,} {noun}"


def fail(operator, error) -> set:
    """Report ``error`` (an exception or a message) and cancel."""
    message = str(error) if not isinstance(error, MemoryError) or str(error) else \
        "Not enough memory for this operation; ask for fewer scratches"
    operator.report({"ERROR"}, message)
    return {"CANCELLED"}


def warn_relaxed_arcs(operator, placed) -> None:
    """Say so when some arcs were too long or too bent to keep their sagitta below the limit."""
    if placed.relaxed_arcs:
        from ..geometry.scatter import MAX_SEGMENTS, SAGITTA_FRACTION

        operator.report({"WARNING"}, f"{plural(placed.relaxed_arcs, 'arc')} would need more than "
                                     f"{MAX_SEGMENTS} straight segments to keep the sagitta below "
                                     f"{SAGITTA_FRACTION:g} × width; they use {MAX_SEGMENTS}")
