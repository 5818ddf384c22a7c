"""The fixed sample schedule of a render and the order its chunks are summed in.

A render of ``spp`` samples per pixel is split into *chunks*, one
``mi.render(scene, spp=chunk.spp, seed=chunk.seed)`` call each.  The split
depends only on (spp, pixel count, seed), never on time or machine load, so
the same scene, spp and seed always give the same image, bit for bit, on one
machine or spread over many (``--chunk K/N`` and ``merge`` on the command line).

* **Sizes.**  Every chunk takes ``per_chunk`` samples per pixel (:func:`chunk_spp`),
  the largest power of two whose ``pixels × per_chunk`` stays within
  :data:`MAX_SAMPLES_PER_PASS` (what one call renders before Esc is looked at
  again, see docs/rendering.md); the remainder goes in chunks of
  :data:`SMALL_CHUNK_SPP` and then of 2 and 1.  So at most four sizes (four
  compiled kernels) serve a render.  A render of fewer spp than a full chunk
  takes the largest power of two within its spp as its full size (64 spp at
  256² is one chunk of 64, not sixteen of 4).
* **Why not smaller chunks.**  A pixel's samples are consecutive lanes, so a
  chunk of fewer spp than the SIMD packet (16 lanes with AVX-512) puts
  several pixels in one packet, whose lanes then diverge in the scratch
  BSDF's loops and branches: measured on the Fig. 9 grating at 720 × 450
  (docs/rendering.md, What a chunk's size costs), 256 spp in chunks of 2, 4, 8 and
  16+ spp rendered at 0.86, 0.92, 0.96 and 1 times the samples per core-second.
* **Why these sizes: one pixel, one thread.**  Mitsuba adds a pixel's samples
  into the film with atomic float additions, so a pixel whose samples were
  split between two CPU threads gets them added in whatever order the threads
  ran (the last bits change from run to run).  Dr.Jit's LLVM backend (see its
  ``LLVMThreadState::launch``) hands each thread blocks of 16 384 consecutive
  samples once a call holds more than ``16 384 × 2 × threads`` samples, and
  otherwise blocks that are multiples of its SIMD width (4, 8 or 16).  A
  pixel's samples are consecutive, so they stay in one block when the chunk's
  spp is at most 4, or when it divides 16 384 and the call is large (full
  chunks: more than 2**21 samples, large for up to 64 threads).  On a GPU
  (``gpu=True``) a full chunk takes at most :data:`GPU_CHUNK_SPP` samples per
  pixel: a pixel's samples are then neighbouring lanes of one 32-lane warp.
  Measured on an H200 (docs/rendering.md): chunks of up to 32 spp rendered the
  same bits every time, chunks of 64 and more did not (a pixel over several
  warps gets their atomic additions in whatever order they ran).  The schedule is
  then another one (its digest differs), and split renders merge only parts
  of one variant anyway.
* **Sizes every sampler takes as they are.**  Mitsuba's stratified samplers round a
  render call's spp to the counts they can stratify, and a chunk must render exactly
  the samples its weight says.  The renderer's samplers (``independent``, the default,
  and ``multijitter``; docs/rendering.md, The sampler) both take 1, 2, 4, 8 and 16 and
  every even power of two (64, 256, ... 16 384), not 32, 128, 512, 2 048 or 8 192
  (``multijitter`` would make 32 spp 35): a full chunk of such a size takes half of it
  (:func:`stratified_size`).  Every size of a schedule is one of :data:`SAMPLER_SIZES`.
* **Seeds.**  Chunk ``i`` uses :func:`pass_seed` ``(seed, i)``: distinct
  32-bit seeds, so chunks draw independent samples (a stratified sampler stratifies
  within a chunk; chunks add like independent estimates).
* **Sum.**  Chunk ``i`` contributes ``float64(image_i) × spp_i`` (exact: a
  float32 times an integer below 2**29 fits in a float64).  The contributions
  are added pairwise along a fixed binary tree over the chunk indices
  (:class:`PairwiseSum`), and any contiguous run of chunks is a handful of
  whole tree nodes (:func:`tree_nodes`).  A machine that renders a run of
  chunks stores its node sums; the merge adds the nodes exactly as a single
  machine would have, so the result is the same bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["MAX_SAMPLES_PER_PASS", "MAX_CHUNKS", "SMALL_CHUNK_SPP", "GPU_CHUNK_SPP", "ScheduleError", "Chunk", "Node",
           "SAMPLER_SIZES", "sample_schedule", "schedule_sizes", "chunk_spp", "stratified_size", "pass_seed",
           "part_range", "tree_nodes", "tree_sum", "root", "PairwiseSum"]

#: Samples per ``mi.render`` call (a chunk): 720 × 450 takes 16 spp (one pixel per 16-lane SIMD packet),
#: 1080p 4; Esc waits for the chunk in flight (docs/rendering.md, What a chunk's size costs).
MAX_SAMPLES_PER_PASS = 1 << 23
#: More chunks than this is a mistake (hours of per-call overhead alone), refused before anything starts.
MAX_CHUNKS = 1 << 20
#: Chunks this small never split a pixel between threads (Dr.Jit's narrowest SIMD packet holds 4 samples).
SMALL_CHUNK_SPP = 4
#: On a GPU, full chunks take at most this many spp: a pixel's samples stay in one 32-lane warp.
GPU_CHUNK_SPP = 32
#: The chunk sizes every sampler the renderer writes takes as they are (``multijitter``: 2**k for k <= 4 or
#: even k; ``independent``: any): a schedule is made of these only.
SAMPLER_SIZES = frozenset(1 << k for k in range(15) if k <= 4 or k % 2 == 0)
#: Dr.Jit's LLVM work block (``jit_llvm_block_size``): full chunks take at most this many spp.
_BLOCK_SAMPLES = 16384
#: Calls above this hand out whole 16 384-sample blocks on machines with up to 64 threads.
_LARGE_CALL_SAMPLES = _BLOCK_SAMPLES * 2 * 64


class ScheduleError(ValueError):
    """A render that cannot be scheduled (no samples, no pixels, far too many chunks, a bad split)."""


@dataclass(frozen=True)
class Chunk:
    """One ``mi.render`` call of a schedule: its position, samples per pixel and sampler seed."""

    index: int
    spp: int
    seed: int


@dataclass(frozen=True, order=True)
class Node:
    """A node of the summation tree: chunks ``[index·2**level, (index+1)·2**level)`` (clipped to the schedule)."""

    level: int
    index: int

    @property
    def start(self) -> int:
        return self.index << self.level

    @property
    def stop(self) -> int:
        return (self.index + 1) << self.level


def pass_seed(seed: int, index: int) -> int:
    """A distinct 32-bit sampler seed per (user seed, chunk index) pair."""
    return (int(seed) * 0x9E3779B1 + int(index)) & 0xFFFFFFFF


def stratified_size(spp: int) -> int:
    """The largest of :data:`SAMPLER_SIZES` within ``spp`` (a power of two from 1 to 16 384): ``spp`` itself,
    or half of it where the stratified sampler would round it up (32 → 16, 8 192 → 4 096)."""
    size = 1 << (max(int(spp), 1).bit_length() - 1)
    while size not in SAMPLER_SIZES:
        size >>= 1
    return size


def chunk_spp(pixels: int, *, gpu: bool = False) -> int:
    """Samples per pixel of a full chunk of a ``pixels``-pixel film (see the module docstring).

    The largest of :data:`SAMPLER_SIZES` ``s ≤ 16 384`` with ``pixels × s ≤ MAX_SAMPLES_PER_PASS``;
    when that call would still hold no more than :data:`_LARGE_CALL_SAMPLES`
    samples (films under 129 pixels), :data:`SMALL_CHUNK_SPP`.  ``gpu``: at most
    :data:`GPU_CHUNK_SPP` instead (a pixel in one 32-lane warp or SIMD group; a GPU has no CPU threads' blocks).
    """
    budget = max(1, MAX_SAMPLES_PER_PASS // max(int(pixels), 1))
    full = stratified_size(min(budget, _BLOCK_SAMPLES))
    if gpu:
        return stratified_size(min(full, GPU_CHUNK_SPP))
    if full > SMALL_CHUNK_SPP and int(pixels) * full <= _LARGE_CALL_SAMPLES:
        return SMALL_CHUNK_SPP
    return full


def sample_schedule(spp: int, pixels: int, seed: int = 0, *, gpu: bool = False) -> list[Chunk]:
    """The chunks of a render of ``spp`` samples per pixel over ``pixels`` pixels.

    Parameters
    ----------
    spp : int
        Samples per pixel of the whole render (at least 1).
    pixels : int
        Pixels of the rendered film (the crop window's width × height).
    seed : int
        The user's seed; each chunk gets its own seed derived from it.
    gpu : bool
        The schedule of a GPU (CUDA or Metal) render: full chunks of at most
        :data:`GPU_CHUNK_SPP` spp (:func:`chunk_spp`).

    Returns
    -------
    list of Chunk
        ``Chunk(index, spp, seed)`` in rendering order; their ``spp`` sum to
        ``spp``.  The same arguments always give the same list.

    Examples
    --------
    >>> [c.spp for c in sample_schedule(100, 720 * 450)]
    [16, 16, 16, 16, 16, 16, 4]
    >>> [c.spp for c in sample_schedule(8192 + 11, 32 * 24)]
    [4096, 4096, 4, 4, 2, 1]
    >>> [c.spp for c in sample_schedule(100, 32 * 24, gpu=True)]
    [16, 16, 16, 16, 16, 16, 4]
    """
    sizes = schedule_sizes(spp, pixels, gpu=gpu)
    return [Chunk(index, size, pass_seed(seed, index)) for index, size in enumerate(sizes)]


def schedule_sizes(spp: int, pixels: int, *, gpu: bool = False) -> list[int]:
    """The samples per pixel of :func:`sample_schedule`'s chunks, in order, without their seeds: a plain list
    of ints (a check of a part's header compares its length before building up to a million chunks)."""
    spp, pixels = int(spp), int(pixels)
    if spp < 1:
        raise ScheduleError(f"spp must be at least 1, got {spp}")
    if pixels < 1:
        raise ScheduleError(f"the film must have at least one pixel, got {pixels}")
    full = chunk_spp(pixels, gpu=gpu)
    within = stratified_size(spp)  # the largest size within spp
    if SMALL_CHUNK_SPP < within < full and (gpu or pixels * within > _LARGE_CALL_SAMPLES):
        full = within  # fewer spp than a full chunk: one chunk of the most it can take, not 4-spp ones
    count = spp // full + (spp % full) // SMALL_CHUNK_SPP + 2
    if count > MAX_CHUNKS:
        raise ScheduleError(f"{spp:,} spp over {pixels:,} pixels would take {count - 2:,} or more render calls "
                         f"(at most {MAX_CHUNKS:,}): lower the samples")
    sizes = [full] * (spp // full)
    remainder = spp % full
    if full > SMALL_CHUNK_SPP:
        sizes += [SMALL_CHUNK_SPP] * (remainder // SMALL_CHUNK_SPP)
        remainder %= SMALL_CHUNK_SPP
    sizes += [1 << bit for bit in reversed(range(remainder.bit_length())) if remainder >> bit & 1]
    return sizes


def part_range(part: int, parts: int, chunk_count: int) -> range:
    """Chunk indices of part ``part`` (1-based) of ``parts`` contiguous, near-equal parts."""
    if not 1 <= part <= parts:
        raise ScheduleError(f"part {part} of {parts}: expected 1 <= part <= {parts}")
    if parts > chunk_count:
        plural = "s" * (chunk_count != 1)
        raise ScheduleError(f"this render has {chunk_count} chunk{plural}: it splits into at most {chunk_count} "
                         f"part{plural}, not {parts}")
    return range((part - 1) * chunk_count // parts, part * chunk_count // parts)


def tree_nodes(chunks: range, chunk_count: int) -> list[Node]:
    """The fewest whole tree nodes that cover the contiguous run ``chunks`` of a ``chunk_count``-chunk schedule.

    A node reaching past the schedule's end counts as whole when its chunks
    inside the schedule all lie in ``chunks``.
    """
    nodes, start = [], chunks.start
    while start < chunks.stop:
        level = 0
        # Grow while the node stays aligned and ends inside the run (or the schedule).
        while start % (1 << (level + 1)) == 0 and min(start + (1 << (level + 1)), chunk_count) <= chunks.stop \
                and start + (1 << level) < chunk_count:
            level += 1
        nodes.append(Node(level, start >> level))
        start = min(start + (1 << level), chunk_count)
    return nodes


def tree_sum(node: Node, chunk_count: int, value: Callable[[Node], np.ndarray | None]) -> np.ndarray:
    """The sum of ``node``: ``value(node)`` when that is known (not None), else its children's sum.

    A node whose right child lies past the schedule's end is its left child.
    Raises ``KeyError`` naming the first chunk whose value is missing.
    """
    known = value(node)
    if known is not None:
        return known
    if node.level == 0:
        raise KeyError(node.index)
    left, right = Node(node.level - 1, 2 * node.index), Node(node.level - 1, 2 * node.index + 1)
    if right.start >= chunk_count:
        return tree_sum(left, chunk_count, value)
    return tree_sum(left, chunk_count, value) + tree_sum(right, chunk_count, value)


def root(chunk_count: int) -> Node:
    """The node that covers the whole schedule."""
    return Node(max(chunk_count - 1, 0).bit_length(), 0)


class PairwiseSum:
    """Chunk contributions added in schedule order along the fixed tree of :func:`tree_sum`.

    Starts at chunk ``start`` (a part of a render) and holds at most
    2·log2(chunks) + 1 partial sums, each a complete tree node.  :meth:`total`
    of all chunks equals ``tree_sum(root)`` bit for bit, and :meth:`node_sums`
    gives the nodes a part file stores.  The contributions may be NumPy arrays
    or Dr.Jit arrays (a render keeps them on the device,
    :func:`~mitsuba_bridge.render.passes.render_chunks`): the sums are then Dr.Jit's
    float64 additions, the same bits; :meth:`total` and :meth:`node_sums` are
    NumPy arrays either way.
    """

    def __init__(self, start: int = 0):
        self._stack: list[tuple[Node, np.ndarray]] = []
        self.start = int(start)
        self.count = 0

    def add(self, contribution: np.ndarray) -> None:
        """Add the next chunk's contribution (float64, ``image × spp``; NumPy or Dr.Jit)."""
        node, value = Node(0, self.start + self.count), contribution
        self.count += 1
        while self._stack and self._stack[-1][0].level == node.level and self._stack[-1][0].index == node.index - 1 \
                and node.index % 2 == 1:
            left, left_value = self._stack.pop()
            node, value = Node(node.level + 1, left.index >> 1), left_value + value
        self._stack.append((node, value))

    def total(self) -> np.ndarray:
        """The sum of the chunks added so far, folded right to left (as the tree adds them), as NumPy float64."""
        return np.asarray(self.fold(self.partials()), dtype=np.float64)

    def partials(self) -> tuple:
        """The partial sums held now, largest first (arrays that are never modified in place)."""
        return tuple(value for _, value in self._stack)

    def node_sums(self, chunk_count: int) -> dict[Node, np.ndarray]:
        """The sums of :func:`tree_nodes` of the chunks added so far (in a ``chunk_count``-chunk schedule),
        as NumPy float64 arrays."""
        run = range(self.start, self.start + self.count)
        inside = lambda node: [value for held, value in self._stack if node.start <= held.start < node.stop]
        return {node: np.asarray(self.fold(inside(node)), dtype=np.float64) for node in tree_nodes(run, chunk_count)}

    @staticmethod
    def fold(partials):
        """``partials[0] + (partials[1] + (... + partials[-1]))``: how the tree adds a run's partial sums
        (NumPy or Dr.Jit arrays, as added)."""
        if not partials:
            raise ValueError("no chunk added yet")
        value = partials[-1]
        for partial in reversed(partials[:-1]):
            value = partial + value
        return value
