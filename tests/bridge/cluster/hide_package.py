"""``dask worker --preload`` file: a worker on which the scratch-iridescence package cannot be imported."""
import sys


class _Hidden:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] == "scratch_iridescence":
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


sys.meta_path.insert(0, _Hidden())
