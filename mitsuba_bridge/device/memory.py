"""How much memory this process may still take, from every limit that applies, and one check for the whole product.

Free physical memory is one limit among several.  A process may be refused
memory long before the machine runs out:

* **Address-space limit** (``ulimit -v``, ``RLIMIT_AS``): every mapping counts,
  including the address space Dr.Jit and LLVM reserve; past it ``malloc`` fails
  and a native library may crash (a 10000 × 10000 render under
  ``ulimit -v 6000000`` died with SIGSEGV when only ``MemAvailable`` was asked).
  What is left is the limit less the current ``VmSize``.
* **Data limit** (``ulimit -d``, ``RLIMIT_DATA``): private writable memory
  (Linux ≥ 4.7 counts anonymous mappings), less the current ``VmData``.
* **Control groups** (containers, systemd slices, render farm workers): cgroup
  v2's ``memory.max`` of the process's group and every group above it, less
  ``memory.current``; cgroup v1's ``memory.limit_in_bytes`` (and the
  ``hierarchical_memory_limit`` of ``memory.stat``) less ``memory.usage_in_bytes``.
  Inactive file pages (``inactive_file``) are reclaimable and do not count as used.
  Past the limit the kernel's OOM killer ends the process without a word.
* **Free physical memory**: ``MemAvailable`` (Linux), ``GlobalMemoryStatusEx``
  (Windows: physical memory and the commit charge left), else ``sysconf``.

:func:`memory_limits` reads them all (each with where it came from);
:func:`check_memory` compares an estimate with the smallest and raises
:class:`NotEnoughMemory` (a user error: one report in Blender, one ``error:``
line on the command line) saying what is needed and what is allowed.  F12, the
command line's ``render`` and ``generate``, the live viewport's session and the
add-on's Generate and paint tools all ask it.  Linux's files are read from
``proc`` and ``cgroup_root`` arguments so that tests can lay out their own.
"""
from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

from ..errors import ScratchUserError

__all__ = ["NotEnoughMemory", "MemoryLimit", "memory_limits", "smallest_limit", "check_memory", "format_bytes"]

_PROC = Path("/proc")
_CGROUP_ROOT = Path("/sys/fs/cgroup")
#: cgroup v1 writes "no limit" as the largest page-aligned 63-bit value (9223372036854771712) or near it.
_V1_UNLIMITED = 1 << 62


class NotEnoughMemory(ScratchUserError, MemoryError):
    """An operation would need more memory than this process is allowed (the message gives both figures)."""


@dataclass(frozen=True)
class MemoryLimit:
    """Bytes this process may still allocate under one limit, and which limit (for messages)."""

    bytes: int
    source: str


def format_bytes(count: float) -> str:
    """``"1.5 GiB"``, ``"12.0 MiB"``, ``"3.4e+06 GiB"`` for absurd figures (binary units, as ``ulimit`` and cgroups)."""
    count = float(count)
    if count >= 2 ** 30:
        gib = count / 2 ** 30
        return f"{gib:.1f} GiB" if gib < 1e6 else f"{gib:.2g} GiB"
    return f"{count / 2 ** 20:.1f} MiB"


def memory_limits(*, proc: Path | None = None, cgroup_root: Path | None = None) -> list[MemoryLimit]:
    """Every limit that applies to this process now (the free memory first); empty where none is known.

    ``proc`` and ``cgroup_root`` stand for ``/proc`` and ``/sys/fs/cgroup`` (tests lay out their own).
    """
    proc = _PROC if proc is None else Path(proc)
    cgroup_root = _CGROUP_ROOT if cgroup_root is None else Path(cgroup_root)
    limits = []
    physical = _physical(proc)
    if physical is not None:
        limits.append(physical)
    status = _status(proc)
    limits += _rlimits(status)
    limits += _cgroup_limits(proc, cgroup_root)
    return limits


def smallest_limit(**paths) -> MemoryLimit | None:
    """The limit with the fewest bytes left (None where no limit is known)."""
    limits = memory_limits(**paths)
    return min(limits, key=lambda limit: limit.bytes) if limits else None


def check_memory(needed_bytes: int, what: str, *, detail: str = "", advice: str = "",
                 limit: MemoryLimit | None = None, **paths) -> MemoryLimit | None:
    """Raise :class:`NotEnoughMemory` when ``needed_bytes`` exceeds what this process is allowed.

    Parameters
    ----------
    needed_bytes : int
        The estimate (bytes); NaN or infinite counts as too much.
    what : str
        The operation, as the message starts (``"a 10000 x 10000 render"``).
    detail : str
        What the estimate is made of, in parentheses after it (``"film 3.4 GiB, ..."``).
    advice : str
        How to need less, appended to the message (``"lower the resolution"``).
    limit : MemoryLimit, optional
        The limit to compare with (default: :func:`smallest_limit` now).

    Returns
    -------
    MemoryLimit or None
        The limit compared with (None where none is known: nothing is refused then).
    """
    limit = smallest_limit(**paths) if limit is None else limit
    needed = float(needed_bytes)
    if limit is not None and not needed <= limit.bytes:
        needed_text = format_bytes(needed) if math.isfinite(needed) else "more than any machine has"
        raise NotEnoughMemory(f"{what} needs about {needed_text} of memory" + (f" ({detail})" if detail else "")
                              + f" but only {format_bytes(limit.bytes)} is allowed ({limit.source})"
                              + (f"; {advice}" if advice else ""))
    return limit


# ------------------------------------------------------------------ free physical memory
def _physical(proc: Path) -> MemoryLimit | None:
    available = _meminfo(proc, "MemAvailable")
    if available is not None:
        return MemoryLimit(available, "free memory, MemAvailable")
    if sys.platform == "win32":  # pragma: no cover - not run on the Linux CI
        return _windows()
    try:
        return MemoryLimit(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"), "free memory")
    except (ValueError, OSError, AttributeError):
        pass
    try:  # macOS offers no free-page count through Python: the installed memory bounds it
        return MemoryLimit(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"), "installed memory")
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return None


def _windows() -> MemoryLimit | None:  # pragma: no cover - not run on the Linux CI
    import ctypes

    class _Status(ctypes.Structure):
        _fields_ = [("length", ctypes.c_ulong), ("load", ctypes.c_ulong),
                    ("total", ctypes.c_ulonglong), ("available", ctypes.c_ulonglong),
                    ("total_page", ctypes.c_ulonglong), ("available_page", ctypes.c_ulonglong),
                    ("total_virtual", ctypes.c_ulonglong), ("available_virtual", ctypes.c_ulonglong),
                    ("extended", ctypes.c_ulonglong)]

    status = _Status()
    status.length = ctypes.sizeof(_Status)
    if not ctypes.windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status)):
        return None
    # (the commit charge left: beyond it Windows refuses allocations even with physical memory free)
    return min(MemoryLimit(int(status.available), "free physical memory"),
               MemoryLimit(int(status.available_page), "commit limit left"),
               MemoryLimit(int(status.available_virtual), "address space left"), key=lambda limit: limit.bytes)


def _meminfo(proc: Path, field: str) -> int | None:
    try:
        with open(proc / "meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError, UnicodeDecodeError):
        pass
    return None


# ------------------------------------------------------------------ address space and data limits
def _status(proc: Path) -> dict[str, int]:
    """``VmSize`` and ``VmData`` of this process (bytes), from ``proc/self/status`` (empty elsewhere)."""
    found = {}
    try:
        with open(proc / "self" / "status", encoding="ascii", errors="replace") as status:
            for line in status:
                name, _, rest = line.partition(":")
                if name in ("VmSize", "VmData"):
                    found[name] = int(rest.split()[0]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return found


def _rlimits(status: dict[str, int]) -> list[MemoryLimit]:
    try:
        import resource
    except ImportError:  # Windows
        return []
    limits = []
    for name, used, text in (("RLIMIT_AS", "VmSize", "address-space limit, ulimit -v"),
                             ("RLIMIT_DATA", "VmData", "data limit, ulimit -d")):
        number = getattr(resource, name, None)
        if number is None:
            continue
        try:
            soft, _ = resource.getrlimit(number)
        except (OSError, ValueError):
            continue
        if soft == resource.RLIM_INFINITY or soft < 0:
            continue
        limits.append(MemoryLimit(max(int(soft) - status.get(used, 0), 0),
                                  f"{text} {format_bytes(soft)}, {format_bytes(status.get(used, 0))} in use"))
    return limits


# ------------------------------------------------------------------ control groups
def _cgroup_limits(proc: Path, root: Path) -> list[MemoryLimit]:
    """The tightest cgroup v2 and v1 memory limits of this process (none where it is not in a limited group)."""
    try:
        lines = (proc / "self" / "cgroup").read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return []
    limits = []
    for line in lines:
        number, _, rest = line.partition(":")
        controllers, _, path = rest.partition(":")
        if number == "0" and controllers == "":
            # (a hybrid layout mounts the v2 hierarchy at unified/, beside the v1 controllers)
            hybrid = (root / "unified").is_dir() and not (root / "cgroup.controllers").exists()
            limits += _v2(root / "unified" if hybrid else root, path)
        elif "memory" in controllers.split(","):
            limits += _v1(root / "memory", path)
    return limits


def _group_folder(mount: Path, path: str) -> Path:
    """The group's folder under ``mount``; the mount itself where the path is not visible (a container's
    namespace shows its own group as the root)."""
    folder = mount / path.strip("/")
    return folder if path.strip("/") and folder.is_dir() else mount


def _read_number(path: Path) -> int | None:
    """An integer file's value; None for ``max``, missing or unreadable files."""
    try:
        text = path.read_text(encoding="ascii", errors="replace").strip()
    except OSError:
        return None
    try:
        return int(text)
    except ValueError:
        return None


def _stat_value(path: Path, key: str) -> int:
    try:
        for line in path.read_text(encoding="ascii", errors="replace").splitlines():
            name, _, value = line.partition(" ")
            if name == key:
                return int(value)
    except (OSError, ValueError):
        pass
    return 0


def _v2(root: Path, path: str) -> list[MemoryLimit]:
    """``memory.max`` of the group and of every group above it, each less that group's usage."""
    limits = []
    folder = _group_folder(root, path)
    while True:
        ceiling = _read_number(folder / "memory.max")
        if ceiling is not None:
            usage = _read_number(folder / "memory.current") or 0
            usage = max(usage - _stat_value(folder / "memory.stat", "inactive_file"), 0)
            name = "/" + folder.relative_to(root).as_posix() if folder != root else "/"
            limits.append(MemoryLimit(max(ceiling - usage, 0), f"cgroup v2 memory.max {format_bytes(ceiling)} of "
                                                               f"{name}, {format_bytes(usage)} in use"))
        if folder == root or root not in folder.parents:
            break
        folder = folder.parent
    return limits


def _v1(mount: Path, path: str) -> list[MemoryLimit]:
    """``memory.limit_in_bytes`` (or the hierarchy's, from ``memory.stat``) less ``memory.usage_in_bytes``."""
    folder = _group_folder(mount, path)
    ceilings = [_read_number(folder / "memory.limit_in_bytes"),
                _stat_value(folder / "memory.stat", "hierarchical_memory_limit") or None]
    ceilings = [value for value in ceilings if value is not None and 0 <= value < _V1_UNLIMITED]
    if not ceilings:
        return []
    ceiling = min(ceilings)
    usage = _read_number(folder / "memory.usage_in_bytes") or 0
    usage = max(usage - _stat_value(folder / "memory.stat", "total_inactive_file"), 0)
    return [MemoryLimit(max(ceiling - usage, 0), f"cgroup v1 memory.limit_in_bytes {format_bytes(ceiling)}, "
                                                 f"{format_bytes(usage)} in use")]
