"""The ``scratch_diffraction`` Mitsuba plugin (thin class over :mod:`.model`).

``mi.BSDF`` is the class of the active variant, so the plugin class is built
per variant by :func:`plugin_class` after ``mi.set_variant``.
"""
from __future__ import annotations

import time

import drjit as dr
import mitsuba as mi

from .. import scratch
from . import handoff, parameters, persistent, tensors
from .fresnel import ConductorSpectra, material_textures
from .filtered.model import FilteredModel
from .filtered.single import NARROW_ACROSS_SIGMAS
from .lookup import Grid
from .model import Model
from .tables import disk_cache, grid
from .tables.density import density_table
from .tables.incremental import update_tables
from .tables.lines import line_continuation
from .tables.references import aligned_array
from .tables.scan import ScanArrays

__all__ = ["plugin_class", "MANUAL"]

MANUAL = """Wave-optical scratch BSDF (``scratch_diffraction``)

Werner et al., "Scratch iridescence" (SIGGRAPH Asia 2017): a metal (or perfect
mirror) carrying microscopic straight scratches, rendered with scalar
diffraction inside a Gaussian coherence window around each shading point.

.. list-table::
   * - Parameter
     - Type
     - Description
   * - filename
     - string
     - Scratch file, format v1 (docs/scratch-format.md).  Alternatively the
       eight in-memory keys below; neither gives an unscratched surface.
   * - scratch_uv, scratch_offsets, scratch_width, scratch_depth,
       scratch_profile, scratch_width_variation, scratch_depth_variation,
       scratch_seed
     - tensors
     - The format-v1 arrays in memory (TensorXf64, TensorXi64, TensorXf64,
       TensorXf64, TensorXu8, TensorXf64, TensorXf64, TensorXu);
       ``mitsuba_bridge.bsdf.plugin_dict`` builds them.  Exposed by
       ``mi.traverse`` under the same names: assigning all eight and calling
       ``params.update()`` swaps the scratch set without reloading the scene.
   * - coherence_diameter
     - float
     - Coherence diameter δ_c in metres (σ = δ_c / 6).  Default 30e-6
       (σ = 5 µm, a mirror lobe of ≈ 0.7° at 550 nm, like the sun's disc).
       Traversable.
   * - unit_scale
     - float
     - Metres per scene unit (default 1).  Scratch positions are UV
       coordinates; the shading point's dp/du, dp/dv times unit_scale map
       them to metres.  Traversable.
   * - material
     - string
     - Base conductor, any name of Mitsuba's ``conductor`` plugin (Al, Ag, Au,
       Cu, Cr, ...), or ``none`` for a perfect mirror (F = 1).  Default Al.
   * - eta, k
     - spectrum or texture
     - Explicit complex index of refraction instead of ``material``.
   * - diffuse_reflectance
     - spectrum or texture
     - Optional Lambertian base ρ_d added incoherently (default: none).  It is
       not energy-coupled to the metal: keep ρ_d <= 1 - F for conservation.
   * - coherent
     - boolean
     - Coherent (default) or incoherent superposition of the scratches
       (incoherent: no interference between scratches, no grating orders).
   * - cell_size
     - float
     - UV size of the lookup grid's cells; 0 (default) picks it from the
       scratch density.  A hint for very dense or very sparse sets only.
   * - crossings
     - string
     - ``additive`` (default, the paper: overlapping scratches add their
       transfer functions, so a crossing counts both depths) or
       ``height_field`` (where scratches cross, the overlap takes the
       deepest one's depth, as on a real surface: one analytic
       parallelogram correction per crossing pair in the window, V-grooves
       included, plus the inclusion-exclusion terms of overlaps of three to
       five flat-bottomed scratches (also where two of them are nearly
       parallel and another crosses them), and the overlaps of nearly
       parallel or parallel scratches (duplicates included) found in the
       window;
       eval several times slower on a crossed plate (docs/bsdf.md);
       coherent mode only; docs/model.md §3.4).
   * - depth_phase
     - string
     - ``kirchhoff`` (default, the paper's depth phase 2π(γ_i + γ_o)d/λ,
       reciprocal, deep grooves may reflect more than they receive) or
       ``incidence`` (4πγ_i d/λ, a phase screen fixed by the incident
       direction: conserves energy for any depth, but is not reciprocal and
       departs from the Kirchhoff field off the mirror direction) or
       ``bounded`` (the Kirchhoff BRDF divided by max(1, Â(ω_i), Â(ω_o)),
       Â the directional albedo estimated per scratch segment: reciprocal,
       albedo ≤ 1 for any depth, unchanged for shallow scratches; eval
       costs tens of times more per segment in the window; coherent mode
       only, docs/bsdf.md).

The model.  Each evaluation is one coherence window w = exp(-|x - x0|²/2σ²) at
the shading point x0.  The reflected far field is the mirror lobe of the
window plus, for every straight scratch segment within 4σ, its transform:
the window integrated along the segment between its ends and across its
rectangular or V-shaped cross-section, both exactly (complex error functions
through the Faddeeva function; the window's curvature across wide or offset
scratches included, which the complex-frequency form of docs/model.md §3.3 only linearises),
depth and width following the file's simplex noise.  f_r = F |U|² / (λ² π σ²),
F the spectral conductor Fresnel at the half vector; coherent mode adds the
amplitudes (interference, grating orders), incoherent mode the intensities.
Without scratches in the window the BSDF is the window's Gaussian mirror lobe
(angular standard deviation λ / (2√2 π σ), 0.7° at 550 nm by default) times F:
a glossy lobe, never a delta, so scratched and unscratched points are one
BSDF; its albedo is F.  Energy: light only moves between directions for
shallow scratches; the depth phase 2π(γ_i + γ_o)d/λ depends on the outgoing
direction, so deep grooves can reflect a few percent more than they receive
(the scalar model itself, not this implementation: docs/bsdf.md);
depth_phase="incidence" fixes the screen by the incident direction and
conserves energy for any depth, at the price of reciprocity;
depth_phase="bounded" keeps the Kirchhoff phase and reciprocity and divides
by the estimated albedo where it exceeds 1, at the price of speed.  Scratch
crossings add their transfer functions (the paper's limitation) unless
crossings="height_field" gives each overlap the deepest depth.  Scratches
are UV polylines (mesh UVs required); phases are formed relative to x0, so
float32 suffices at any object size.  Renders need an unpolarised spectral JIT
variant (llvm_ad_spectral, cuda_ad_spectral, metal_ad_spectral): diffraction colours do not exist
in RGB.  Sampling: mirror lobe, scratch lines (segment drawn in proportion to
its diffracted energy) and the diffuse base, combined with the balance
heuristic; pdf and weights use the first (hero) wavelength.  The set's lookup
tables are built when the plugin loads, shared with other live scenes and kept
on disk for later processes (docs/rendering.md, Scratch tables on disk).

.. code-block:: python

    import mitsuba as mi, mitsuba_bridge
    mi.set_variant("llvm_ad_spectral")
    mitsuba_bridge.register_plugins()
    bsdf = mi.load_dict({"type": "scratch_diffraction", "filename": "plate.npz",
                         "coherence_diameter": 30e-6, "unit_scale": 0.01, "material": "Al"})
    # or, without a file: mi.load_dict(mitsuba_bridge.bsdf.plugin_dict(scratch_set))
"""

_classes: dict[str, type] = {}


def plugin_class() -> type:
    """The plugin class for the active variant (created once per variant)."""
    variant = mi.variant()
    if variant not in _classes:
        _classes[variant] = _make_class()
    return _classes[variant]


def _check_variant() -> None:
    variant = mi.variant()
    if not mi.is_spectral or mi.is_polarized or variant.startswith("scalar"):
        raise ValueError(
            f"the active Mitsuba variant is '{variant}', but diffraction colours need an unpolarised "
            "spectral JIT variant: call mi.set_variant('llvm_ad_spectral') (CPU), "
            "mi.set_variant('cuda_ad_spectral') (NVIDIA GPU) or mi.set_variant('metal_ad_spectral') (Apple GPU) "
            "before loading the scene")


def _read_scratches(props):
    """The scratch set named by the properties (file or in-memory keys), validated."""
    in_memory = [key for key in tensors.KEYS if key in props]
    filename = props.get("filename", "")
    if filename and in_memory:
        raise ValueError("give either 'filename' or the in-memory keys scratch_*, not both")
    if filename:
        path = str(mi.file_resolver().resolve(filename))
        try:
            return scratch.load(path)
        except FileNotFoundError:
            raise ValueError(f"parameter 'filename': scratch file '{path}' does not exist") from None
        except OSError as error:
            raise ValueError(f"parameter 'filename': cannot read scratch file '{path}': {error}") from None
    if in_memory:
        return tensors.from_values({key: props[key] for key in in_memory})
    return scratch.ScratchSet.empty()


def _positive(props, name, default):
    value = float(props.get(name, default))
    if not value > 0.0 or value == float("inf"):
        raise ValueError(f"parameter '{name}' must be a positive length in metres, got {value!r}")
    return value


def _non_negative(props, name):
    value = float(props.get(name, 0.0))
    if not value >= 0.0 or value == float("inf"):
        raise ValueError(f"parameter '{name}' must be a finite value >= 0, got {value!r}")
    return value


def _make_class() -> type:
    class ScratchDiffraction(mi.BSDF):
        __doc__ = MANUAL

        def __init__(self, props):
            _check_variant()
            mi.BSDF.__init__(self, props)
            try:
                self._configure(props)
            except ValueError as error:  # ScratchFormatError included: it names file and field
                raise ValueError(f"{parameters.PLUGIN_NAME}: {error}") from error

        def _configure(self, props):
            self.coherence_diameter = dr.opaque(mi.Float, _positive(
                props, "coherence_diameter", parameters.DEFAULT_COHERENCE_DIAMETER_M))
            self.unit_scale = dr.opaque(mi.Float, _positive(props, "unit_scale", 1.0))
            self.cell_size = float(props.get("cell_size", 0.0))
            self.coherent = bool(props.get("coherent", True))
            self.depth_phase = str(props.get("depth_phase", parameters.DEFAULT_DEPTH_PHASE))
            if self.depth_phase not in parameters.DEPTH_PHASES:
                raise ValueError(f"parameter 'depth_phase' must be one of {', '.join(parameters.DEPTH_PHASES)}, "
                                 f"got {self.depth_phase!r}")
            # the footprint filter (docs/model.md §11): compiled only where asked for; the renderer sets the
            # sample's cone (footprint_angle, radians) and orthographic width (footprint_width, scene units)
            self.footprint_filter = bool(props.get("footprint_filter", False))
            self.footprint_angle = dr.opaque(mi.Float, _non_negative(props, "footprint_angle"))
            self.footprint_width = dr.opaque(mi.Float, _non_negative(props, "footprint_width"))
            self.crossings = str(props.get("crossings", parameters.DEFAULT_CROSSINGS))
            if self.crossings not in parameters.CROSSINGS:
                raise ValueError(f"parameter 'crossings' must be one of {', '.join(parameters.CROSSINGS)}, "
                                 f"got {self.crossings!r}")

            has_eta, has_k = "eta" in props, "k" in props
            if has_eta != has_k:
                raise ValueError("parameters 'eta' and 'k' go together")
            if has_eta and "material" in props:
                raise ValueError("give either 'material' or 'eta' and 'k', not both")
            if has_eta:
                self.eta, self.k = props.get_texture("eta"), props.get_texture("k")
                self.material = "custom"
            else:
                self.material = str(props.get("material", parameters.DEFAULT_MATERIAL))
                self.eta, self.k = (None, None) if self.material.lower() == "none" \
                    else material_textures(self.material)
            self.diffuse = props.get_texture("diffuse_reflectance") if "diffuse_reflectance" in props else None

            glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [glossy] + ([diffuse] if self.diffuse is not None else [])
            self.m_flags = glossy | (diffuse if self.diffuse is not None else 0)

            scratches = _read_scratches(props)
            self.scratch_values = tensors.to_tensors(scratches)
            self._set_scratches(scratches)

        def _set_scratches(self, scratches):
            # the grooves' runs past their pieces: the incoherent sums and the height field's crossings use them
            periodic = Model.sums_families(self.coherent, self.depth_phase)
            continuation = not self.coherent or self._height_field
            previous = getattr(self, "table_cache", None)

            def build(key=None):
                # a new BSDF's set (``key``) may have been built by an earlier process (.disk_cache)
                found = disk_cache.load_tables(key, scratches, repr(options)) if key is not None else None
                if found is not None:
                    cache, scan, _ = found
                else:
                    began = time.perf_counter()
                    # a set that only appends scratches (a stroke) extends the previous tables (.incremental)
                    cache = update_tables(previous, scratches, self.cell_size, crossings=self._height_field)
                    scan = ScanArrays.of(cache.tables, periodic)
                    if key is not None and time.perf_counter() - began >= disk_cache.MIN_BUILD_SECONDS:
                        disk_cache.store_tables(key, cache, scan, repr(options))
                return cache, Grid.from_arrays(cache.tables, scan, continuation=continuation)

            options = (self.cell_size, self._height_field, periodic, continuation, grid.build_constants())
            if previous is None:  # a new BSDF: another live scene or Persistent Data may hold its tables
                self.shared_tables = persistent.reuse_or_build(scratches, options, build)
            else:  # an edited set: entered for later scenes (F12 after painting in the viewport)
                self.shared_tables = persistent.share(scratches, options, build())
            self.table_cache, self.grid = self.shared_tables.value
            self.tables = self.table_cache.tables
            self.scratch_count = scratches.count
            # the filter's runs (every piece of a straight line, whatever its depth): built with the tables' rows
            self.line_runs = aligned_array(mi.Float, line_continuation(self.tables).ravel()) \
                if self.footprint_filter else None
            # the cells' piece densities that cap a footprint's reach in dense regions (docs/model.md §11.8)
            self.piece_density = aligned_array(mi.Float, density_table(self.tables).ravel()) \
                if self.footprint_filter else None
            self._rebuild_model()

        @property
        def _height_field(self):
            return self.crossings == "height_field" and self.coherent

        def _rebuild_model(self):
            sigma = dr.opaque(mi.Float, dr.slice(self.coherence_diameter) * (1e6 / 6.0))
            scale = dr.opaque(mi.Float, dr.slice(self.unit_scale) * 1e6)
            # (rebuilt here: a parameter update may have changed the spectra's values)
            spectra = ConductorSpectra.of(self.eta, self.k) \
                if self.eta is not None and ConductorSpectra.matches(self.eta, self.k) else None
            common = dict(grid=self.grid, sigma=sigma, micrometres_per_unit=scale, coherent=self.coherent,
                          eta=self.eta, k=self.k, spectra=spectra, diffuse=self.diffuse, depth_phase=self.depth_phase,
                          height_field=self._height_field)
            if self.footprint_filter:
                # (a Python choice: two nodes across where every groove is at most 1.2σ wide, docs/model.md §11.3)
                widest = float(self.tables.segments[:self.tables.piece_count, 6].max(initial=0.0))
                narrow = widest <= NARROW_ACROSS_SIGMAS * dr.slice(sigma)
                self.model = FilteredModel(**common, footprint_angle=self.footprint_angle,
                                           footprint_width=self.footprint_width, line_continuation=self.line_runs,
                                           piece_density=self.piece_density,
                                           across_nodes=2 if narrow else 3)
            else:
                self.model = Model(**common)

        # ------------------------------------------------------ interface
        def _lobes(self, ctx):
            return (ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 0),
                    self.diffuse is not None and ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1))

        def eval(self, ctx, si, wo, active=True):
            glossy, diffuse = self._lobes(ctx)
            return self.model.evaluate(si, wo, has_glossy=glossy, has_diffuse=diffuse,
                                       want_pdf=False, active=active)[0]

        def pdf(self, ctx, si, wo, active=True):
            glossy, diffuse = self._lobes(ctx)
            return self.model.evaluate(si, wo, has_glossy=glossy, has_diffuse=diffuse,
                                       want_value=False, active=active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            glossy, diffuse = self._lobes(ctx)
            if not handoff.traced():  # evaluated calls: the search's arrays would stay held for every lane
                handoff.clear()
                return self.model.evaluate(si, wo, has_glossy=glossy, has_diffuse=diffuse, active=active)
            # (a path tracer samples at the same point next: the window's search is left for that call)
            value, pdf, search = self.model.evaluate(si, wo, has_glossy=glossy, has_diffuse=diffuse, active=active,
                                                     keep_search=True)
            handoff.leave(self, si, active, (glossy, diffuse), search)
            return value, pdf

        def sample(self, ctx, si, sample1, sample2, active=True):
            glossy, diffuse = self._lobes(ctx)
            wo, pdf, value, chose_diffuse = self.model.sample(
                si, sample1, sample2, has_glossy=glossy, has_diffuse=diffuse, active=active,
                search=handoff.take(self, si, active, (glossy, diffuse)))
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = pdf
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(dr.select(chose_diffuse, +mi.BSDFFlags.DiffuseReflection,
                                                  +mi.BSDFFlags.GlossyReflection))
            bs.sampled_component = mi.UInt32(dr.select(chose_diffuse, 1, 0))
            weight = dr.select(pdf > 0.0, value / dr.maximum(pdf, 1e-30), 0.0)
            return bs, dr.select(dr.isfinite(weight), weight, 0.0)

        # -------------------------------------------------- parameters
        def traverse(self, callback):
            flags = mi.ParamFlags.NonDifferentiable
            for key, value in self.scratch_values.items():
                callback.put(key, value, flags)
            callback.put("coherence_diameter", self.coherence_diameter, flags)
            callback.put("unit_scale", self.unit_scale, flags)
            callback.put("footprint_angle", self.footprint_angle, flags)
            callback.put("footprint_width", self.footprint_width, flags)
            for name, texture in (("eta", self.eta), ("k", self.k), ("diffuse_reflectance", self.diffuse)):
                if texture is not None:
                    callback.put(name, texture, mi.ParamFlags.Differentiable)

        def set_scratch_set(self, scratches):
            """Swap the scratch set for ``scratches`` (:func:`..update_scratches`): the tables are updated
            (extended where the set only appends) and the traversed ``scratch_*`` tensors point at its arrays."""
            if not isinstance(scratches, scratch.ScratchSet):
                raise TypeError(f"expected a ScratchSet, got {type(scratches).__name__}")
            for key, value in tensors.to_tensors(scratches).items():
                mi.set_property(self.scratch_values[key], value)  # in place: mi.traverse holds these objects
            self._set_scratches(scratches)

        def parameters_changed(self, keys):
            keys = set(keys)
            if not keys or keys & set(tensors.KEYS):
                try:
                    scratches = tensors.from_values(self.scratch_values)
                except scratch.ScratchFormatError as error:
                    raise ValueError(f"{parameters.PLUGIN_NAME}: {error}") from error
                self._set_scratches(scratches)
            else:
                self._rebuild_model()

        def to_string(self):
            t = self.tables
            return (f"ScratchDiffraction[scratches={self.scratch_count}, pieces={t.piece_count}, "
                    f"grid={t.shape[0]}x{t.shape[1]} cells of {t.cell_size:.3g} UV, "
                    f"coherence_diameter={dr.slice(self.coherence_diameter):.3g} m, "
                    f"unit_scale={dr.slice(self.unit_scale):.3g} m, material={self.material}, "
                    f"diffuse={'yes' if self.diffuse is not None else 'no'}, "
                    f"{'coherent' if self.coherent else 'incoherent'}, depth_phase={self.depth_phase}, "
                    f"crossings={self.crossings} ({t.crossing_count} pairs), "
                    f"periodic families={self.grid.family_count}, kinks={self.grid.kink_count}, "
                    f"footprint filter={'on' if self.footprint_filter else 'off'}]")

    ScratchDiffraction.__name__ = "ScratchDiffraction"
    return ScratchDiffraction
