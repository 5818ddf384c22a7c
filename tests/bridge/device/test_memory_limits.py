"""What this process may still allocate (mitsuba_bridge/device/memory.py): free memory, ``ulimit -v``/``-d`` and
cgroup v1 and v2 limits, read from real files laid out as ``/proc`` and ``/sys/fs/cgroup`` are, and from real rlimits
in a child."""
from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

from scratch_iridescence.mitsuba_bridge.device import memory

ROOT = Path(__file__).resolve().parents[3]
GiB, MiB = 2 ** 30, 2 ** 20


def layout(base: Path, files: dict[str, str]) -> tuple[Path, Path]:
    """``proc`` and ``cgroup`` folders under ``base`` holding ``files`` (paths relative to base)."""
    for relative, text in files.items():
        (base / relative).parent.mkdir(parents=True, exist_ok=True)
        (base / relative).write_text(text)
    (base / "proc").mkdir(exist_ok=True)
    (base / "cgroup").mkdir(exist_ok=True)
    return base / "proc", base / "cgroup"


def limits(proc: Path, cgroup: Path) -> list[memory.MemoryLimit]:
    """The cgroup limits found (where the fake ``proc`` has no meminfo, free memory comes from sysconf)."""
    return [limit for limit in memory.memory_limits(proc=proc, cgroup_root=cgroup) if "cgroup" in limit.source]


MEMINFO = f"MemTotal: {64 * GiB // 1024} kB\nMemFree: 1000 kB\nMemAvailable: {48 * GiB // 1024} kB\n"


def test01_free_memory_comes_from_memavailable(tmp_path):
    proc, cgroup = layout(tmp_path, {"proc/meminfo": MEMINFO, "proc/self/cgroup": "0::/\n"})
    found = [limit for limit in memory.memory_limits(proc=proc, cgroup_root=cgroup) if "MemAvailable" in limit.source]
    assert found == [memory.MemoryLimit(48 * GiB, "free memory, MemAvailable")]


def test02_cgroup_v2_limits_of_the_group_and_every_group_above_it(tmp_path):
    proc, cgroup = layout(tmp_path, {
        "proc/meminfo": MEMINFO, "proc/self/cgroup": "0::/farm.slice/worker-3.scope\n",
        "cgroup/cgroup.controllers": "cpu memory pids\n",
        "cgroup/farm.slice/memory.max": "max\n", "cgroup/farm.slice/memory.current": f"{5 * GiB}\n",
        "cgroup/farm.slice/worker-3.scope/memory.max": f"{2 * GiB}\n",
        "cgroup/farm.slice/worker-3.scope/memory.current": f"{700 * MiB}\n",
        "cgroup/farm.slice/worker-3.scope/memory.stat": f"anon {400 * MiB}\nfile {300 * MiB}\n"
                                                        f"inactive_file {200 * MiB}\n"})
    smallest = memory.smallest_limit(proc=proc, cgroup_root=cgroup)
    assert smallest.bytes == 2 * GiB - 500 * MiB  # inactive file pages are reclaimable: not counted as used
    assert smallest.source.startswith("cgroup v2 memory.max 2.0 GiB of /farm.slice/worker-3.scope, 500.0 MiB in use")
    # a tighter limit higher up wins
    (cgroup / "farm.slice" / "memory.max").write_text(f"{6 * GiB}\n")
    smallest = memory.smallest_limit(proc=proc, cgroup_root=cgroup)
    assert smallest.bytes == 1 * GiB and "/farm.slice," in smallest.source


def test03_cgroup_v2_in_a_container_namespace_and_in_a_hybrid_layout(tmp_path):
    # A container sees its own group as the root: /proc/self/cgroup says "0::/" and the limit sits at the mount.
    proc, cgroup = layout(tmp_path / "container", {
        "proc/self/cgroup": "0::/\n", "cgroup/cgroup.controllers": "memory\n",
        "cgroup/memory.max": f"{512 * MiB}\n", "cgroup/memory.current": f"{12 * MiB}\n"})
    assert memory.smallest_limit(proc=proc, cgroup_root=cgroup).bytes == 500 * MiB
    # systemd's hybrid layout: v1 controllers beside the v2 tree mounted at unified/
    proc, cgroup = layout(tmp_path / "hybrid", {
        "proc/self/cgroup": "4:memory:/\n0::/job\n", "cgroup/memory/memory.limit_in_bytes": "9223372036854771712\n",
        "cgroup/unified/job/memory.max": f"{3 * GiB}\n", "cgroup/unified/job/memory.current": "0\n"})
    (smallest,) = limits(proc, cgroup)
    assert smallest.bytes == 3 * GiB and "of /job" in smallest.source


def test04_cgroup_v1_limits_and_the_hierarchy_s(tmp_path):
    proc, cgroup = layout(tmp_path, {
        "proc/self/cgroup": "5:cpu,cpuacct:/docker/abc\n4:memory:/docker/abc\n0::/\n",
        "cgroup/memory/docker/abc/memory.limit_in_bytes": f"{4 * GiB}\n",
        "cgroup/memory/docker/abc/memory.usage_in_bytes": f"{1 * GiB}\n",
        "cgroup/memory/docker/abc/memory.stat": f"cache 0\nhierarchical_memory_limit {3 * GiB}\n"
                                                f"total_inactive_file {256 * MiB}\n"})
    (limit,) = limits(proc, cgroup)
    assert limit.bytes == 3 * GiB - 768 * MiB and limit.source.startswith("cgroup v1 memory.limit_in_bytes 3.0 GiB")
    # no limit (v1 writes the largest page-aligned 63-bit number), and a group path the namespace hides
    (cgroup / "memory" / "docker" / "abc" / "memory.limit_in_bytes").write_text("9223372036854771712\n")
    (cgroup / "memory" / "docker" / "abc" / "memory.stat").write_text("hierarchical_memory_limit 9223372036854771712\n")
    assert limits(proc, cgroup) == []
    (cgroup / "memory" / "memory.limit_in_bytes").write_text(f"{GiB}\n")
    (proc / "self" / "cgroup").write_text("4:memory:/not/visible/here\n")
    assert [limit.bytes for limit in limits(proc, cgroup)] == [GiB]


@pytest.mark.parametrize("text", ["", "garbage\n", "0::\n", "4:memory\n", "::::\n\n"])
def test05_damaged_cgroup_files_mean_no_limit_never_an_error(tmp_path, text):
    proc, cgroup = layout(tmp_path, {"proc/self/cgroup": text, "cgroup/memory.max": "lots\n"})
    assert limits(proc, cgroup) == []


def child_limit(code: str, **rlimits) -> str:
    """``code``'s output in a child started with the given soft rlimits (``ulimit -v`` is RLIMIT_AS in KiB × 1024)."""
    def apply():
        for name, value in rlimits.items():
            resource.setrlimit(getattr(resource, name), (value, resource.RLIM_INFINITY))

    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300,
                            preexec_fn=apply)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test06_ulimit_v_and_ulimit_d_in_a_child(tmp_path):
    code = "from scratch_iridescence.mitsuba_bridge.device import memory\nprint(memory.smallest_limit())"
    limited = child_limit(code, RLIMIT_AS=3 * GiB)
    assert "address-space limit, ulimit -v 3.0 GiB" in limited and "MiB in use" in limited
    assert "data limit, ulimit -d 2.0 GiB" in child_limit(code, RLIMIT_DATA=2 * GiB)


def test07_the_check_says_what_is_needed_and_what_is_allowed():
    allowed = memory.MemoryLimit(3 * GiB, "address-space limit, ulimit -v 3.0 GiB, 1.0 GiB in use")
    assert memory.check_memory(GiB, "a small thing", limit=allowed) is allowed
    with pytest.raises(memory.NotEnoughMemory) as refused:
        memory.check_memory(40 * GiB, "a big thing", detail="two halves", advice="ask for less", limit=allowed)
    assert str(refused.value) == ("a big thing needs about 40.0 GiB of memory (two halves) but only 3.0 GiB is "
                                  "allowed (address-space limit, ulimit -v 3.0 GiB, 1.0 GiB in use); ask for less")
    with pytest.raises(memory.NotEnoughMemory, match="more than any machine has"):
        memory.check_memory(float("inf"), "an infinite thing", limit=allowed)
    with pytest.raises(memory.NotEnoughMemory):
        memory.check_memory(float("nan"), "a NaN thing", limit=allowed)
    assert memory.format_bytes(3.4e18) == "3.2e+09 GiB"


def test08_this_machine_reports_something_plausible():
    found = memory.smallest_limit()
    assert found is None or 1e6 < found.bytes < 1e16
