"""Paths and the variant of the farm tests (a module of its own: test modules import it, never a conftest)."""
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
VARIANT = "llvm_ad_spectral"
