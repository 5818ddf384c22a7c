"""Eraser hit test, unit formatting, memory checks, and the helpers' independence from Blender."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from scratch_iridescence.addon.erase import densify, touched_scratches
from scratch_iridescence.addon.units import MemoryLimitError, check_memory, format_length


def brute_force(a, b, scratch, stroke, radius, count):
    """Exact segment–segment distances between every scratch piece and every stroke segment."""
    hit = np.zeros(count, dtype=bool)
    s0, s1 = stroke[:-1], stroke[1:]
    ts = np.linspace(0, 1, 401)
    for i in range(len(a)):
        # Dense sampling of the piece against exact point-to-segment distances of the stroke.
        points = a[i] + ts[:, None] * (b[i] - a[i])
        d = s1 - s0
        t = np.clip(np.einsum("pki,ki->pk", points[:, None, :] - s0[None], d) / np.einsum("ki,ki->k", d, d), 0, 1)
        closest = s0[None] + t[..., None] * d[None]
        if np.linalg.norm(points[:, None, :] - closest, axis=2).min() <= radius:
            hit[scratch[i]] = True
    return hit


def test01_eraser_touches_what_lies_within_the_radius():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 1, (400, 3)) * [1, 1, 0]
    b = a + rng.normal(0, 0.05, (400, 3)) * [1, 1, 0]
    scratch = np.repeat(np.arange(200), 2)
    stroke = np.column_stack([np.linspace(0.1, 0.9, 9), 0.5 + 0.2 * np.sin(np.linspace(0, 3, 9)), np.zeros(9)])
    radius = 0.04
    expected = brute_force(a, b, scratch, stroke, radius, 200)
    got = touched_scratches(a, b, scratch, [stroke], radius, 200)
    # Differences only where a piece grazes the tube within the sampling tolerance.
    disagree = np.flatnonzero(got != expected)
    looser = brute_force(a, b, scratch, stroke, radius * (1 + 1 / 64), 200)
    tighter = brute_force(a, b, scratch, stroke, radius * (1 - 1 / 64), 200)
    assert np.all(looser[disagree] & ~tighter[disagree])
    assert 0 < expected.sum() < 200


def test02_eraser_edge_cases():
    a = np.array([[0.0, 0.0, 0.0]])
    b = np.array([[1.0, 0.0, 0.0]])
    far = [np.array([[0.5, 1.0, 0.0], [0.6, 1.0, 0.0]])]
    assert not touched_scratches(a, b, [0], far, 0.5, 1).any()
    assert touched_scratches(a, b, [0], far, 1.0, 1).all()
    assert touched_scratches(a, b, [0], [np.array([[0.5, 0.2, 0.0]])], 0.3, 1).all()  # a single dab
    assert not touched_scratches(np.zeros((0, 3)), np.zeros((0, 3)), [], far, 1.0, 0).any()


def test03_densify_spacing_and_ends():
    points = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 2.0, 0]])
    dense = densify(points, 0.3)
    assert np.linalg.norm(np.diff(dense, axis=0), axis=1).max() <= 0.3 + 1e-12
    np.testing.assert_allclose(dense[[0, -1]], points[[0, -1]])
    assert any(np.allclose(p, points[1]) for p in dense)


@pytest.mark.parametrize("metres, text", [
    (250e-9, "250 nm"), (4e-6, "4 µm"), (1.3e-6, "1.3 µm"), (999.9e-9, "1 µm"), (0.0123, "12.3 mm"),
    (2.0, "2 m"), (0.0, "0 m"), (5e-12, "0.005 nm"),
])
def test04_lengths_read_naturally(metres, text):
    assert format_length(metres) == text


def test05_memory_check_refuses_what_does_not_fit():
    check_memory(10, "Small", available=100)
    with pytest.raises(MemoryLimitError, match="Big needs about 1.0 GiB.*0.0 GiB is free"):
        check_memory(2**30, "Big", available=1000)


def test06_pure_helpers_import_without_blender():
    code = """
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('bpy', 'mathutils', 'gpu', 'bmesh', 'bpy_extras'):
            raise ImportError('blocked: ' + name)
sys.meta_path.insert(0, Block())
import importlib
for name in ('surface', 'trace', 'scatter', 'uvmap', 'lines', 'erase', 'units'):
    importlib.import_module('scratch_iridescence.addon.' + name)
print('ok')
"""
    root = Path(__file__).resolve().parents[2]
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"
