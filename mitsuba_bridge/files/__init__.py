"""Files written safely and images read and written: atomic replacement (a temporary sibling,
then a rename; :mod:`.swap`: folders swapped in with a journal a killed swap is completed from),
reads of regular files only (:mod:`.regular`), linear OpenEXR, 8-bit sRGB PNG.

A bottom room: it imports nothing of the project but :mod:`..errors`.
"""
