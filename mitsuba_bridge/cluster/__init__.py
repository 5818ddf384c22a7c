"""Renders spread over a Dask cluster (``render --cluster``, ``render-frames --cluster``): the driver, the
workers' tasks, the scene folders shipped to workers once, and the merge of their node sums.

Needs Dask (``pip install 'scratch-iridescence[cluster]'``); nothing here is imported by a render on one
machine, and the Blender extension leaves this room out.
"""
from __future__ import annotations
