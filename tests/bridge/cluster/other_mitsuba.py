"""``dask worker --preload`` file: a worker whose Mitsuba reports another release than the driver's."""
import mitsuba

mitsuba.__version__ = "3.9.0"
