"""Benchmark: sample, save and load 300 000 scratches of 8 vertices (the paper's dining table).

Targets on the 2-core development machine: sampling < 1 s, save + load < 1 s,
memory < 200 MB.  Run: ``.venv/bin/python tests/bench/bench_scratch.py``.
"""
from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

from scratch_iridescence.mitsuba_bridge import scratch


def best_of(repeat, function):
    times, result = [], None
    for _ in range(repeat):
        result = None  # free the previous result before measuring again
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=300_000)
    parser.add_argument("--vertices", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--memory-run", action="store_true",
                        help="internal: sample, save, drop, load once and print the max RSS")
    args = parser.parse_args()
    if args.memory_run:
        return memory_run(args)

    def sample():
        return scratch.random_scratches(
            args.count, seed=1, vertices=args.vertices, curvature=2.0,
            width=scratch.Uniform(0, 6e-6), depth=scratch.Uniform(0, 6e-6))

    tracemalloc.start()
    t_sample, scratches = best_of(args.repeat, sample)
    _, peak_sample = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "table.npz"
        t_save, _ = best_of(args.repeat, lambda: scratch.save(scratches, path))
        t_load, loaded = best_of(args.repeat, lambda: scratch.load(path))
        _, peak_io = tracemalloc.get_traced_memory()
        t_numpy, _ = best_of(args.repeat, lambda: numpy_load(path))
        size = path.stat().st_size
        t_save_c, _ = best_of(1, lambda: scratch.save(scratches, path, compress=True))
        t_load_c, _ = best_of(args.repeat, lambda: scratch.load(path))
        t_numpy_c, _ = best_of(args.repeat, lambda: numpy_load(path))
        size_c = path.stat().st_size
    tracemalloc.stop()
    assert loaded == scratches

    mb = 1024 * 1024
    print(f"{args.count} scratches x {args.vertices} vertices ({scratches.nbytes / mb:.0f} MB of arrays)")
    print(f"  sample            {t_sample:7.3f} s   (target < 1 s)")
    print(f"  save + load       {t_save + t_load:7.3f} s   (save {t_save:.3f}, load {t_load:.3f}; target < 1 s), "
          f"file {size / mb:.0f} MB")
    print(f"  compressed        {t_save_c + t_load_c:7.3f} s   (save {t_save_c:.3f}, load {t_load_c:.3f}), "
          f"file {size_c / mb:.0f} MB")
    # The checked reader against numpy.load + validation of the same file, in this run (the machine is noisy).
    print(f"  load / numpy.load {t_load / t_numpy:7.2f}     (uncompressed; {t_load_c / t_numpy_c:.2f} compressed): "
          "the cost of checking headers and sizes before inflating")
    # The whole workflow once, in a fresh process, for an honest resident-memory figure.
    child = subprocess.run([sys.executable, __file__, "--memory-run", "--count", str(args.count),
                            "--vertices", str(args.vertices)], capture_output=True, text=True, check=True)
    print(f"  peak numpy memory: sampling {peak_sample / mb:.0f} MB, save/load {peak_io / mb:.0f} MB")
    print(f"  max resident set of sample -> save -> load in a fresh process: {child.stdout.strip()} MB "
          f"(interpreter and numpy alone: {baseline_rss():.0f} MB; target < 200 MB)")


def numpy_load(path) -> scratch.ScratchSet:
    """The file read with plain ``numpy.load``, then validated: the reference for the checked reader's cost."""
    import numpy as np

    with np.load(path, allow_pickle=False) as archive:
        return scratch.ScratchSet(**{key: archive[key] for key in archive.files if key != "format"})


def peak_rss_mb() -> float:
    """High-water resident set of this process (VmHWM: unlike ru_maxrss, not inherited over fork)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def baseline_rss() -> float:
    code = f"import numpy, sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import bench_scratch; print(bench_scratch.peak_rss_mb())"
    return float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout)


def memory_run(args):
    scratches = scratch.random_scratches(args.count, seed=1, vertices=args.vertices, curvature=2.0,
                                         width=scratch.Uniform(0, 6e-6), depth=scratch.Uniform(0, 6e-6))
    with tempfile.TemporaryDirectory() as folder:
        path = scratch.save(scratches, Path(folder) / "table.npz")
        del scratches
        loaded = scratch.load(path)
    assert loaded.count == args.count
    print(f"{peak_rss_mb():.0f}")


if __name__ == "__main__":
    main()
