"""Scenes built in code with bpy: the demo (`make demo`) and the paper's figures (`make paper`).

Each module exposes ``build_scene(scene, ...)`` that fills an empty scene, so the
same code serves scripts, tests and the user interface.
"""
