"""Self-contained export folders: ``scene.xml`` (Mitsuba 3 scene XML) beside the meshes (PLY),
textures and scratch files that it names; written and loaded back.
"""
