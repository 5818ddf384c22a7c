"""Bridge fixtures: the LLVM spectral variant (the CI machine has no GPU) and small scenes built in code."""
import pytest

mi = pytest.importorskip("mitsuba")


@pytest.fixture(scope="session")
def variant():
    """``llvm_ad_spectral`` with the project's plugins registered."""
    from scratch_iridescence.mitsuba_bridge import variants

    return variants.activate("llvm_ad_spectral")

