"""Scratch Iridescence: paint microscopic scratches in Blender, render their diffraction with Mitsuba 3."""
from .addon import register, unregister
__all__ = ["register", "unregister"]
