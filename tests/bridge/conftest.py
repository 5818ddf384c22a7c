"""Bridge fixtures: the LLVM spectral variant (the CI machine has no GPU) and small scenes built in code.

``SCRATCH_TEST_VARIANT=cuda_ad_spectral`` runs them on an NVIDIA GPU instead (docs/bsdf.md, GPU), as
for ``tests/bridge/bsdf``.
"""
import os

import pytest

mi = pytest.importorskip("mitsuba")

VARIANT = os.environ.get("SCRATCH_TEST_VARIANT", "llvm_ad_spectral")


@pytest.fixture(scope="session")
def variant():
    """The test variant (``llvm_ad_spectral`` unless told otherwise) with the project's plugins registered."""
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    return activate(VARIANT)
