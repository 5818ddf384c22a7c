"""What a paper scene reproduces: the figure, its parameters, and each render's settings (no bpy).

Every figure module (``fig01_table`` ... ``fig17_profile``) declares one
:class:`Figure`; :mod:`.paper` renders its :class:`Render` entries and writes
the gallery and the benchmark table from these records.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Figure", "Render", "PAPER_SPP", "PAPER_CORES", "paper_samples_per_core_second"]

#: The supplement's render settings: 4 MP at 16 384 samples per pixel on 72 cores, unless noted.
PAPER_SPP = 16384
PAPER_CORES = 72


def paper_samples_per_core_second(megapixels: float, minutes: float) -> float:
    """Samples per core-second implied by one of the supplement's render times."""
    return megapixels * 1e6 * PAPER_SPP / (minutes * 60.0 * PAPER_CORES)


@dataclass(frozen=True)
class Render:
    """One picture: ``build_scene`` keyword arguments and the settings ``make paper`` renders it with.

    ``paper_minutes`` and ``paper_megapixels`` are the supplement's time and
    resolution for the picture this one reproduces.
    """

    name: str
    caption: str
    options: dict = field(default_factory=dict)
    resolution: tuple[int, int] = (640, 400)
    samples: int = 256
    paper_minutes: float = 0.0
    paper_megapixels: float = 4.0

    @property
    def paper_samples_per_core_second(self) -> float | None:
        """The paper's rate for this picture; ``None`` for a render beyond the paper (no time given)."""
        if not self.paper_minutes:
            return None
        return paper_samples_per_core_second(self.paper_megapixels, self.paper_minutes)


@dataclass(frozen=True)
class Figure:
    """A figure of the paper (or its supplement) and the renders that reproduce it."""

    key: str
    label: str             # "Fig. 7(b)"
    title: str             # "Scratched plate"
    paper: str             # what the paper's figure shows (we do not have its pictures)
    scratches: str         # count and parameters in the supplement's notation
    design: str            # how the scene shows the effect: light, camera, why
    renders: tuple[Render, ...]
    module: str = ""       # the module whose build_scene builds it (filled in by the catalogue)
