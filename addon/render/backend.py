"""Mitsuba, Dr.Jit and OpenEXR (the wheels the extension bundles) loaded once, or one clear error.

F12, the Rendered viewport and Export need them.  What can go wrong is found
before anything binary is imported, and then said once, in words a user can act
on, instead of a traceback or a crash:

* a wheel is missing (Blender skipped it, or the zip of another platform was
  installed): its module is not found;
* the wheels are for another Python: Blender 4.2.0's installer put the wheels of
  every Python version of a zip into its Python 3.11, so Dr.Jit's only binary
  was CPython 3.13's and ``import drjit`` failed with ``NameError: name
  '_drjit_ext' is not defined`` (Dr.Jit's own error path), after which Blender
  could crash.  The zips now hold one Python's wheels each (.ci/build_extension.py),
  and a binary built for another Python is recognised by its file name and never
  imported;
* anything else the import raises (a missing system library, a damaged file).

The first answer is kept: a broken binary module is never imported a second
time in one Blender session (its half-initialised state is what crashed).
"""
from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from pathlib import Path

from ...mitsuba_bridge.errors import ScratchUserError

__all__ = ["BackendUnavailable", "MODULES", "MITSUBA_MISSING", "problem", "require"]

#: The bundled modules, in the order they are imported (the bridge first: it chooses Dr.Jit's libLLVM).
MODULES = ("drjit", "mitsuba", "OpenEXR")

MITSUBA_MISSING = (
    "Mitsuba is not available in Blender's Python ({error}). Install the Scratch Iridescence extension zip "
    "built for your platform and Blender version (it bundles the mitsuba, drjit and OpenEXR wheels), or install "
    "'mitsuba==3.9.1 drjit==1.5.0' into Blender's Python, then restart Blender")

WRONG_PYTHON = (
    "The Mitsuba wheels installed with Scratch Iridescence are for Python {found}, but this Blender runs Python "
    "{running} ({module}: {file}). Remove the extension, install the zip built for your Blender version "
    "(scratch_iridescence-<version>-{zip_part}-<platform>.zip) and restart Blender")

#: A binary module's Python tag in its file name: ``.cpython-313-x86_64-linux-gnu.so``, ``.cp313-win_amd64.pyd``.
_PYTHON_TAG = re.compile(r"\.(?:cpython-|cp)3(\d+)")

_answer: list = []  #: [problem or None] once known


class BackendUnavailable(ScratchUserError, ImportError):
    """The bundled modules cannot be used in this Blender; the message says what to install."""


def problem() -> str | None:
    """None when the bundled modules are imported and usable, else the one message saying what to do.

    Imports them on the first call (the bridge first, so that Dr.Jit loads the bundled libLLVM); later
    calls return the first answer.
    """
    if not _answer:
        _answer.append(_first_problem())
    return _answer[0]


def require() -> None:
    """Raise :class:`BackendUnavailable` with :func:`problem`'s message when there is one."""
    message = problem()
    if message is not None:
        raise BackendUnavailable(message)


def _first_problem() -> str | None:
    try:
        for name in MODULES:
            if (message := _wrong_python(name)) is not None:
                return message
        from ... import mitsuba_bridge  # noqa: F401  (before drjit: it hands Dr.Jit the bundled libLLVM)

        for name in MODULES:
            importlib.import_module(name)
    except ImportError as error:
        return MITSUBA_MISSING.format(error=error)
    except Exception as error:  # noqa: BLE001 - anything an import raises must become this one message
        return MITSUBA_MISSING.format(error=f"{type(error).__name__}: {error}")
    return None


def _wrong_python(name: str) -> str | None:
    """The message when ``name``'s binaries exist only for other Python versions; else None (nothing imported)."""
    spec = importlib.util.find_spec(name)
    if spec is not None and spec.submodule_search_locations:
        binaries = [path for folder in spec.submodule_search_locations for path in Path(folder).iterdir()]
    elif spec is None:  # a single-file binary module of another Python is not found at all: look for its file
        binaries = [path for folder in sys.path if folder and Path(folder).is_dir()
                    for path in Path(folder).glob(f"{name}.*")]
    else:
        return None
    tagged = {path: f"3.{match.group(1)}" for path in binaries if (match := _PYTHON_TAG.search(path.name))}
    running = "%d.%d" % sys.version_info[:2]
    if not tagged or running in tagged.values():
        return None
    found = sorted(set(tagged.values()))
    return WRONG_PYTHON.format(found=" and ".join(found), running=running, module=name, file=next(iter(tagged)).name,
                               zip_part=_zip_part(sys.version_info[:2]))


def _zip_part(python: tuple[int, int]) -> str:
    """The part of the zip's name that says which Blender releases it is for (.ci/build_extension.py)."""
    return "blender5.1-newer" if python >= (3, 13) else "blender4.2-5.0"
