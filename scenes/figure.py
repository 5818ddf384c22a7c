"""What a paper scene reproduces: the figure, its parameters, and each render's settings (no bpy).

Every figure module (``fig01_table`` ... ``fig17_profile``) declares one
:class:`Figure`; :mod:`.paper` renders its :class:`Render` entries and writes
the gallery and the benchmark table from these records.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Figure", "Render", "PAPER_SPP", "PAPER_CORES", "PAPER_WAVELENGTHS", "OUR_WAVELENGTHS",
           "paper_samples_per_core_second"]

#: The supplement's render settings: 4 MP at 16 384 samples per pixel on 72 cores, unless noted.
PAPER_SPP = 16384
PAPER_CORES = 72
#: Wavelengths per sample: the supplement's N_λ (16 unless noted: 3 for Fig. 12), and ours (hero wavelength
#: sampling traces 4 per path, docs/model.md §6).
PAPER_WAVELENGTHS = 16
OUR_WAVELENGTHS = 4


def paper_samples_per_core_second(megapixels: float, minutes: float) -> float:
    """Samples per core-second implied by one of the supplement's render times."""
    return megapixels * 1e6 * PAPER_SPP / (minutes * 60.0 * PAPER_CORES)


@dataclass(frozen=True)
class Render:
    """One picture: ``build_scene`` keyword arguments and the settings ``make paper`` renders it with.

    ``paper_minutes``, ``paper_megapixels`` and ``paper_wavelengths`` are the
    supplement's time, resolution and N_λ for the picture this one reproduces.
    """

    name: str
    caption: str
    options: dict = field(default_factory=dict)
    resolution: tuple[int, int] = (640, 400)
    samples: int = 256
    paper_minutes: float = 0.0
    paper_megapixels: float = 4.0
    paper_wavelengths: int = PAPER_WAVELENGTHS

    @property
    def paper_samples_per_core_second(self) -> float | None:
        """The paper's rate for this picture; ``None`` for a render beyond the paper (no time given)."""
        if not self.paper_minutes:
            return None
        return paper_samples_per_core_second(self.paper_megapixels, self.paper_minutes)

    @property
    def wavelength_factor(self) -> float:
        """Our wavelengths per sample over the paper's: a samples-per-core-second ratio times this compares
        wavelength samples (1/4 for the paper's 16, 4/3 for Fig. 12's 3)."""
        return OUR_WAVELENGTHS / self.paper_wavelengths


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
