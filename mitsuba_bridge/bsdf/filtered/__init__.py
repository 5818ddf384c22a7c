"""The scratch BSDF averaged over the footprint of one camera sample (docs/model.md §11).

Pure Dr.Jit functions, µm inside: the footprint (:mod:`.footprint`), the Gauss–Hermite nodes of
localised point values (:mod:`.nodes`), the along factor (:mod:`.along`) and one segment's
footprint-averaged intensity (:mod:`.single`).
"""
