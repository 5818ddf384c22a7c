"""What a worker must share with the driver so that its chunks merge bit for bit: the same software.

A chunk rendered by other code (another release of this package, an edited
checkout, another Mitsuba or Dr.Jit) may give other bits, and the merge of
a split render would then be an image no single machine renders.  So every
worker's :func:`software_identity` must equal the driver's before anything is
sent; a worker without the package cannot even run the check, and is refused
by name too (:mod:`.driver`).
"""
from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["SoftwareIdentity", "software_identity", "DISTRIBUTION"]

#: The name pip installs the package under.
DISTRIBUTION = "scratch-iridescence"
_BRIDGE = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class SoftwareIdentity:
    """The package's version and a digest of the bridge's source, and the Mitsuba and Dr.Jit versions."""

    version: str
    source: str  #: SHA-256 (first 16 hex digits) of every ``.py`` file of the bridge, names and bytes
    mitsuba: str
    drjit: str

    def differences(self, other: "SoftwareIdentity") -> list[str]:
        """``['mitsuba 3.9.1 vs 3.9.0', ...]``: the fields where ``other`` differs from this one."""
        return [f"{name} {getattr(other, name)} vs {getattr(self, name)}"
                for name in self.__dataclass_fields__ if getattr(self, name) != getattr(other, name)]

    def __str__(self) -> str:
        return f"{DISTRIBUTION} {self.version} (source {self.source}), mitsuba {self.mitsuba}, drjit {self.drjit}"


@functools.lru_cache(maxsize=1)
def _source_digest() -> str:
    digest = hashlib.sha256()
    for path in sorted(_BRIDGE.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        digest.update(path.relative_to(_BRIDGE).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def software_identity() -> SoftwareIdentity:
    """This process's :class:`SoftwareIdentity` (Mitsuba and Dr.Jit are imported, not initialised)."""
    import drjit
    import mitsuba

    from .. import __version__

    return SoftwareIdentity(__version__, _source_digest(), mitsuba.__version__, drjit.__version__)
