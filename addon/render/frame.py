"""Rendering one frame for the render engine: gather → build → progressive passes → Combined (and data) passes.

Kept apart from the ``RenderEngine`` class so that it reads top to bottom and
every failure ends in ``report``/``error_set`` rather than in a silent black
image.  Nothing is written to disk: meshes, textures and scratches go to
Mitsuba in memory.
"""
from __future__ import annotations

import dataclasses
import traceback

import bpy
import numpy as np

from ...mitsuba_bridge.errors import ScratchUserError
from ...mitsuba_bridge.render.aovs import PASSES, blender_passes  # numpy only: no Mitsuba imported here
from . import backend
from .gather import GatherError, gather_scene, gather_settings
from .turns import viewports_paused

__all__ = ["render_frame", "combined_rect", "data_passes"]

#: The image in Blender refreshes at most this often (Esc is honoured after every chunk). Only the
#: display depends on time: the chunks and so the image are fixed by samples, resolution and seed.
REFRESH_SECONDS = 1.0


def combined_rect(image: np.ndarray, transparent: bool) -> np.ndarray:
    """Mitsuba's RGBA image (row 0 at the top) as Blender's Combined pass rect (row 0 at the bottom)."""
    rect = np.ascontiguousarray(image[::-1], dtype=np.float32).reshape(-1, 4)
    if not transparent:
        rect[:, 3] = 1.0
    return rect


def data_passes(scene, view_layer) -> dict:
    """The data passes ``view_layer`` asks for: Depth with its Z pass, the denoising passes with Denoising Data."""
    wanted = {"Depth": bool(view_layer.use_pass_z)}
    denoising = bool(scene.scratch_iridescence.denoising_data)
    wanted.update({"Denoising Normal": denoising, "Denoising Albedo": denoising})
    return {name: PASSES[name] for name, on in wanted.items() if on}


def pass_rect(image: np.ndarray) -> np.ndarray:
    """A pass image (H, W, C), row 0 at the top, as Blender's rect (row 0 at the bottom), flat float32."""
    return np.ascontiguousarray(image[::-1], dtype=np.float32).ravel()


def _fail(engine, message: str) -> None:
    engine.report({"ERROR"}, message)
    engine.error_set(message)


def _user_error(error: BaseException):
    """The :class:`ScratchUserError` that is ``error`` or its cause or context, if any (the bridge's loader hands on a
    plugin's user error itself: :func:`...mitsuba_bridge.errors.plugin_user_errors`)."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, ScratchUserError):
            return error
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return None


def _bridge():
    """The bridge modules that need Mitsuba, or :class:`.backend.BackendUnavailable` saying what to install."""
    backend.require()  # Mitsuba, Dr.Jit and OpenEXR importable for this Blender's Python, or one message
    from ...mitsuba_bridge import builder
    from ...mitsuba_bridge.device import variants
    from ...mitsuba_bridge.render import activation, passes
    return builder, passes, variants, activation


def _write(result, image: np.ndarray, wanted: dict, transparent: bool) -> None:
    """The running image into the result: Combined, and the data passes of ``wanted`` (``render.aovs``)."""
    layer = result.layers[0]
    # foreach_set copies in bulk: assigning ``rect`` goes pixel by pixel (about 1 s for 1080p).
    layer.passes["Combined"].rect.foreach_set(combined_rect(image[..., :4], transparent).ravel())
    if wanted:
        for name, pixels in blender_passes(image).items():
            if name in wanted and name in layer.passes:
                layer.passes[name].rect.foreach_set(pass_rect(pixels))


def render_frame(engine, depsgraph) -> None:
    """Render the frame of ``depsgraph`` into ``engine``'s result (the body of ``RenderEngine.render``)."""
    try:
        builder, passes, variants, activation = _bridge()
    except backend.BackendUnavailable as error:
        _fail(engine, str(error))
        return
    scene = depsgraph.scene
    try:
        wanted = data_passes(scene, depsgraph.view_layer)
        settings = dataclasses.replace(gather_settings(scene), data_passes=bool(wanted))
        engine.update_stats("", "Mitsuba | Choosing device")
        variant = activation.activate(settings.variant)
        engine.update_stats("", "Mitsuba | Gathering scene")
        description = gather_scene(depsgraph, camera=getattr(engine, "camera_override", None))
    except (GatherError, variants.VariantError, ScratchUserError) as error:  # (the description's invariants too)
        _fail(engine, str(error))
        return
    except Exception as error:  # an add-on bug must not look like a black render
        traceback.print_exc()
        _fail(engine, f"Mitsuba Scratch: could not prepare the scene: {type(error).__name__}: {error}")
        return
    for warning in description.warnings:
        engine.report({"WARNING"}, warning)
    if engine.test_break():
        return

    width, height = description.film.size
    try:  # before Blender allocates its own image of that size
        passes.check_film_memory(width, height, settings.spp, settings.seed)
    except (passes.NotEnoughMemory, passes.ScheduleError) as error:
        _fail(engine, f"Mitsuba Scratch: {error}")
        return
    result = engine.begin_result(0, 0, width, height, layer=depsgraph.view_layer.name)
    cancelled, progress = False, None
    try:
        if (result.resolution_x, result.resolution_y) != (width, height):
            raise RuntimeError(f"Blender expects a {result.resolution_x} x {result.resolution_y} image but the "
                               f"scene gives {width} x {height}")
        engine.update_stats("", f"Mitsuba | Loading {len(description.shapes)} shapes "
                                f"({description.triangle_count:,} triangles)")
        # Viewports pause meanwhile: Dr.Jit traces every BSDF in the process (turns.py)
        with viewports_paused(lambda: engine.update_stats("", "Mitsuba | Waiting for the viewport's pass")):
            # Persistent Data (Cycles' option, Performance panel): scratch tables kept between final renders
            mi_scene = builder.load_scene(description, settings, keep_tables=scene.render.use_persistent_data)
            transparent = description.film.transparent
            refresh = passes.Refresh(REFRESH_SECONDS)
            for progress in passes.render_passes(mi_scene, settings.spp, seed=settings.seed):
                engine.update_progress(progress.fraction)
                if refresh.due(progress):
                    _write(result, progress.image, wanted, transparent)
                    engine.update_result(result)
                    status = f"Sample {progress.spp_done}/{progress.spp_total} | {progress.seconds:.1f} s"
                    engine.update_stats("", f"Mitsuba ({variant}) | {status}")
                    if bpy.app.background:  # a console render shows its progress, as Cycles' does
                        print(f"Fra:{scene.frame_current} | Mitsuba Scratch | {status}", flush=True)
                if not progress.finished and engine.test_break():
                    cancelled = True
                    # The image keeps every sample done so far, not only those shown at the last refresh.
                    _write(result, progress.image, wanted, transparent)
                    engine.update_result(result)
                    break
    except passes.RenderInterrupted:  # Ctrl-C in Blender's terminal: Blender's own handler heard it too
        cancelled = True
        if progress is not None:  # the samples of the chunks before the interrupted one
            _write(result, progress.image, wanted, description.film.transparent)
            engine.update_result(result)
    except (passes.NotEnoughMemory, passes.ScheduleError) as error:
        _fail(engine, f"Mitsuba Scratch: {error}")
    except Exception as error:
        user = _user_error(error)
        if user is not None:  # raised inside a plugin (Mitsuba wraps it): the user's to fix, no traceback
            _fail(engine, f"Mitsuba Scratch: {user}")
        else:
            traceback.print_exc()
            _fail(engine, f"Mitsuba Scratch: rendering failed: {type(error).__name__}: {error}")
    finally:
        engine.end_result(result)
    if progress is not None and progress.traced_note:
        print(progress.traced_note, flush=True)  # speed only, for the console (as Cycles' device notes)
    if cancelled:
        engine.report({"INFO"}, "Mitsuba Scratch: render cancelled; the image holds the samples done so far")
