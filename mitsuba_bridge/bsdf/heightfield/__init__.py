"""Crossings as a height field (``crossings = "height_field"``, docs/model.md §3.4): the pair
corrections of crossing and of nearly parallel pieces, and the overlaps of three to five pieces.
Dr.Jit code run per lane, on the tables' crossing lists and the lookup grid.
"""
