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


@pytest.fixture
def farm_cgroup(tmp_path, monkeypatch):
    """``limit(max_mib, current_mib)``: this process in a cgroup v2 group ``/farm/worker`` (a farm worker's
    container) with that ``memory.max`` and ``memory.current``, laid out as ``/proc/self/cgroup`` and
    ``/sys/fs/cgroup`` are, and read by the memory guard (mitsuba_bridge/device/memory.py) instead of the real ones."""
    from scratch_iridescence.mitsuba_bridge.device import memory

    def limit(max_mib: int, current_mib: int) -> None:
        (tmp_path / "proc" / "self").mkdir(parents=True, exist_ok=True)
        (tmp_path / "proc" / "self" / "cgroup").write_text("0::/farm/worker\n")
        group = tmp_path / "cgroup" / "farm" / "worker"
        group.mkdir(parents=True, exist_ok=True)
        (group / "memory.max").write_text(f"{max_mib * 2 ** 20}\n")
        (group / "memory.current").write_text(f"{current_mib * 2 ** 20}\n")
        monkeypatch.setattr(memory, "_PROC", tmp_path / "proc")
        monkeypatch.setattr(memory, "_CGROUP_ROOT", tmp_path / "cgroup")

    return limit
