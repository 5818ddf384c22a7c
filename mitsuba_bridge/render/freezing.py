"""Frozen render passes: ``mi.render`` recorded once with ``dr.freeze``, then replayed without re-tracing.

Every ``mi.render`` call traces the integrator and the Python BSDF again before
Dr.Jit finds its cached kernel (about 40 ms per pass on a 2-core CPU, most of a
1-spp pass on a GPU).  ``dr.freeze`` records the kernels a function launches
and replays them for new inputs, found by traversing the arguments (the scene,
its plugins, the Python BSDF's attributes).

Why spectral renders do not freeze out of the box (Mitsuba 3.9, Dr.Jit 1.5):
the film's spectrum → XYZ conversion reads Mitsuba's CIE 1931 tables, static
Dr.Jit arrays that belong to no scene object, so recording fails with
"Variable … was created before recording was started, but it was not specified
as an input" even for a scene of built-in plugins only (the scratch BSDF's
arrays are all reachable).  :func:`mitsuba_globals` finds those variables once
per variant by recording a tiny plugin-free scene, and every frozen pass takes
them as an extra, unused argument.  Only variables found on that plugin-free
scene are accepted, so an array a plugin hides from traversal still fails
loudly (and the pass falls back to ``mi.render``) instead of being replayed stale.

Replays see changed *array* values (camera matrix, field of view, shift) but
not changed scalars of C++ objects (clipping distances, film size) nor Python
values: callers :meth:`FrozenRender.reset` after such updates (the session
resets after anything but a camera move within the same clipping range).
"""
from __future__ import annotations

import re

from .interrupts import raise_if_interrupted

__all__ = ["FrozenRender", "calibrate", "mitsuba_globals", "unreachable_variable"]

#: Unreachable variables accepted at most (Mitsuba 3.9 has four: the CIE x, y, z tables and Y).
MAX_GLOBALS = 16

_globals: dict[str, list] = {}
_UNREACHABLE = re.compile(r"Variable r(\d+)\[\d+\].*created before recording was started")


def unreachable_variable(error: BaseException) -> int | None:
    """The Dr.Jit variable index that a failed recording names as unreachable, or None."""
    while error is not None:
        match = _UNREACHABLE.search(str(error))
        if match:
            return int(match.group(1))
        error = error.__cause__
    return None


def _calibration_scene():
    import mitsuba as mi

    return mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 2},
        "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4,
                                                   "pixel_format": "rgba", "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent"}},
        "floor": {"type": "rectangle", "bsdf": {"type": "diffuse"},
                  "to_world": mi.ScalarTransform4f().translate([0, 0, 2])},
        "world": {"type": "constant"}})


def _pass(scene, seed, handles, sensor: int, spp: int):
    import mitsuba as mi

    del handles  # inputs only: they make Mitsuba's global tables known to the recording
    return mi.render(scene, sensor=sensor, spp=spp, seed=seed)


def _freeze(sensor: int, spp: int):
    import drjit as dr

    return dr.freeze(lambda scene, seed, handles: _pass(scene, seed, handles, sensor, spp))


def mitsuba_globals() -> list:
    """Handles on the Dr.Jit arrays a spectral render reads outside any scene object (cached per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant not in _globals:
        handles: list = []
        scene, function = _calibration_scene(), _freeze(0, 1)
        for _ in range(MAX_GLOBALS + 1):
            try:
                dr.eval(function(scene, mi.UInt32(0), handles))
                break
            except RuntimeError as error:
                index = unreachable_variable(error)
                if index is None or len(handles) == MAX_GLOBALS:
                    raise
                # dr.detail.update_indices wraps an existing variable (taking a reference): the
                # documented way to name a variable by index, meant for Dr.Jit's own use.
                handles.append(dr.detail.update_indices(dr.zeros(mi.Float, 1), [index]))
                function = _freeze(0, 1)
        _globals[variant] = handles
    return _globals[variant]


def calibrate() -> None:
    """Find :func:`mitsuba_globals` now, while no scene of the active variant exists (called by
    :func:`.activation.activate`).

    The calibration scene's BSDF call is a virtual call over every live BSDF of the variant: found
    later, with a scratch BSDF loaded, its kernel holds the whole scratch model and compiles as long
    as the render's own (measured on the Fig. 17 V-grooves with height-field crossings, cold kernel
    cache: 24.7 s for the first frozen pass against 11.5 s traced).  A failure here is left to the
    first frozen pass, which falls back to traced passes.
    """
    try:
        mitsuba_globals()
    except RuntimeError:
        pass


class FrozenRender:
    """``render(scene, sensor, spp, seed)`` through one frozen function per (sensor, spp).

    Falls back to plain ``mi.render`` for good (``failure`` says why) when a
    recording fails, so freezing can only make passes faster, never wrong.
    """

    def __init__(self, enabled: bool = True):
        self.enabled = enabled
        self.failure: str | None = None
        self._recorded = 0  #: recordings of functions already dropped
        self._functions: dict = {}

    @property
    def recordings(self) -> int:
        """Passes recorded so far (each costs about one traced pass; replays cost almost nothing)."""
        return self._recorded + sum(function.n_recordings for function in self._functions.values())

    def reset(self) -> None:
        """Forget the recordings (after updates that replays would not see)."""
        self._recorded = self.recordings
        self._functions.clear()

    def __call__(self, scene, sensor: int, spp: int, seed: int):
        import drjit as dr
        import mitsuba as mi

        if self.enabled:
            try:
                handles = mitsuba_globals()
                key = (sensor, spp)
                if key not in self._functions:
                    self._functions[key] = _freeze(sensor, spp)
                # An opaque seed: a literal one would be recorded again as soon as it changes.
                return self._functions[key](scene, dr.opaque(mi.UInt32, seed), handles)
            except RuntimeError as error:
                raise_if_interrupted(error)  # Ctrl-C while recording: not the recording's fault
                self.enabled, self._functions = False, {}
                self.failure = _chain(error)
        try:
            return mi.render(scene, sensor=sensor, spp=spp, seed=seed)
        except RuntimeError as error:
            raise_if_interrupted(error)
            raise


def _chain(error: BaseException) -> str:
    """The messages of ``error`` and its causes (Dr.Jit puts the reason in the innermost one)."""
    messages = []
    while error is not None:
        messages.append(str(error))
        error = error.__cause__
    return " <- ".join(reversed(messages))
