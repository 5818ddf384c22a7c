"""The scratch tables, built once per scratch set on the host (numpy only: never Dr.Jit or Mitsuba).

:func:`.grid.build_tables` turns a :class:`~..scratch.ScratchSet` into the segment table and its UV
grid of references, with the crossing pairs (:mod:`.crossings`), the periodic families
(:mod:`.periodic`) and the arrays the kernel scans (:mod:`.scan`); :mod:`.incremental` extends them
by appended scratches (a pen stroke) and :mod:`.disk_cache` keeps them on disk between processes.
The plugin uploads the result once (:meth:`..lookup.Grid.from_arrays`).
"""
