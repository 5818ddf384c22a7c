"""Suite-wide settings: every random test input is reproducible.

Hypothesis draws its examples at random unless told otherwise, so a property
test could pass on one run and fail on the next (and its example database would
make the outcome depend on earlier runs).  The ``deterministic`` profile,
loaded by default, derives every example from the test itself and keeps no
database: the same code gives the same examples, run after run.  Set
``HYPOTHESIS_PROFILE=explore`` to search new examples (failures print a
``@reproduce_failure`` blob to pin them down).
"""
import os

from hypothesis import settings

settings.register_profile("deterministic", derandomize=True, database=None, print_blob=True)
settings.register_profile("explore", derandomize=False, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))
