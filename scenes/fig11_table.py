"""Fig. 6 (top middle) and Fig. 11 (a–d): the dining table of Fig. 1 with and without depth variation.

The same 300 000 scratches as Fig. 1 (``scenes/fig01_table.py`` builds them: the
same strokes, seeds and generator), once with constant depths and once with the
supplement's depth variation D[1.1, 0.04]: each scratch's depth follows a
simplex noise of about ten oscillations along it, down to zero in places
(amplitude 1.1).  The variation changes neither where the scratches lie nor
their mean depth, only how each one's glint is broken up along its length and
how its colour changes there (the depth phase).

Fig. 6 (top middle) is Fig. 1's view with variation; Fig. 11 compares the two
under two further lightings and views: (a, b) a low, close view across the
right-hand plate, the pendant lamp's reflection just beyond it; (c, d) looking
steeply down on the left-hand plate, the reflection among its wiping arcs.
"""
from __future__ import annotations

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "VARIATION", "VIEWS"]

#: D[1.1, 0.04]
VARIATION = (1.1, 0.04)
#: Camera, its target, lens (mm), where the lamp's reflection falls on the table, the lamp's height, exposure.
VIEWS = {
    "diner": None,  # Fig. 1's own (fig01_table's defaults)
    "close": dict(camera=(0.02, -0.42, 0.20), camera_target=(0.20, 0.02, 0.0), lens_mm=45.0,
                  lamp_reflection=(0.22, 0.0), lamp_height_m=0.55, exposure=-0.5),
    "above": dict(camera=(-0.30, -0.52, 0.78), camera_target=(-0.32, -0.08, 0.0), lens_mm=40.0,
                  lamp_reflection=(-0.25, -0.02), lamp_height_m=0.75, exposure=-1.0),
}

FIGURE = Figure(
    key="fig11_table", label="Fig. 6 (top middle), Fig. 11 (a–d)", title="Dining table: depth variation",
    paper="Fig. 6 (top middle) renders the Fig. 1 table with depth variation D[1.1, 0.04]; Fig. 11 compares the "
          "table without (a, c) and with (b, d) that variation under two lightings and views. With variation a "
          "scratch's glint breaks into dashes and changes colour along its length, so the sparkle looks finer "
          "and more natural; without it each lit scratch glows as one uniform line.",
    scratches="the Fig. 1 (middle) table's 300 000 scratches (same strokes, seeds and generator), U_D[0, 6] µm, "
              "U_W[0, 6] µm, rectangular, without and with D[1.1, 0.04]; aluminium top, coherence diameter 30 µm",
    design="diner: Fig. 1's view, pendant lamp and window (fig01_table), the scratches with variation: the rings of "
           "glints around the lamp's reflection break into dots and short dashes, fainter and sparser than Fig. 1 "
           "(middle)'s continuous arcs (part of that is noise: fewer samples per pixel here). close (a, b): the "
           "camera 16 cm above the table, 40 cm from the right-hand plate, looking across it with a 45 mm lens; the "
           "lamp's reflection is a long streak on the table just in front of the plate, and the glints around it are"
           " long arcs of single scratches, brightest in a coloured fan where the wiping arcs pass the plate's edge;"
           " the window's reflection fills the left half, where the glints are lost. above (c, d): looking steeply "
           "down (about 60°) from 80 cm on the left-hand plate: the lamp's round reflection beside it, concentric "
           "rings of glints, and three pale gold-white patches where the wiping arcs' aligned scratches light up "
           "together. At the page's size the pictures with and without variation look alike (mean within 0.1 %); "
           "enlarged, the glints without variation are streaks of one colour, those with it change colour along "
           "their length and break into shorter, sparser dashes (the paper's point, which its 4 MP pictures show "
           "better).",
    renders=(
        Render("diner-variation", "Fig. 6 (top middle): Fig. 1's view, the scratches with D[1.1, 0.04]",
               {"view": "diner", "variation": True}, resolution=(960, 600), samples=64, paper_minutes=120),
        Render("close", "Fig. 11 (a): close and low, constant depth", {"view": "close", "variation": False},
               resolution=(960, 600), samples=64, paper_minutes=266),
        Render("close-variation", "Fig. 11 (b): close and low, D[1.1, 0.04]", {"view": "close", "variation": True},
               resolution=(960, 600), samples=64, paper_minutes=284),
        Render("above", "Fig. 11 (c): from above, constant depth", {"view": "above", "variation": False},
               resolution=(800, 600), samples=64, paper_minutes=167),
        Render("above-variation", "Fig. 11 (d): from above, D[1.1, 0.04]", {"view": "above", "variation": True},
               resolution=(800, 600), samples=64, paper_minutes=168),
    ),
)


def build_scene(scene, *, view: str = "diner", variation: bool = True, resolution=(960, 600), samples: int = 256,
                scale: float = 1.0):
    """The Fig. 1 table seen and lit as ``view`` says (a key of ``VIEWS``), with or without D[1.1, 0.04];
    returns the table top. ``scale`` < 1 scratches less (tests)."""
    from . import fig01_table

    if view not in VIEWS:
        raise ValueError(f"view must be one of {sorted(VIEWS)}, not {view!r}")
    return fig01_table.build_scene(scene, resolution=resolution, samples=samples, scale=scale,
                                   depth_variation=VARIATION if variation else (0.0, 0.0), **(VIEWS[view] or {}))
