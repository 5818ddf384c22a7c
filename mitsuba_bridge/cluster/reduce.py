"""The sums of a split render, added as tasks finish, in whatever order: the same bits as one machine.

Tasks return whole nodes of the schedule's summation tree
(:mod:`...render.schedule`).  :class:`NodeReducer` keeps them and adds two
siblings into their parent as soon as both are there (a parent whose right
child lies past the schedule's end is its left child), which is exactly the
addition :func:`~...render.schedule.tree_sum` and a single machine's
:class:`~...render.schedule.PairwiseSum` make for that node.  So the order in
which workers finish changes nothing, and memory holds at most about one
image per tree level plus the tasks that finished early.
"""
from __future__ import annotations

import numpy as np

from ..render.schedule import Node, root

__all__ = ["NodeReducer", "task_nodes"]


def task_nodes(chunk_count: int, chunks_per_task: int) -> list[range]:
    """The chunk runs of a render's tasks: aligned runs of ``chunks_per_task`` (a power of two) chunks.

    Aligned to the tree, each run is one whole node (the last one clipped), so a task returns one sum.
    """
    if chunks_per_task < 1 or chunks_per_task & (chunks_per_task - 1):
        raise ValueError(f"chunks per task must be a power of two, got {chunks_per_task}")
    return [range(start, min(start + chunks_per_task, chunk_count)) for start in range(0, chunk_count, chunks_per_task)]


class NodeReducer:
    """Node sums of one render in any order → the render's total sum (float64, spp-weighted)."""

    def __init__(self, chunk_count: int):
        self.chunk_count = int(chunk_count)
        self._root = root(self.chunk_count)
        self._held: dict[Node, np.ndarray] = {}
        self.chunks_done = 0

    def add(self, node: Node, value: np.ndarray) -> None:
        """Add one node's sum (each chunk must arrive exactly once, in one node)."""
        covered = range(node.start, min(node.stop, self.chunk_count))
        if any(held.start < covered.stop and covered.start < min(held.stop, self.chunk_count) for held in self._held):
            raise ValueError(f"node {node} overlaps a node already added")
        self._held[node] = value
        self.chunks_done += len(covered)
        while node != self._root:
            parent = Node(node.level + 1, node.index >> 1)
            left, right = Node(node.level, 2 * parent.index), Node(node.level, 2 * parent.index + 1)
            if right.start >= self.chunk_count:
                self._held[parent] = self._held.pop(left)
            elif left in self._held and right in self._held:
                self._held[parent] = self._held.pop(left) + self._held.pop(right)
            else:
                break
            node = parent

    @property
    def finished(self) -> bool:
        return self._root in self._held

    def total(self) -> np.ndarray:
        """The sum of every chunk (raises ``KeyError`` naming a missing node while some are missing)."""
        if not self.finished:
            raise KeyError(f"{self.chunk_count - self.chunks_done} of {self.chunk_count} chunks are missing")
        return self._held[self._root]

