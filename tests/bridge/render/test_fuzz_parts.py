"""Fuzzing ``merge``: a mutated part gives ``PartError`` or exactly the image of the intact parts, nothing else.

Parts are made without rendering (``write_part`` of random chunk images, the sums as a render makes them).  Byte
mutations (bit flips, truncations, inserted and overwritten bytes) hit the EXR file anywhere: its header, offset
table or compressed pixels; structural mutations rewrite a consistent EXR whose attributes or channels are wrong
(random values of random types, dropped, renamed, retyped or resized channels), with the part's checksum recomputed
or not.  Neither kind may produce a traceback, another exception, or a different image.  The seed is fixed; the
fast subset runs in ``make test``, the long run under ``make test-slow``.
"""
from __future__ import annotations

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.render import parts
from scratch_iridescence.mitsuba_bridge.render.schedule import PairwiseSum, part_range, sample_schedule

SEED = 20261208
WIDTH, HEIGHT, SPP = 6, 4, 13


@pytest.fixture(scope="module")
def intact(tmp_path_factory):
    """Three parts of a 6 × 4 render of 13 spp and the image they merge into."""
    folder = tmp_path_factory.mktemp("parts")
    chunks = sample_schedule(SPP, WIDTH * HEIGHT, 2)
    identity = parts.RenderIdentity("scene", "llvm_ad_spectral", "mitsuba 3, drjit 1", WIDTH, HEIGHT, SPP, 2,
                                    len(chunks), parts.schedule_digest(chunks), "none")
    rng = np.random.default_rng(7)
    files = []
    for k in (1, 2, 3):
        run = part_range(k, 3, len(chunks))
        sums = PairwiseSum(run.start)
        for index in run:
            sums.add(rng.random((HEIGHT, WIDTH, 4)).astype(np.float32).astype(np.float64) * chunks[index].spp)
        files.append(parts.write_part(folder / f"p{k}.exr", identity, sums, sum(c.spp for c in chunks[run.start:
                                                                                                      run.stop])))
    image, _ = parts.merge_parts(files)
    return files, image


def outcome(files, mutated: bytes, path) -> str:
    """"refused" (PartError), "same" (the intact image) or what else happened (a failure)."""
    path.write_bytes(mutated)
    try:
        image, _ = parts.merge_parts([files[0], path, files[2]])
    except parts.PartError:
        return "refused"
    return "same" if image.tobytes() == outcome.image.tobytes() else "a different image"


def byte_mutation(data: bytes, rng) -> bytes:
    kind = int(rng.integers(4))
    if kind == 0:  # bit flips
        mutated = bytearray(data)
        for _ in range(int(rng.integers(1, 4))):
            mutated[int(rng.integers(len(data)))] ^= 1 << int(rng.integers(8))
        return bytes(mutated)
    if kind == 1:  # truncation
        return data[:int(rng.integers(len(data)))]
    where = int(rng.integers(len(data) + 1))
    run = rng.bytes(int(rng.integers(1, 24)))
    if kind == 2:  # inserted bytes
        return data[:where] + run + data[where:]
    return data[:where] + run + data[where + len(run):]  # overwritten bytes


def random_value(rng):
    return [int(rng.integers(-2 ** 31, 2 ** 31)), float(rng.normal() * 10 ** int(rng.integers(-5, 300))),
            "".join(chr(int(c)) for c in rng.integers(32, 127, int(rng.integers(0, 40)))),
            int(rng.choice([0, 1, -1, 2 ** 31 - 1, -2 ** 31]))][int(rng.integers(4))]


def structural_mutation(source, target, rng):
    import OpenEXR

    with OpenEXR.File(str(source), separate_channels=True) as file:
        header = dict(file.header())
        channels = {name: np.array(channel.pixels) for name, channel in file.channels().items()}
    for name in ("dataWindow", "displayWindow", "channels"):
        header.pop(name, None)
    kind = int(rng.integers(5))
    names = sorted(channels)
    if kind == 0:
        key = str(rng.choice(sorted(set(header) - {"compression", "type", "lineOrder"})))
        header[key] = random_value(rng)
    elif kind == 1:
        del channels[str(rng.choice(names))]
    elif kind == 2:
        name = str(rng.choice(names))
        channels[name + "x" if rng.random() < 0.5 else "sum.L9.N9.R.hi"] = channels.pop(name)
    elif kind == 3:
        name = str(rng.choice(names))
        with np.errstate(over="ignore", invalid="ignore"):
            channels[name] = channels[name].astype([np.float32, np.float16, np.uint32][int(rng.integers(3))])
    else:
        channels = {name: value[:, :-1] if rng.random() < 0.5 else value[:-1] for name, value in channels.items()}
    if rng.random() < 0.5:  # as a tool that edits parts on purpose would
        header["checksum"] = parts._checksum(header, channels)
    try:
        OpenEXR.File(header, channels).write(str(target))
    except (RuntimeError, ValueError, TypeError):  # a mutation OpenEXR itself will not write
        return None
    return target.read_bytes()


def run_fuzz(intact, tmp_path, count: int) -> dict:
    files, image = intact
    outcome.image = image
    rng = np.random.default_rng(SEED)
    data = files[1].read_bytes()
    found = {}
    for case in range(count):
        if case % 3 == 2:
            mutated = structural_mutation(files[1], tmp_path / "structural.exr", rng)
            if mutated is None:
                continue
        else:
            mutated = byte_mutation(data, rng)
        result = outcome(files, mutated, tmp_path / "mutated.exr")
        found[result] = found.get(result, 0) + 1
        assert result in ("refused", "same"), (case, result)
    return found


def test01_mutated_parts_are_refused_or_merge_into_the_same_image(intact, tmp_path, capfd):
    found = run_fuzz(intact, tmp_path, 300)
    assert found.get("refused", 0) > 150, found  # the mutations do reach the checks
    assert capfd.readouterr() == ("", "")  # OpenEXR's own complaints are captured, quoted in the one error


@pytest.mark.slow
def test02_the_long_run(intact, tmp_path):
    found = run_fuzz(intact, tmp_path, 6000)
    assert found.get("refused", 0) > 3000, found
