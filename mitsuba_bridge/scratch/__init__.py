"""The scratch set: data model, file format v1, distributions, noise and polyline tools.

Depends on numpy and the standard library only.
"""
from .distributions import Constant, Distribution, Gaussian, Uniform, parse_distribution
from .fileformat import FORMAT, FORMAT_VERSION, declared_counts, dumps, load, loads, save, save_bytes
from .generate import check_looks, estimate_generate_bytes, random_scratches, sample_parameters
from .noise import GRADIENTS, noise_offset, simplex_noise, variation_factor, width_depth_at
from .polyline import arc_parameter, edge_lengths, resample, scratch_lengths, vertex_arc_length
from .scratchset import Profile, ScratchFormatError, ScratchSet
from .segments import Segments, subdivide

__all__ = [
    "Constant", "Distribution", "Gaussian", "Uniform", "parse_distribution",
    "FORMAT", "FORMAT_VERSION", "declared_counts", "dumps", "load", "loads", "save", "save_bytes",
    "random_scratches", "sample_parameters", "check_looks", "estimate_generate_bytes",
    "GRADIENTS", "noise_offset", "simplex_noise", "variation_factor", "width_depth_at",
    "arc_parameter", "edge_lengths", "resample", "scratch_lengths", "vertex_arc_length",
    "Profile", "ScratchFormatError", "ScratchSet",
    "Segments", "subdivide",
]
