"""Render parts: one render split over machines (``--chunk K/N``) and merged back bit for bit.

A part renders the contiguous chunks :func:`~mitsuba_bridge.render.schedule.part_range`
``(K, N, chunks)`` of the render's schedule and writes an EXR whose RGBA is the
mean of its own samples (viewable as it is) and whose extra channels hold the
exact float64 sums of its summation-tree nodes (each as two uint32 channels,
``sum.L<level>.N<index>.<R|G|B|A>.hi/.lo``).  Header attributes identify the
render: scene fingerprint, variant, software, the scratch tables it rendered
with (:func:`tables_fingerprint`), size, spp, seed, the schedule's digest, and
the part's chunks and sample count (``samples``).

:func:`merge_parts` refuses parts of different renders, duplicated or missing
chunks, and otherwise adds the nodes along the same tree as a single machine,
so the merged image equals the single-machine image bit for bit.

**Nothing in a part is trusted.**  EXR headers carry no checksum, so before any
pixel is read every header number is checked against the others and against
the image (:func:`read_header`): the identity's types and ranges, the schedule
recomputed from spp, pixels and seed (its chunk count and digest), the part's
chunk range, its sample count (the sum of its chunks' spp), its node list (the
tree nodes of its range), the data window (the image size) and the channel list
(exactly RGBA and the nodes' sums, full resolution).  A part also carries a
``checksum`` (SHA-256 of its own attributes and every pixel): a part damaged in
storage or transfer, a flipped bit of a stored sum included, is refused.  The memory a merge needs
is then checked against what the process is allowed
(:mod:`mitsuba_bridge.device.memory`) before any part's pixels are read.  Read
back, the sums must be uint32 halves of finite float64 values whose total,
divided by the part's samples, is the part's own float32 RGBA (to float32
rounding): a NaN, infinite or 1e308 sum, or sums that do not belong to the
image beside them, are refused.  Every refusal is one :class:`PartError`
naming the file and the field.
"""
from __future__ import annotations

import contextlib
import hashlib
import numbers
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from ..device.memory import NotEnoughMemory, check_memory, format_bytes
from ..files.regular import NotARegularFile, open_regular
from .schedule import (MAX_CHUNKS, Chunk, Node, PairwiseSum, ScheduleError, root, sample_schedule, schedule_sizes,
                       tree_nodes, tree_sum)

__all__ = ["PART_FORMAT", "RenderIdentity", "PartError", "scene_fingerprint", "schedule_digest", "software",
           "recording_tables", "tables_fingerprint", "write_part", "read_header", "read_part", "merge_parts"]

#: ``format`` attribute of a part file (2: the identity names the scratch tables).
PART_FORMAT = "scratch-iridescence/render-part/2"
_RGBA = "RGBA"
_EXR_MAGIC = bytes([0x76, 0x2F, 0x31, 0x01])
#: Longest text attribute of an identity (digests and version strings are far shorter).
_MAX_TEXT = 256
#: Relative agreement of a part's sums with its own RGBA: float32 rounding of the mean (2**-24), with room for the
#: order of the float64 additions.
_RGBA_TOLERANCE = 1e-6


class PartError(ValueError):
    """A part file that cannot be merged (names the file and what is wrong)."""


@dataclass(frozen=True)
class RenderIdentity:
    """What makes two parts belong to the same render; every field must agree."""

    scene: str      #: :func:`scene_fingerprint` of the exported folder
    variant: str    #: Mitsuba variant (CPU and GPU round differently)
    software: str   #: Mitsuba and Dr.Jit versions (kernels may change between releases)
    width: int
    height: int
    spp: int        #: samples per pixel of the whole render
    seed: int
    chunk_count: int
    schedule: str   #: :func:`schedule_digest` of the whole schedule
    tables: str     #: :func:`tables_fingerprint` of the scratch tables rendered with (code version included)


#: The header attributes a part writes beside EXR's own, all covered by its ``checksum``.
_OWN_ATTRIBUTES = ("format", "samples", "chunkFirst", "chunkStop", "nodes",
                   *(f"render.{field.name}" for field in fields(RenderIdentity)))


def scene_fingerprint(folder, entries: tuple[str, ...]) -> str:
    """SHA-256 (hex) of the named entries of an export folder: names, sizes and bytes of every file."""
    from ..files.entries import entry_files

    folder = Path(folder)
    digest = hashlib.sha256()
    for path in entry_files(folder, entries):
        digest.update(f"{path.relative_to(folder).as_posix()}\0{path.stat().st_size}\0".encode())
        with open_regular(path) as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


def software() -> str:
    """The Mitsuba and Dr.Jit versions that render here."""
    import drjit
    import mitsuba

    return f"mitsuba {mitsuba.__version__}, drjit {drjit.__version__}"


def schedule_digest(chunks: list[Chunk]) -> str:
    """A short digest of every chunk's spp and seed."""
    text = ";".join(f"{c.spp}:{c.seed}" for c in chunks)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@contextlib.contextmanager
def recording_tables():
    """Around a scene's load: yields a list of the scratch tables its BSDFs took or built
    (for :func:`tables_fingerprint`)."""
    from ..bsdf import persistent

    with persistent.recording() as found:
        yield found


def tables_fingerprint(recorded: list) -> str:
    """A digest of the scratch tables a scene renders with (:func:`recording_tables`): their contents and the code
    that built and reads them; ``"none"`` for a scene without scratches.  Parts rendered from other tables (another
    version of the add-on, a damaged cache) carry another fingerprint, and ``merge`` refuses to combine them."""
    from ..bsdf import persistent

    return persistent.fingerprint(recorded) if recorded else "none"


def _node_channel(node: Node, channel: str, half: str) -> str:
    return f"sum.L{node.level}.N{node.index}.{channel}.{half}"


def write_part(path, identity: RenderIdentity, sums: PairwiseSum, samples: int) -> Path:
    """Write a part file (atomically) from the accumulator of its chunks; ``samples`` is their spp sum."""
    from ..files.images import write_image

    nodes = sums.node_sums(identity.chunk_count)
    channels = {}
    for node, value in nodes.items():
        bits = np.ascontiguousarray(value, dtype=np.float64).view(np.uint64)
        for c, name in enumerate(_RGBA):
            channels[_node_channel(node, name, "hi")] = (bits[..., c] >> np.uint64(32)).astype(np.uint32)
            channels[_node_channel(node, name, "lo")] = (bits[..., c] & np.uint64(0xFFFFFFFF)).astype(np.uint32)
    header = {"format": PART_FORMAT, "samples": int(samples), "chunkFirst": sums.start,
              "chunkStop": sums.start + sums.count,
              "nodes": ",".join(f"{n.level}.{n.index}" for n in nodes),
              **{f"render.{key}": value for key, value in asdict(identity).items()}}
    mean = (sums.total() / samples).astype(np.float32)
    pixels = {**{name: mean[..., c] for c, name in enumerate(_RGBA)}, **channels}
    header["checksum"] = _checksum(header, pixels)
    return write_image(path, mean, header=header, channels=channels)


def _checksum(header: dict, pixels: dict) -> str:
    """SHA-256 of a part's own header attributes and of every channel's pixels: EXR itself has no checksum, so a part
    damaged in storage or transfer (a flipped bit in a stored sum) would otherwise merge into a wrong image."""
    digest = hashlib.sha256()
    own = {key: header.get(key) for key in sorted(_OWN_ATTRIBUTES)}
    digest.update(repr(sorted(own.items())).encode())
    for name in sorted(pixels):
        values = np.asarray(pixels[name])
        digest.update(f"{name}:{values.dtype.kind}{values.dtype.itemsize}:{values.shape}".encode())
        digest.update(np.ascontiguousarray(values, dtype=values.dtype.newbyteorder("<")).tobytes())
    return digest.hexdigest()


@dataclass(frozen=True)
class PartHeader:
    """A part's header, every number checked against the others (:func:`read_header`)."""

    path: Path
    identity: RenderIdentity
    chunks: range
    samples: int
    nodes: tuple[Node, ...]
    node_samples: dict  #: Node -> samples per pixel its sums hold
    checksum: str  #: what :func:`_checksum` of its attributes and pixels must give
    attributes: dict  #: the part's own header attributes, as read


@dataclass(frozen=True)
class Part:
    path: Path
    identity: RenderIdentity
    chunks: range
    samples: int
    nodes: dict


def _open(path: Path):
    try:
        return open_regular(path)
    except FileNotFoundError:
        raise PartError(f"{path}: no such file") from None
    except NotARegularFile as error:
        raise PartError(str(error)) from None
    except OSError as error:
        raise PartError(f"{path}: cannot be read ({error.strerror or error})") from None


def _whole(path: Path, header: dict, name: str, low: int, high: int) -> int:
    value = header.get(name)
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise PartError(f"{path}: header field {name} is {value!r}, not a whole number")
    if not low <= value <= high:
        raise PartError(f"{path}: header field {name} is {value}, outside {low}..{high}")
    return int(value)


def _text(path: Path, header: dict, name: str) -> str:
    value = header.get(name)
    if not isinstance(value, str) or not 0 < len(value) <= _MAX_TEXT:
        raise PartError(f"{path}: header field {name} is {str(value)[:40]!r}, not a short text")
    return value


def read_header(path) -> PartHeader:
    """A part file's header, every number checked against the others and the image size (module docstring).

    Reads the header only: nothing is allocated for pixels.  Raises
    :class:`PartError` naming the file and the field.
    """
    import OpenEXR

    path = Path(path)
    with _open(path) as stream:
        if stream.read(4) != _EXR_MAGIC:  # checked here: OpenEXR would also print its own complaint
            raise PartError(f"{path}: not a render part (not an EXR file)")
        stream.seek(0)
        with _openexr_messages(path):
            header = dict(OpenEXR.File(stream, header_only=True).header())
            return _check_header(path, header)


@contextlib.contextmanager
def _openexr_messages(path: Path):
    """Run OpenEXR calls with what its libraries print (C errors on stderr, the binding's warnings on stdout)
    captured, and turn any failure into one :class:`PartError` that quotes them: the command line prints one line
    per error, nothing else."""
    import sys
    import tempfile

    import io

    captured, printed = tempfile.TemporaryFile(), io.StringIO()
    saved = {}
    for stream, number in ((sys.stdout, 1), (sys.stderr, 2)):
        try:
            stream.flush()
            saved[number] = os.dup(number)
        except (OSError, ValueError, AttributeError):  # no such descriptor (an embedding host): leave it
            continue
        os.dup2(captured.fileno(), number)
    try:
        # (the binding prints its warnings through Python's sys.stdout, the C library to the descriptors)
        with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
            yield
    except PartError:
        raise
    except (OSError, RuntimeError, ValueError, TypeError, KeyError, AttributeError, MemoryError) as error:
        captured.write(printed.getvalue().encode())
        raise PartError(f"{path}: not a readable render part ({type(error).__name__}: "
                        f"{_first_line(error, captured)})") from None
    finally:
        _flush_c_streams()  # (the binding writes through C++'s cout, buffered in C's stdout until flushed)
        for number, descriptor in saved.items():
            os.dup2(descriptor, number)
            os.close(descriptor)
        captured.close()


def _flush_c_streams() -> None:
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None)
        libc.fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library to ask (Windows' is per module): nothing buffered there
        pass


def _first_line(error: BaseException, captured) -> str:
    captured.seek(0)
    said = captured.read(4096).decode("utf-8", "replace").strip().splitlines()
    text = str(error).strip().splitlines()
    return (text[0] if text else "") + (f"; OpenEXR: {said[0].split(': ', 1)[-1]}" if said else "")


def _check_header(path: Path, header: dict) -> PartHeader:
    if header.get("format") != PART_FORMAT:
        older = str(header.get("format", "")).startswith("scratch-iridescence/render-part/")
        raise PartError(f"{path}: " + ("a render part of an older version: render the parts again with this one"
                                       if older else "not a render part (render with --chunk K/N to make parts)"))
    texts = {name: _text(path, header, f"render.{name}") for name in ("scene", "variant", "software", "schedule",
                                                                        "tables")}
    width = _whole(path, header, "render.width", 1, 1 << 31)
    height = _whole(path, header, "render.height", 1, 1 << 31)
    spp = _whole(path, header, "render.spp", 1, 1 << 62)
    seed = _whole(path, header, "render.seed", 0, (1 << 32) - 1)
    count = _whole(path, header, "render.chunk_count", 1, MAX_CHUNKS)
    identity = RenderIdentity(width=width, height=height, spp=spp, seed=seed, chunk_count=count, **texts)
    chunks = _schedule(path, identity)
    first = _whole(path, header, "chunkFirst", 0, count - 1)
    stop = _whole(path, header, "chunkStop", first + 1, count)
    samples = _whole(path, header, "samples", 1, spp)
    if samples != sum(chunk.spp for chunk in chunks[first:stop]):
        raise PartError(f"{path}: header field samples is {samples}, but chunks {first}-{stop - 1} of this schedule "
                        f"hold {sum(chunk.spp for chunk in chunks[first:stop])}")
    nodes = tuple(tree_nodes(range(first, stop), count))
    if header.get("nodes") != ",".join(f"{n.level}.{n.index}" for n in nodes):
        raise PartError(f"{path}: header field nodes is {str(header.get('nodes'))[:60]!r}, not the sums of chunks "
                        f"{first}-{stop - 1}")
    window = header.get("dataWindow")
    try:
        corners = [int(v) for corner in window for v in corner]
    except (TypeError, ValueError):
        corners = None
    if corners != [0, 0, width - 1, height - 1]:
        raise PartError(f"{path}: its pixels span {window!r}, not the {width} x {height} image its header names")
    expected = set(_RGBA) | {_node_channel(node, c, half) for node in nodes for c in _RGBA for half in ("hi", "lo")}
    channels = header.get("channels") or []
    names = [getattr(channel, "name", None) for channel in channels]
    if sorted(map(str, names)) != sorted(expected) or any(
            (getattr(channel, "xSampling", 0), getattr(channel, "ySampling", 0)) != (1, 1) for channel in channels):
        raise PartError(f"{path}: its channels are not RGBA and the sums of its {len(nodes)} tree nodes")
    node_samples = {node: sum(chunk.spp for chunk in chunks[node.start:min(node.stop, count)]) for node in nodes}
    checksum = _text(path, header, "checksum")
    attributes = {key: header.get(key) for key in _OWN_ATTRIBUTES}
    return PartHeader(path, identity, range(first, stop), samples, nodes, node_samples, checksum, attributes)


def _schedule(path: Path, identity: RenderIdentity) -> list[Chunk]:
    """The render's schedule, recomputed (CPU or GPU schedule, whichever the part's digest names)."""
    pixels = identity.width * identity.height
    for gpu in (False, True):
        try:
            # (the sizes first: a header naming 2³¹ spp of another chunk count costs no list of 10⁵ chunks)
            if len(schedule_sizes(identity.spp, pixels, gpu=gpu)) != identity.chunk_count:
                continue
            chunks = sample_schedule(identity.spp, pixels, identity.seed, gpu=gpu)
        except ScheduleError as error:
            raise PartError(f"{path}: its header names an impossible render ({error})") from None
        if schedule_digest(chunks) == identity.schedule:
            return chunks
    raise PartError(f"{path}: header fields chunk_count {identity.chunk_count} and schedule {identity.schedule!r} "
                    f"are not the schedule of {identity.spp} spp over {identity.width} x {identity.height} pixels "
                    f"with seed {identity.seed}")


def _read_sums(header: PartHeader) -> dict:
    """The node sums of a part whose header is checked, each checked against the part's own RGBA."""
    import OpenEXR

    path = header.path
    with _open(path) as stream, _openexr_messages(path):
        with OpenEXR.File(stream, separate_channels=True) as file:
            return _checked_sums(header, file.channels())


def _checked_sums(header: PartHeader, channels: dict) -> dict:
    import OpenEXR

    path, shape = header.path, (header.identity.height, header.identity.width)
    for name, channel in channels.items():
        wanted = OpenEXR.FLOAT if name in _RGBA else OpenEXR.UINT
        if channel.type() != wanted or np.shape(channel.pixels) != shape:
            raise PartError(f"{path}: channel {name} holds {channel.type()} {np.shape(channel.pixels)}, not "
                            f"{wanted} {shape}")
    nodes = {}
    for node in header.nodes:
        halves = [[np.asarray(channels[_node_channel(node, c, half)].pixels, dtype=np.uint64) for c in _RGBA]
                  for half in ("hi", "lo")]
        value = ((np.stack(halves[0], axis=-1) << np.uint64(32)) | np.stack(halves[1], axis=-1)).view(np.float64)
        del halves
        if not np.all(np.isfinite(value)):
            raise PartError(f"{path}: the sums of chunks {node.start}-{min(node.stop, header.identity.chunk_count) - 1}"
                            " hold NaN or infinite values")
        nodes[node] = value
    if header.checksum != _checksum(header.attributes, {name: channel.pixels for name, channel in channels.items()}):
        raise PartError(f"{path}: damaged: its checksum does not match its header and pixels")
    rgba = np.stack([np.asarray(channels[c].pixels, dtype=np.float64) for c in _RGBA], axis=-1)
    if not np.all(np.isfinite(rgba)):
        raise PartError(f"{path}: its image holds NaN or infinite values")
    total = PairwiseSum.fold([nodes[node] for node in header.nodes]) / header.samples
    off = np.abs(total - rgba) > _RGBA_TOLERANCE * np.abs(rgba) + 1e-37
    if np.any(off):
        raise PartError(f"{path}: its sums are not the image beside them ({int(off.sum()):,} values differ): a "
                        "damaged or edited part")
    return nodes


def read_part(path) -> Part:
    """A part file's identity, chunks and node sums; :class:`PartError` if it is not a readable, consistent part."""
    header = read_header(path)
    return Part(header.path, header.identity, header.chunks, header.samples, _read_sums(header))


def _ranges(indices: list[int]) -> str:
    """'3-5, 8' for [3, 4, 5, 8]."""
    groups, start = [], None
    for i, value in enumerate(indices):
        if start is None:
            start = value
        if i + 1 == len(indices) or indices[i + 1] != value + 1:
            groups.append(f"{start}" if start == value else f"{start}-{value}")
            start = None
    return ", ".join(groups)


def merge_parts(paths) -> tuple[np.ndarray, RenderIdentity]:
    """The (H, W, 4) float32 image of a render from all its parts, bit for bit the single-machine image.

    Raises :class:`PartError` when a file is not a consistent part (module
    docstring), when the parts belong to different renders (naming the field
    and both files), when a chunk is held by two parts or by none, or when the
    merge would need more memory than the process is allowed.
    """
    headers = [read_header(path) for path in paths]
    if not headers:
        raise PartError("no parts given")
    first = headers[0]
    for part in headers[1:]:
        for field in fields(RenderIdentity):
            value, expected = getattr(part.identity, field.name), getattr(first.identity, field.name)
            if value != expected:
                raise PartError(f"{part.path} and {first.path} are parts of different renders: {field.name} "
                                f"{value!r} vs {expected!r}")
    count = first.identity.chunk_count
    owner: dict[int, Path] = {}
    for part in headers:
        clash = [i for i in part.chunks if i in owner]
        if clash:
            raise PartError(f"chunks {_ranges(clash)} are in both {owner[clash[0]]} and {part.path}")
        owner.update({i: part.path for i in part.chunks})
    missing = [i for i in range(count) if i not in owner]
    if missing:
        raise PartError(f"chunks {_ranges(missing)} of {count} are missing: no part holds them")
    _check_merge_memory(headers)
    stored = {}
    for part in headers:
        stored.update(_read_sums(part))
    total = tree_sum(root(count), count, stored.get)
    return (total / first.identity.spp).astype(np.float32), first.identity


def _check_merge_memory(headers: list[PartHeader]) -> None:
    """Refuse a merge whose sums (float64 RGBA per node, all kept) and one part's channels read at once do not fit."""
    pixels = headers[0].identity.width * headers[0].identity.height
    kept = sum(len(part.nodes) for part in headers) * 32 * pixels
    reading = max(len(part.nodes) for part in headers) * (32 + 32 + 32) * pixels + 3 * 16 * pixels
    try:
        check_memory(kept + reading + 48 * pixels, f"merging {len(headers)} parts of a "
                     f"{headers[0].identity.width} x {headers[0].identity.height} render",
                     detail=f"node sums {format_bytes(kept)}", advice="merge on a machine with more memory")
    except NotEnoughMemory as error:
        raise PartError(str(error)) from None
