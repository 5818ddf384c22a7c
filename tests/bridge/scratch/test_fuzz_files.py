"""Fuzzing the scratch-file reader: mutated files give ScratchFormatError or the set they still hold.

Byte-level mutations (bit flips, truncations, inserted or appended bytes) of a
valid file must give ``ScratchFormatError`` or exactly the original set: the
zip CRCs, sizes and layout checks leave no room for a third outcome.
Structural mutations (members reordered, swapped, dropped, duplicated, their
``.npy`` headers edited) are rebuilt into consistent archives; for those the
expected outcome is what ``numpy.load`` reads from the same bytes, validated as
a ScratchSet, or ``ScratchFormatError`` where that fails.  The seed is fixed.
"""
from __future__ import annotations

import io
import warnings
import zipfile

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.scratch import FORMAT, ScratchFormatError, ScratchSet, random_scratches
from scratch_iridescence.mitsuba_bridge.scratch.scratchset import FIELD_SPECS

SEED = 20261130
HEADER_ALPHABET = list(b"0123456789(),' <>|=fiuUbcOTFS:{}")


@pytest.fixture(scope="module")
def originals() -> list[tuple[ScratchSet, bytes]]:
    """A small set, stored uncompressed and compressed."""
    scratches = random_scratches(12, seed=4, vertices=4, depth_variation=(1.1, 0.04))
    return [(scratches, scratch.dumps(scratches, compress=compress)) for compress in (False, True)]


# ----------------------------------------------------------- byte mutations
def flip_bits(data: bytes, rng) -> bytes:
    mutated = bytearray(data)
    for _ in range(int(rng.integers(1, 5))):
        mutated[int(rng.integers(len(data)))] ^= 1 << int(rng.integers(8))
    return bytes(mutated)


def truncate(data: bytes, rng) -> bytes:
    return data[:int(rng.integers(len(data)))]


def insert_bytes(data: bytes, rng) -> bytes:
    where = int(rng.integers(len(data) + 1))
    return data[:where] + rng.bytes(int(rng.integers(1, 40))) + data[where:]


def overwrite_run(data: bytes, rng) -> bytes:
    where = int(rng.integers(len(data)))
    run = rng.bytes(int(rng.integers(1, 16)))
    return data[:where] + run + data[where + len(run):]


BYTE_MUTATIONS = (flip_bits, truncate, insert_bytes, overwrite_run)


# ------------------------------------------------------ structural mutations
def _members(data: bytes) -> list[tuple[str, bytes, int]]:
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return [(info.filename, archive.read(info), info.compress_type) for info in archive.infolist()]


def _rezip(members: list[tuple[str, bytes, int]]) -> bytes:
    stream = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # duplicate names are one of the mutations
        with zipfile.ZipFile(stream, "w") as archive:
            for name, content, method in members:
                archive.writestr(name, content, compress_type=method)
    return stream.getvalue()


def reorder(members, rng):
    return [members[i] for i in rng.permutation(len(members))]


def swap_contents(members, rng):
    i, j = rng.choice(len(members), 2, replace=False)
    swapped = list(members)
    swapped[i] = (members[i][0], members[j][1], members[i][2])
    swapped[j] = (members[j][0], members[i][1], members[j][2])
    return swapped


def drop_or_duplicate(members, rng):
    i = int(rng.integers(len(members)))
    if rng.random() < 0.5:
        return members[:i] + members[i + 1:]
    return members + [members[i]]


def edit_header(members, rng):
    """Replace one character of one member's .npy header dict."""
    i = int(rng.integers(len(members)))
    name, content, method = members[i]
    header_end = 10 + int.from_bytes(content[8:10], "little")
    position = int(rng.integers(10, header_end))
    edited = bytearray(content)
    edited[position] = HEADER_ALPHABET[int(rng.integers(len(HEADER_ALPHABET)))]
    return members[:i] + [(name, bytes(edited), method)] + members[i + 1:]


STRUCTURAL_MUTATIONS = (reorder, swap_contents, drop_or_duplicate, edit_header)


def numpy_reading(data: bytes) -> ScratchSet | None:
    """What numpy.load makes of a consistent archive, validated; None where numpy or validation refuses.

    Stricter than numpy by design: a name that appears twice is refused (numpy takes the last one),
    and so is a header numpy reads only with a deprecation warning.
    """
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        names = archive.namelist()
    if len(set(names)) != len(names):
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with np.load(io.BytesIO(data), allow_pickle=False) as archive:
                arrays = {key: archive[key] for key in archive.files}
        if sorted(arrays) != sorted(("format",) + tuple(FIELD_SPECS)):
            return None
        text = arrays["format"]
        if text.shape != () or text.dtype.kind != "U" or str(text) != FORMAT:
            return None
        return ScratchSet(**{key: arrays[key].astype(arrays[key].dtype.newbyteorder("="))
                             for key in FIELD_SPECS})
    except Exception:  # noqa: BLE001 (the reference: anything numpy refuses counts as refused)
        return None


# ------------------------------------------------------------------- the test
def outcome(data: bytes) -> ScratchSet | ScratchFormatError:
    try:
        return scratch.loads(data)
    except ScratchFormatError as error:
        return error


def run_fuzz(originals, cases: int, seed: int) -> dict[str, int]:
    """Mutate ``cases`` files; return how many ended in each outcome (for the assertion message)."""
    rng = np.random.default_rng(seed)
    tally = {"refused": 0, "equal": 0}
    for case in range(cases):
        original, data = originals[case % len(originals)]
        if rng.random() < 0.6:
            mutation = BYTE_MUTATIONS[int(rng.integers(len(BYTE_MUTATIONS)))]
            mutated = mutation(data, rng)
            expected = original
        else:
            mutation = STRUCTURAL_MUTATIONS[int(rng.integers(len(STRUCTURAL_MUTATIONS)))]
            mutated = _rezip(mutation(_members(data), rng))
            expected = numpy_reading(mutated)
        try:
            result = outcome(mutated)
        except Exception as error:  # noqa: BLE001 (any other type is the failure this test looks for)
            pytest.fail(f"case {case} ({mutation.__name__}): {type(error).__name__} leaked: {error}")
        if isinstance(result, ScratchFormatError):
            tally["refused"] += 1
            assert mutation in BYTE_MUTATIONS or expected is None, \
                f"case {case} ({mutation.__name__}): refused a file numpy reads as a valid set: {result}"
        else:
            tally["equal"] += 1
            assert expected is not None and result == expected, \
                f"case {case} ({mutation.__name__}): read a set that differs from the expected one"
    return tally


def test_mutated_files_give_format_errors_or_the_set_they_hold(originals):
    tally = run_fuzz(originals, cases=600, seed=SEED)
    # Both outcomes occur: the fuzzing reaches past the first check and also hits harmless bytes.
    assert tally["refused"] > 300 and tally["equal"] > 30, tally


@pytest.mark.slow
def test_many_mutated_files(originals):
    tally = run_fuzz(originals, cases=20_000, seed=SEED + 1)
    assert tally["refused"] > 10_000, tally


def test_every_mutation_kind_is_exercised(originals):
    rng = np.random.default_rng(SEED)
    _, data = originals[0]
    for mutation in BYTE_MUTATIONS:
        assert mutation(data, rng) != data
    members = _members(data)
    for mutation in STRUCTURAL_MUTATIONS:
        assert any(mutation(members, rng) != members for _ in range(5))
