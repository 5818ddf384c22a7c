"""Impossible generation parameters are refused before anything is drawn or written (no Blender)."""
import math
import re

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.cli.main import main
from scratch_iridescence.mitsuba_bridge.scratch import (Constant, Gaussian, Uniform, check_looks, parse_distribution,
                                                        random_scratches)

FLT_MAX_NM = 3.4028234663852886e38 * 1e-9  # what Blender makes of a width of "inf" nanometres


@pytest.mark.parametrize("looks, message", [
    (dict(width=Gaussian(FLT_MAX_NM, 1.3e-6)), r"width G\[3.40282e\+29, 1.3e-06\] \(metres\) reaches 3.4e\+29 m"),
    (dict(width=Gaussian(4e-6, FLT_MAX_NM)), "width G.* reaches 1.02e\\+30 m, beyond 0.001 m"),
    (dict(depth=Uniform(0.0, 2e-3)), r"depth U\[0, 0.002\] \(metres\) reaches 0.002 m, beyond 0.001 m"),
    (dict(depth=Constant(1.5e-3)), "depth 0.0015 .* beyond 0.001 m"),
    (dict(width_variation=(math.nan, 0.04)), "width variation: amplitude nan must lie in"),
    (dict(depth_variation=(10.5, 0.04)), r"depth variation: amplitude 10.5 must lie in \[0, 10\]"),
    (dict(depth_variation=(1.1, -0.1)), r"depth variation: frequency -0.1 must lie in \[0, 1\]"),
    (dict(depth_variation=(1.1, math.inf)), "depth variation: frequency inf must lie in"),
    (dict(depth_variation=(1.1,)), "expected \\(amplitude, frequency\\)"),
])
def test_impossible_looks_are_refused(looks, message):
    arguments = dict(width=Constant(1e-6), depth=Constant(250e-9)) | looks
    with pytest.raises(ValueError, match=message):
        check_looks(**arguments)
    with pytest.raises(ValueError, match=message):  # and by everything that draws parameters
        scratch.sample_parameters(np.random.default_rng(0), 5, **arguments)


def test_the_limits_themselves_are_accepted():
    check_looks(width=Uniform(1e-3, 1e-3), depth=Gaussian(0.4e-3, 0.2e-3), width_variation=(10.0, 1.0),
                depth_variation=(0.0, 0.0))


@pytest.mark.parametrize("arguments, message", [
    (dict(count=-1), "count must be a whole number >= 0"),
    (dict(count=2.5), "count must be a whole number"),
    (dict(length=(0.2, math.inf)), "lengths must satisfy 0 < min <= max and be finite"),
    (dict(length=(math.nan, 0.6)), "lengths must satisfy"),
    (dict(length=(0.6, 0.2)), "lengths must satisfy"),
    (dict(length=(0.0, 0.2)), "lengths must satisfy"),
    (dict(vertices=1), "at least 2 vertices"),
    (dict(angle=math.nan), "angle must be finite"),
    (dict(angle_spread=-0.1), "angle spread must be finite and >= 0"),
    (dict(curvature=math.inf), "curvature must be finite and >= 0"),
    (dict(region=((0, 0), (math.inf, 1))), "region must be"),
    (dict(width=Constant(1.0)), "width 1 .* beyond 0.001 m"),
])
def test_random_scratches_refuses_impossible_requests(arguments, message):
    with pytest.raises(ValueError, match=message):
        random_scratches(**(dict(count=10) | arguments))


def test_parse_distribution_scales_any_number_exactly():
    assert parse_distribution("1e30", "um") == Constant(1e24)  # was refused as "1e+30e-6"
    assert parse_distribution("G[250, 80]", "nm") == Gaussian(250e-9, 80e-9)
    for text in ("G[inf, 1]", "U[1, x]", "nan"):
        with pytest.raises(ValueError, match="cannot read distribution"):
            parse_distribution(text, "nm")


@pytest.mark.parametrize("arguments, message", [
    (["--length-max", "inf"], "lengths must satisfy"),
    (["--width", "1e30"], "width 1e\\+24 .* beyond 0.001 m"),
    (["--width", "G[inf, 1]"], "cannot read distribution"),
    (["--count", "-3"], "--count must be at least 1"),
    (["--depth-variation", "nan", "0.04"], "depth variation: amplitude nan"),
    (["--curvature", "inf"], "curvature must be finite"),
])
def test_cli_generate_refuses_with_one_line_and_writes_nothing(tmp_path, capsys, arguments, message):
    output = tmp_path / "out.npz"
    assert main(["generate", str(output), "--count", "5", *arguments]) == 2
    error = capsys.readouterr().err
    assert error.startswith("error: ") and error.count("\n") == 1 and "Traceback" not in error
    assert re.search(message, error)
    assert not output.exists() and list(tmp_path.iterdir()) == []


def test_cli_generate_still_writes_valid_requests(tmp_path):
    output = tmp_path / "out.npz"
    assert main(["generate", str(output), "--count", "5", "--width", "U[1, 1000]"]) == 0
    assert scratch.load(output).count == 5


def one_error_line(capsys) -> str:
    error = capsys.readouterr().err
    assert error.startswith("error: ") and error.count("\n") == 1 and "Traceback" not in error, error
    return error


def test_cli_generate_beyond_the_format_s_limits_is_refused_with_the_estimate(tmp_path, capsys):
    """``--count 1e9`` ended in a MemoryError traceback or the OOM killer; now one line, before anything is drawn."""
    output = tmp_path / "out.npz"
    assert main(["generate", str(output), "--count", "1e9"]) == 2
    error = one_error_line(capsys)
    assert "--count 1,000,000,000 of 8 vertices: a scratch file holds at most 16,777,216 scratches" in error
    assert re.search(r"would also need about 484\.\d GiB of memory", error), error  # 1e9 x (200 + 40 x 8) bytes
    assert list(tmp_path.iterdir()) == []


def test_cli_generate_beyond_the_allowed_memory_is_refused_before_drawing(tmp_path, capsys, farm_cgroup):
    """A count the format takes, in a farm worker whose cgroup leaves 156 MiB: refused with both figures."""
    import time

    farm_cgroup(256, 100)
    output = tmp_path / "out.npz"
    started = time.perf_counter()
    assert main(["generate", str(output), "--count", "1e6"]) == 1
    assert time.perf_counter() - started < 2.0  # refused from the estimate: nothing drawn
    error = one_error_line(capsys)
    assert ("generating 1,000,000 scratches of 8 vertices needs about 495.9 MiB of memory but only 156.0 MiB is "
            "allowed (cgroup v2 memory.max 256.0 MiB of /farm/worker, 100.0 MiB in use)") in error, error
    assert not output.exists()


@pytest.mark.parametrize("count, vertices", [(20_000, 8), (20_000, 2), (5_000, 32)])
def test_the_generate_estimate_bounds_the_measured_peak(tmp_path, count, vertices):
    """The estimate the refusal quotes bounds what generating and saving a set really allocates (tracemalloc
    counts numpy's buffers), without overstating it twice over (measured: 0.77-0.80 of the estimate)."""
    import tracemalloc

    tracemalloc.start()
    try:
        scratch.save(random_scratches(count, seed=1, vertices=vertices), tmp_path / "set.npz")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    estimate = scratch.estimate_generate_bytes(count, vertices)
    assert estimate / 2 < peak <= estimate, (peak, estimate)
