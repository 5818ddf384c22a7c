"""Damaged scratch files shared by the tests of every reader (loader, CLI, add-on)."""
import io

import numpy as np

from scratch_iridescence.mitsuba_bridge import scratch


def overflowing_offsets_file() -> bytes:
    """A scratch file whose offsets wrap around in int64 (``np.diff`` passes them; the loader must not)."""
    offsets = np.array([0, 2**63 - 1, -2**63 + 1, -1, 8], dtype=np.int64)
    count = len(offsets) - 1
    stream = io.BytesIO()
    np.savez(stream, format=np.array(scratch.FORMAT), uv=np.full((8, 2), 0.5), offsets=offsets,
             width=np.full(count, 1e-6), depth=np.full(count, 1e-7), profile=np.zeros(count, np.uint8),
             width_variation=np.zeros((count, 2)), depth_variation=np.zeros((count, 2)),
             seed=np.zeros(count, np.uint32))
    return stream.getvalue()
