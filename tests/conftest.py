"""Suite-wide settings and fixtures.

Every random test input is reproducible: Hypothesis draws its examples at random
unless told otherwise, so a property test could pass on one run and fail on the
next (and its example database would make the outcome depend on earlier runs).
The ``deterministic`` profile, loaded by default, derives every example from the
test itself and keeps no database.  Set ``HYPOTHESIS_PROFILE=explore`` to search
new examples (failures print a ``@reproduce_failure`` blob to pin them down).

The real libLLVM 15, where installed, serves the LLVM-15 simulations.

The scratch tables' disk cache (``mitsuba_bridge/bsdf/tables/disk_cache.py``) is a fresh
folder per run, inherited by the tests' subprocesses: a run never reads what an
earlier one wrote, nor writes into the user's cache.
"""
from __future__ import annotations

import atexit
import glob
import os
import shutil
import tempfile

import pytest
from hypothesis import settings

settings.register_profile("deterministic", derandomize=True, database=None, print_blob=True)
settings.register_profile("explore", derandomize=False, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))
_TABLES_CACHE = tempfile.mkdtemp(prefix="scratch-tables-cache-")
os.environ["SCRATCH_IRIDESCENCE_CACHE_DIR"] = _TABLES_CACHE
atexit.register(shutil.rmtree, _TABLES_CACHE, ignore_errors=True)
#: Where Debian's ``libllvm15`` (or llvm.org's packages) put libLLVM 15.
LLVM15_PATTERNS = ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so*", "/usr/lib/llvm-15/lib/libLLVM-15.so*")


@pytest.fixture(scope="session")
def llvm15_or_none() -> str | None:
    """Path of a real libLLVM 15 on this machine, or None."""
    return next(iter(sorted(path for pattern in LLVM15_PATTERNS for path in glob.glob(pattern))), None)


@pytest.fixture(scope="session")
def llvm15(llvm15_or_none) -> str:
    """Path of a real libLLVM 15; skips the test with the reason when there is none."""
    if llvm15_or_none is None:
        pytest.skip("no libLLVM 15 on this machine (Debian: 'apt-get install libllvm15'); "
                    "the LLVM-15 simulation needs the real library")
    return llvm15_or_none
