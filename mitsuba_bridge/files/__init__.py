"""Files written safely and images read and written: atomic replacement (a temporary sibling,
then a rename), linear OpenEXR, 8-bit sRGB PNG.

A bottom room: it imports nothing of the project but :mod:`..errors`.
"""
