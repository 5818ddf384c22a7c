"""The wave-optical scratch BSDF ``scratch_diffraction`` for Mitsuba 3 (docs/model.md).

Importing this package imports neither Mitsuba nor Dr.Jit; the functions
below do, and need an active variant (``mi.set_variant(...)``).

Layout: pure Dr.Jit maths in :mod:`.complexmath`, :mod:`.faddeeva`,
:mod:`.window`, :mod:`.profiles`, :mod:`.segment`, :mod:`.sampling`,
:mod:`.overlap` (the height-field correction of a crossing pair), :mod:`.polygon`
(windowed transforms of clipped cells) and :mod:`.triples` (overlaps of three to five),
:mod:`.energy` (the albedo estimate of ``depth_phase="bounded"``); the
numpy side in :mod:`.tables` (segment table, UV grid, cell size), :mod:`.references`
(the grid's references to the pieces, sorted by offset), :mod:`.crossings`
(crossing pairs of pieces), :mod:`.memory` (in-memory parameters) and :mod:`.persistent` (tables shared
with live scenes and kept between final renders); the per-lane model in :mod:`.model` with the grid walk
of :mod:`.lookup`; and the thin ``mi.BSDF`` class in :mod:`.plugin`, whose
docstring is the manual.
"""
from __future__ import annotations

from .parameters import (DEFAULT_COHERENCE_DIAMETER_M, DEFAULT_CROSSINGS, DEFAULT_DEPTH_PHASE, DEFAULT_MATERIAL,
                         PLUGIN_NAME)

__all__ = ["register", "plugin_dict", "load", "scratch_parameters", "update_scratches", "PLUGIN_NAME"]


def register() -> None:
    """Register ``scratch_diffraction`` for the active Mitsuba variant (idempotent)."""
    import mitsuba as mi

    from .plugin import plugin_class

    cls = plugin_class()
    mi.register_bsdf(PLUGIN_NAME, lambda props: _construct(cls, props))


def _construct(cls, props):
    """``cls(props)``; a user error on its way into Mitsuba's loader is noted (:func:`..errors.plugin_user_errors`)."""
    from ..errors import ScratchUserError, raised_in_plugin

    try:
        return cls(props)
    except ScratchUserError as error:
        raised_in_plugin(error)
        raise


def plugin_dict(scratches=None, *, filename=None, coherence_diameter=DEFAULT_COHERENCE_DIAMETER_M,
                unit_scale=1.0, material=DEFAULT_MATERIAL, eta=None, k=None, diffuse_reflectance=None,
                coherent=True, depth_phase=DEFAULT_DEPTH_PHASE, crossings=DEFAULT_CROSSINGS,
                cell_size=0.0, footprint_filter=False, footprint_angle=0.0, footprint_width=0.0) -> dict:
    """The ``mi.load_dict`` dictionary of a ``scratch_diffraction`` BSDF.

    Parameters
    ----------
    scratches : mitsuba_bridge.scratch.ScratchSet, optional
        Passed in memory (Dr.Jit tensors, no temporary file).  Mutually
        exclusive with ``filename``; neither gives an unscratched surface.
    filename : str or path, optional
        A format-v1 scratch file, read when the dictionary is loaded.
    coherence_diameter : float
        δ_c in metres.
    unit_scale : float
        Metres per scene unit.
    material : str
        Conductor name of Mitsuba's ``conductor`` plugin, or ``"none"``.
    eta, k : float or dict, optional
        Explicit conductor indices (a number or a Mitsuba spectrum/texture
        dictionary); replace ``material``.
    diffuse_reflectance : float or dict, optional
        Lambertian base.
    coherent : bool
        Coherent or incoherent superposition.
    depth_phase : str
        ``"kirchhoff"`` (the paper's phase 2π(γ_i + γ_o)d/λ) or ``"incidence"``
        (4πγ_i d/λ: energy-conserving, not reciprocal; docs/bsdf.md, Energy).
        Written to the dictionary only when not the default.
    crossings : str
        ``"additive"`` (the paper's sum of transfer functions) or
        ``"height_field"`` (crossings of rectangular scratches take the deeper
        depth, docs/model.md §3.4).  Written only when not the default.
    cell_size : float
        UV size of the lookup grid's cells (rounded up to a power of two); 0,
        the default, picks it from the scratch density.  Written only when set.
    footprint_filter : bool
        Average the BRDF over each camera sample's footprint (docs/model.md §11);
        ``footprint_angle`` (radians of a sample's cone) and ``footprint_width``
        (scene units, orthographic cameras) size it, 0 and 0 a point.  Written
        only when on.

    Needs an active Mitsuba variant (the tensors belong to it).
    """
    if scratches is not None and filename is not None:
        raise ValueError("give either scratches or filename, not both")
    if (eta is None) != (k is None):
        raise ValueError("eta and k go together")
    result = {"type": PLUGIN_NAME, "coherence_diameter": float(coherence_diameter),
              "unit_scale": float(unit_scale), "coherent": bool(coherent)}
    if depth_phase != DEFAULT_DEPTH_PHASE:
        result["depth_phase"] = str(depth_phase)
    if crossings != DEFAULT_CROSSINGS:
        result["crossings"] = str(crossings)
    if cell_size:
        result["cell_size"] = float(cell_size)
    if footprint_filter:
        result.update(footprint_filter=True, footprint_angle=float(footprint_angle),
                      footprint_width=float(footprint_width))
    if eta is not None:
        result["eta"], result["k"] = _spectrum(eta), _spectrum(k)
    else:
        result["material"] = str(material)
    if diffuse_reflectance is not None:
        result["diffuse_reflectance"] = _spectrum(diffuse_reflectance)
    if filename is not None:
        result["filename"] = str(filename)
    elif scratches is not None:
        result.update(scratch_parameters(scratches))
    return result


def load(scratches=None, **settings):
    """The ``scratch_diffraction`` BSDF itself, loaded for the active Mitsuba variant.

    ``mi.load_dict(plugin_dict(scratches, **settings))`` after registering the
    plugin for the variant: the one way code outside the bridge (the paper
    runner's load timing, scripts) makes a scratch BSDF without a scene.
    Parameters as :func:`plugin_dict`.
    """
    import mitsuba as mi

    register()
    return mi.load_dict(plugin_dict(scratches, **settings), parallel=False)  # (serial: builder.load_dict says why)


def scratch_parameters(scratches) -> dict:
    """Values to assign to a loaded BSDF's traversed parameters to swap its scratch set.

    Keys are relative to the BSDF (``scratch_uv`` ...); under ``mi.traverse(scene)``
    they carry the BSDF's prefix, e.g. ``plate.bsdf.scratch_uv``.  See
    :func:`update_scratches`.
    """
    from .tensors import to_tensors

    return to_tensors(scratches)


def update_scratches(params, scratches, prefix: str | None = None) -> None:
    """Swap the scratch set of a loaded scene's BSDF in place.

    The set is handed to the BSDF as it is (no copy, no second validation: a
    :class:`~..scratch.ScratchSet` is valid by construction); its tables are
    extended where the set only appends scratches (a pen stroke, :mod:`.tables.incremental`)
    and its traversed ``scratch_*`` parameters then hold the new set.  Assigning
    :func:`scratch_parameters` through ``params`` and ``params.update()`` does the
    same, at the cost of reading the set back from the tensors.

    Parameters
    ----------
    params : mi.SceneParameters
        From ``mi.traverse(scene)`` (or of the BSDF itself).
    scratches : ScratchSet
    prefix : str, optional
        The BSDF's key prefix (``"plate.bsdf."``); by default the one
        ``scratch_diffraction`` BSDF found in ``params`` (an error if there are several).
    """
    key = _FIRST_KEY
    if prefix is None:
        found = sorted(name[: -len(key)] for name in params.keys() if name.endswith(key))
        if len(found) != 1:
            raise ValueError(f"expected one {PLUGIN_NAME} BSDF in the parameters, found {len(found)}; "
                             "pass prefix=")
        prefix = found[0]
    if prefix + key not in params:
        raise KeyError(f"no {PLUGIN_NAME} BSDF under {prefix!r} in the parameters")
    bsdf = params.properties[prefix + key][2]  # the plugin object that traversed the key
    bsdf.set_scratch_set(scratches)


#: A traversed key every scratch BSDF has: finds the BSDFs in a scene's parameters.
_FIRST_KEY = "scratch_uv"


def _spectrum(value):
    if isinstance(value, dict):
        return value
    return {"type": "spectrum", "value": float(value)}
