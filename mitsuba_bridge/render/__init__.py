"""Rendering a loaded scene: the fixed sample schedule and its chunks, passes summed into one image,
interrupts, frozen passes, render parts merged bit for bit, the memory a render needs, and the
interactive session that the live viewport drives.
"""
