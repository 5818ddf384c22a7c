"""Render parts: one render split over machines (``--chunk K/N``) and merged back bit for bit.

A part renders the contiguous chunks :func:`~mitsuba_bridge.render.schedule.part_range`
``(K, N, chunks)`` of the render's schedule and writes an EXR whose RGBA is the
mean of its own samples (viewable as it is) and whose extra channels hold the
exact float64 sums of its summation-tree nodes (each as two uint32 channels,
``sum.L<level>.N<index>.<R|G|B|A>.hi/.lo``).  Header attributes identify the
render: scene fingerprint, variant, size, spp, seed, the schedule's digest, and
the part's chunks and sample count (``samples``).

:func:`merge_parts` refuses parts of different renders, duplicated or missing
chunks, and otherwise adds the nodes along the same tree as a single machine,
so the merged image equals the single-machine image bit for bit.
"""
from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .schedule import Chunk, Node, PairwiseSum, root, tree_sum

__all__ = ["PART_FORMAT", "RenderIdentity", "PartError", "scene_fingerprint", "schedule_digest", "software",
           "write_part", "read_part", "merge_parts"]

#: ``format`` attribute of a part file.
PART_FORMAT = "scratch-iridescence/render-part/1"
_RGBA = "RGBA"
_EXR_MAGIC = bytes([0x76, 0x2F, 0x31, 0x01])


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


def scene_fingerprint(folder, entries: tuple[str, ...]) -> str:
    """SHA-256 (hex) of the named entries of an export folder: names, sizes and bytes of every file."""
    from ..files.entries import entry_files

    folder = Path(folder)
    digest = hashlib.sha256()
    for path in entry_files(folder, entries):
        digest.update(f"{path.relative_to(folder).as_posix()}\0{path.stat().st_size}\0".encode())
        with open(path, "rb") as stream:
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
    return write_image(path, mean, header=header, channels=channels)


@dataclass(frozen=True)
class Part:
    path: Path
    identity: RenderIdentity
    chunks: range
    samples: int
    nodes: dict


def read_part(path) -> Part:
    """A part file's identity, chunks and node sums; :class:`PartError` if it is not a readable part."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise PartError(f"{path}: no such file")
    with open(path, "rb") as stream:
        if stream.read(4) != _EXR_MAGIC:  # checked here: OpenEXR would also print its own complaint
            raise PartError(f"{path}: not a render part (not an EXR file)")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as file:
            header = file.header()
            if header.get("format") != PART_FORMAT:
                raise PartError(f"{path}: not a render part (render with --chunk K/N to make parts)")
            identity = RenderIdentity(**{name: header[f"render.{name}"]
                                         for name in RenderIdentity.__dataclass_fields__})
            channels = file.channels()
            nodes = {}
            for item in str(header["nodes"]).split(","):
                level, index = (int(v) for v in item.split("."))
                node = Node(level, index)
                halves = [[np.asarray(channels[_node_channel(node, c, half)].pixels, dtype=np.uint64)
                           for c in _RGBA] for half in ("hi", "lo")]
                bits = (np.stack(halves[0], axis=-1) << np.uint64(32)) | np.stack(halves[1], axis=-1)
                nodes[node] = bits.view(np.float64)
            return Part(path, identity, range(int(header["chunkFirst"]), int(header["chunkStop"])),
                        int(header["samples"]), nodes)
    except PartError:
        raise
    except (OSError, RuntimeError, KeyError, ValueError, TypeError) as error:
        raise PartError(f"{path}: not a readable render part ({type(error).__name__}: {error})") from None


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

    Raises :class:`PartError` when the parts belong to different renders
    (naming the field and both files), when a chunk is held by two parts or by
    none, or when a file is not a part.
    """
    parts = [read_part(path) for path in paths]
    if not parts:
        raise PartError("no parts given")
    first = parts[0]
    for part in parts[1:]:
        for field, value in asdict(part.identity).items():
            expected = getattr(first.identity, field)
            if value != expected:
                raise PartError(f"{part.path} and {first.path} are parts of different renders: {field} "
                                f"{value!r} vs {expected!r}")
    count = first.identity.chunk_count
    owner: dict[int, Path] = {}
    for part in parts:
        clash = [i for i in part.chunks if i in owner]
        if clash:
            raise PartError(f"chunks {_ranges(clash)} are in both {owner[clash[0]]} and {part.path}")
        owner.update({i: part.path for i in part.chunks})
    missing = [i for i in range(count) if i not in owner]
    if missing:
        raise PartError(f"chunks {_ranges(missing)} of {count} are missing: no part holds them")
    stored = {node: value for part in parts for node, value in part.nodes.items()}
    try:
        total = tree_sum(root(count), count, stored.get)
    except KeyError as missing:
        raise PartError(f"chunk {missing.args[0]}: its part file names the chunk but lacks its sums") from None
    return (total / first.identity.spp).astype(np.float32), first.identity
