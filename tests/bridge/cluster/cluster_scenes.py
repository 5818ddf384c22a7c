"""Helpers of the cluster tests: small exported scenes, the one-process reference render, worker start-up."""
import contextlib
import os
import sys
from pathlib import Path

VARIANT = "llvm_ad_spectral"
ROOT = Path(__file__).resolve().parents[3]


@contextlib.contextmanager
def worker_sys_path():
    """Start worker processes without the checkout's parent folder on their path.

    The repository root is a package (the extension), so pytest puts its parent folder first on
    ``sys.path``, and spawned workers inherit it: any folder there named like a standard module
    (a sibling checkout called ``platform``) would shadow that module in every worker.
    """
    parent = str(ROOT.parent)
    saved = list(sys.path)
    sys.path[:] = [entry for entry in sys.path if os.path.abspath(entry or ".") != parent]
    try:
        yield
    finally:
        sys.path[:] = saved


def export_scene(folder, *, film=(32, 24), light=(1.0, 1.0, 1.0), sampler="independent"):
    """A lit grey floor exported to ``folder`` (different ``light`` values give different scenes), rendered with
    Mitsuba's ``sampler``."""
    from bridge_scenes import simple_scene
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.folder import export
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    activate(VARIANT)  # the export writes Mitsuba transforms: whichever test runs first needs the variant
    description = simple_scene(film=S.Film(*film), lights=[S.PointLight((0, 0, 2), light)],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    export.export_folder(description, S.RenderSettings(spp=4, sampler=sampler), folder)
    return folder


def one_process_render(folder, output, spp, seed):
    """The one-machine render of the ``render`` command (the reference every cluster render must equal)."""
    from scratch_iridescence.mitsuba_bridge.cli.main import main
    from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

    assert main(["render", str(folder), "-o", str(output), "--spp", str(spp), "--seed", str(seed), "-q",
                 "--variant", VARIANT]) == 0
    return read_exr(output)
