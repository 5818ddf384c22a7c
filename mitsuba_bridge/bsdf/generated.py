"""``generated``: a texture looked up in Blender's Generated coordinates instead of the UV map.

Blender's procedural textures read *Generated* coordinates when nothing is connected to their Vector
input: the object's texture space (by default the bounding box of its undeformed mesh) mapped to
[0, 1]³. Mitsuba's textures read the UV map, so the builder stores the coordinates as a mesh attribute
(``vertex_generated``, three floats per vertex) and this small texture reads them.

.. list-table::
   :header-rows: 1

   * - parameter
     - type
     - meaning
   * - ``mode``
     - string
     - ``"checker"``: Cycles' 3D checker (``svm_checker``) of cubes of side 1/``scale``;
       ``"flat"``: ``texture`` looked up at the (x, y) of the coordinates (Blender's Flat projection)
   * - ``color0``, ``color1``
     - spectrum or texture
     - the checker's colours: ``color0`` where the cube indices' parities say Cycles' *Color2*
   * - ``scale``
     - float
     - checker cubes per coordinate unit (default 5)
   * - ``texture``
     - texture
     - what ``"flat"`` looks up (a ``bitmap``)
   * - ``attribute``
     - string
     - the mesh attribute holding the coordinates (default ``vertex_generated``)

Every mesh wearing a material with this texture carries the attribute (gather adds it to exactly
those meshes). Example::

    {"type": "generated", "mode": "checker", "scale": 5.0,
     "color0": {"type": "rgb", "value": [0.2, 0.2, 0.2]}, "color1": {"type": "rgb", "value": [0.8, 0.8, 0.8]}}
"""
from __future__ import annotations

__all__ = ["PLUGIN_NAME", "ATTRIBUTE", "register", "plugin_class"]

PLUGIN_NAME = "generated"
ATTRIBUTE = "vertex_generated"
_CLASSES: dict = {}
#: Cycles nudges coordinates off integers before the checker's floor ("avoid precision issues on unit
#: coordinates"): the faces of a unit texture space then fall in well-defined cubes.
_NUDGE, _SHRINK = 1e-6, 0.999999


def plugin_class():
    """The ``mi.Texture`` subclass for the active variant (built once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _CLASSES:
        return _CLASSES[variant]

    class Generated(mi.Texture):
        def __init__(self, props):
            super().__init__(props)
            self.mode = props.get("mode", "checker")
            if self.mode not in ("checker", "flat"):
                raise ValueError(f"generated: unknown mode {self.mode!r} (checker or flat)")
            self.attribute = props.get("attribute", ATTRIBUTE)
            if self.mode == "checker":
                self.scale = float(props.get("scale", 5.0))
                self.color0 = props.get_texture("color0")
                self.color1 = props.get_texture("color1")
            else:
                self.texture = props.get_texture("texture")

        def _coordinates(self, si, active):
            return si.shape.eval_attribute_3(self.attribute, si, active)

        def _checker(self, si, active):
            """True where Cycles' checker gives its Color1 (our ``color1``)."""
            p = (mi.Vector3f(self._coordinates(si, active)) * self.scale + _NUDGE) * _SHRINK
            parity = [mi.Int32(dr.abs(dr.floor(c))) % 2 for c in (p.x, p.y, p.z)]
            return (parity[0] == parity[1]) == (parity[2] == 1)

        def _flat(self, si, active):
            g = self._coordinates(si, active)
            moved = mi.SurfaceInteraction3f(si)
            moved.uv = mi.Point2f(g.x, g.y)
            return moved

        def eval(self, si, active=True):
            if self.mode == "flat":
                return self.texture.eval(self._flat(si, active), active)
            return dr.select(self._checker(si, active), self.color1.eval(si, active), self.color0.eval(si, active))

        def eval_1(self, si, active=True):
            if self.mode == "flat":
                return self.texture.eval_1(self._flat(si, active), active)
            return dr.select(self._checker(si, active), self.color1.eval_1(si, active),
                             self.color0.eval_1(si, active))

        def eval_3(self, si, active=True):
            if self.mode == "flat":
                return self.texture.eval_3(self._flat(si, active), active)
            return dr.select(self._checker(si, active), self.color1.eval_3(si, active),
                             self.color0.eval_3(si, active))

        def mean(self):
            if self.mode == "flat":
                return self.texture.mean()
            return 0.5 * (self.color0.mean() + self.color1.mean())

        def max(self):
            if self.mode == "flat":
                return self.texture.max()
            return dr.maximum(self.color0.max(), self.color1.max())

        def is_spatially_varying(self):
            return True

        def traverse(self, callback):
            if self.mode == "flat":
                callback.put("texture", self.texture, mi.ParamFlags.NonDifferentiable)
            else:
                callback.put("color0", self.color0, mi.ParamFlags.NonDifferentiable)
                callback.put("color1", self.color1, mi.ParamFlags.NonDifferentiable)

        def to_string(self):
            return f"Generated[mode={self.mode}]"

    _CLASSES[variant] = Generated
    return Generated


def register() -> None:
    """Register ``generated`` for the active variant (call after ``mi.set_variant``)."""
    import mitsuba as mi

    mi.register_texture(PLUGIN_NAME, lambda props: plugin_class()(props))
