"""Stroke collections for the brush operators, built in code (a helper module, not a conftest: a test
module importing ``conftest`` gets whichever conftest pytest loaded last, which depends on the order of
the command line's paths)."""


def stroke(points, starts=(), pressure=None):
    """An operator ``stroke`` collection: world-space points, ``is_start`` at the given indices, the
    tablet ``pressure`` of each point (default 1.0, a mouse)."""
    pressure = [1.0] * len(points) if pressure is None else list(map(float, pressure))
    return [{"name": "", "location": tuple(map(float, p)), "mouse": (0.0, 0.0), "mouse_event": (0.0, 0.0),
             "pressure": pressure[i], "size": 0.0, "x_tilt": 0.0, "y_tilt": 0.0, "time": float(i),
             "is_start": i == 0 or i in starts} for i, p in enumerate(points)]
