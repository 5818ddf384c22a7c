"""``merge`` trusts nothing in a part (mitsuba_bridge/render/parts.py): each corrupted header field and each bad sum
is one ``error:`` line, nothing written, the memory used bounded; parts rendered from other scratch tables are
parts of another render."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import quad, simple_scene
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.cli.main import main
from scratch_iridescence.mitsuba_bridge.folder import export
from scratch_iridescence.mitsuba_bridge.render import parts

ROOT = Path(__file__).resolve().parents[3]
LLVM = ["--variant", "llvm_ad_spectral"]


@pytest.fixture(scope="module")
def thirds(variant, tmp_path_factory):
    """A scratched plate at 32 × 24, 31 spp (nine chunks), rendered in three parts."""
    base = tmp_path_factory.mktemp("merge")
    plate = S.ScratchedMetal(scratches=scratch.random_scratches(30, seed=5), coherence_diameter_m=30e-6)
    export.export_folder(simple_scene(shapes=[S.Shape("plate", quad(1.0, "plate"), np.eye(4), "plate")],
                                      materials={"plate": plate}, lights=[S.PointLight((0, 0, 2), (1.0,) * 3)],
                                      world=S.ConstantWorld((0.2, 0.2, 0.2))), S.RenderSettings(spp=4), base / "scene")
    files = []
    for k in (1, 2, 3):
        files.append(base / f"t{k}.exr")
        assert main(["render", str(base / "scene"), "-o", str(files[-1]), "--spp", "31", "--seed", "3", "-q", *LLVM,
                     "--chunk", f"{k}/3"]) == 0
    return files


def contents(path):
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as file:
        return dict(file.header()), {name: np.array(c.pixels) for name, c in file.channels().items()}


def rewritten(source, target, header_edit=None, channels_edit=None, *, checksum=True):
    """``source`` edited; its checksum recomputed (``checksum``: as a tool that edits parts on purpose would),
    so that the checks behind it are the ones tested."""
    import OpenEXR

    header, channels = contents(source)
    for name in ("dataWindow", "displayWindow", "channels"):
        header.pop(name, None)  # (the writer derives them from the pixels)
    if header_edit:
        header_edit(header)
    if channels_edit:
        channels_edit(channels)
    if checksum:
        header["checksum"] = parts._checksum(header, channels)
    OpenEXR.File(header, channels).write(str(target))
    return target


def field(name, value):
    return lambda header: header.__setitem__(name, value)


def sums_of(node_level, node_index, change):
    """Replace the float64 sums of one node (every channel) by ``change(values)``."""
    def edit(channels):
        for c in "RGBA":
            hi, lo = (channels[f"sum.L{node_level}.N{node_index}.{c}.{h}"] for h in ("hi", "lo"))
            value = ((hi.astype(np.uint64) << np.uint64(32)) | lo.astype(np.uint64)).view(np.float64)
            bits = np.ascontiguousarray(change(value.copy()), dtype=np.float64).view(np.uint64)
            channels[f"sum.L{node_level}.N{node_index}.{c}.hi"] = (bits >> np.uint64(32)).astype(np.uint32)
            channels[f"sum.L{node_level}.N{node_index}.{c}.lo"] = (bits & np.uint64(0xFFFFFFFF)).astype(np.uint32)
    return edit


def first_node(header):
    level, index = header["nodes"].split(",")[0].split(".")
    return int(level), int(index)


# (name, header edit, channel edit, words of the error); the second third (chunks 3-5) is the one corrupted.
# (EXR integer attributes hold 32 bits: the largest corrupt values a header can carry are 2**31 - 1.)
HEADER_CASES = [
    ("chunkStop 2**31-1", field("chunkStop", 2 ** 31 - 1), None, "chunkStop is 2147483647, outside"),
    ("chunkFirst -1", field("chunkFirst", -1), None, "chunkFirst is -1"),
    ("chunkFirst after chunkStop", field("chunkFirst", 5), None, "samples is 12, but chunks 5-5"),
    ("samples 0", field("samples", 0), None, "samples is 0, outside"),
    ("samples -3", field("samples", -3), None, "samples is -3"),
    ("samples 13", field("samples", 13), None, "samples is 13, but chunks 3-5"),
    ("spp 0", field("render.spp", 0), None, "render.spp is 0, outside"),
    ("spp 2**31-1", field("render.spp", 2 ** 31 - 1), None, "impossible render"),
    ("spp 32", field("render.spp", 32), None, "are not the schedule of 32 spp"),
    ("width 10**9", field("render.width", 10 ** 9), None, "not the schedule of"),
    ("width 0", field("render.width", 0), None, "render.width is 0"),
    ("width as text", field("render.width", "32"), None, "render.width is '32', not a whole number"),
    ("height 2**31-1", field("render.height", 2 ** 31 - 1), None, "over 32 x 2147483647 pixels"),
    ("chunk_count 2**31-1", field("render.chunk_count", 2 ** 31 - 1), None, "chunk_count is 2147483647, outside"),
    ("chunk_count 8", field("render.chunk_count", 8), None, "chunk_count 8"),
    ("seed -1", field("render.seed", -1), None, "render.seed is -1"),
    ("schedule", field("render.schedule", "0123456789abcdef"), None, "are not the schedule"),
    ("tables empty", field("render.tables", ""), None, "render.tables is '', not a short text"),
    ("nodes of other chunks", field("nodes", "0.0"), None, "nodes is '0.0', not the sums of chunks 3-5"),
    ("nodes garbage", field("nodes", "x" * 5000), None, "not the sums of chunks"),
    ("format of an older version", field("format", "scratch-iridescence/render-part/1"), None, "older version"),
    ("no format", lambda header: header.pop("format"), None, "not a render part"),
    ("another image size", None,
     lambda ch: ch.update({n: np.concatenate([v, v[:, :1]], axis=1) for n, v in ch.items()}),
     "not the 32 x 24 image"),
    ("a channel missing", None, lambda channels: channels.pop("sum.L0.N5.A.lo", None) or channels.pop(sorted(
        n for n in channels if n.startswith("sum."))[0]), "its channels are not RGBA and the sums"),
    ("an extra channel", None, lambda channels: channels.update(Z=channels["R"]), "its channels are not RGBA"),
]
SUM_CASES = [
    ("NaN sums", lambda v: np.full_like(v, np.nan), "hold NaN or infinite values"),
    ("infinite sums", lambda v: np.full_like(v, np.inf), "hold NaN or infinite values"),
    ("1e308 sums", lambda v: np.full_like(v, 1e308), "its sums are not the image beside them"),
    ("doubled sums", lambda v: v * 2, "its sums are not the image beside them"),
    ("one pixel off", lambda v: v + np.where(np.arange(v.size).reshape(v.shape) == 7, 1.0, 0.0),
     "(4 values differ)"),
]


@pytest.fixture(scope="module")
def corrupted(thirds, tmp_path_factory):
    """Every corrupted copy of the second part: ``{name: (path, expected words)}``."""
    base = tmp_path_factory.mktemp("corrupted")
    header, _ = contents(thirds[1])
    cases = {}
    for name, header_edit, channels_edit, words in HEADER_CASES:
        cases[name] = (rewritten(thirds[1], base / f"{len(cases)}.exr", header_edit, channels_edit), words)
    for name, change, words in SUM_CASES:
        cases[name] = (rewritten(thirds[1], base / f"{len(cases)}.exr", None, sums_of(*first_node(header), change)),
                       words)

    def float_sums(channels):
        for key in [n for n in channels if n.startswith("sum.")]:
            channels[key] = channels[key].astype(np.float32)

    cases["float32 sum channels"] = (rewritten(thirds[1], base / "f.exr", None, float_sums),
                                     "holds PixelType.FLOAT (24, 32), not PixelType.UINT")
    flip = sums_of(*first_node(header), lambda v: (v.view(np.uint64) ^ np.uint64(1)).view(np.float64))
    cases["a flipped bit"] = (rewritten(thirds[1], base / "b.exr", None, flip, checksum=False),
                              "damaged: its checksum does not match its header and pixels")
    cases["NaN image"] = (rewritten(thirds[1], base / "n.exr", None,
                                    lambda channels: channels["G"].__setitem__((3, 4), np.nan)), "its image holds NaN")
    return cases


@pytest.mark.parametrize("name", [c[0] for c in HEADER_CASES] + [c[0] for c in SUM_CASES]
                         + ["float32 sum channels", "NaN image", "a flipped bit"])
def test01_each_corruption_is_one_error_line(thirds, corrupted, tmp_path, capsys, name):
    path, words = corrupted[name]
    out = tmp_path / "merged.exr"
    status = main(["merge", str(thirds[0]), str(path), str(thirds[2]), "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert status == 1 and err.startswith("error: ") and "\n" not in err and "Traceback" not in err, err
    assert words in err and str(path) in err, err
    assert not out.exists()


def test02_merging_every_corruption_stays_within_bounded_memory(thirds, corrupted, tmp_path):
    """In a child started small (its peak is its own) under a 4 GiB address-space limit: every corrupted part is
    refused, and the peak resident memory stays that of a process reading 32 × 24 images."""
    cases = {name: str(path) for name, (path, _) in corrupted.items()}
    code = f"""
import contextlib, io, json, resource, sys
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, resource.RLIM_INFINITY))
from scratch_iridescence.mitsuba_bridge.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    valid = main(["merge", *{[str(t) for t in thirds]!r}, "-o", {str(tmp_path / "v.exr")!r}])
baseline_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
results = {{}}
for name, path in json.loads(sys.argv[1]).items():
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = main(["merge", {str(thirds[0])!r}, path, {str(thirds[2])!r}, "-o", {str(tmp_path / "m.exr")!r}])
    results[name] = [status, err.getvalue()]
print(json.dumps({{"valid": valid, "baseline_kb": baseline_kb, "results": results,
                  "peak_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}}))
"""
    # (started from a small launcher: ru_maxrss survives fork and exec, so a child of this test process would
    # report this process's peak, not its own)
    launcher = "import subprocess, sys; sys.exit(subprocess.call(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", launcher, sys.executable, "-c", code, json.dumps(cases)],
                            capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    for name, (status, err) in report["results"].items():
        assert status == 1 and err.count("\n") == 1 and err.startswith("error: "), (name, err)
    # The peak is that of the valid merge before them (the interpreter, the CLI's imports, three 32 × 24 parts:
    # ~45 MB) give or take the allocator's slack. A 10**9-pixel image would be gigabytes, and a header naming
    # 2**31 spp once built its 131 072 chunks (+100 MB) before finding they were not the part's 9.
    assert report["valid"] == 0
    assert report["peak_kb"] - report["baseline_kb"] < 32_000, (report["baseline_kb"], report["peak_kb"])


def test03_parts_rendered_from_other_scratch_tables_are_parts_of_another_render(thirds, tmp_path, capsys,
                                                                               monkeypatch):
    from scratch_iridescence.mitsuba_bridge.bsdf import persistent
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import disk_cache

    assert parts.read_header(thirds[0]).identity.tables not in ("", "none")
    # another version of the code that builds the tables (as on a farm machine with another add-on version)
    monkeypatch.setattr(disk_cache, "_fingerprint", "another version of bsdf/ and scratch/")
    persistent.forget()
    other = tmp_path / "other.exr"
    assert main(["render", str(thirds[0].parent / "scene"), "-o", str(other), "--spp", "31", "--seed", "3", "-q",
                 *LLVM, "--chunk", "2/3"]) == 0
    status = main(["merge", str(thirds[0]), str(other), str(thirds[2]), "-o", str(tmp_path / "m.exr")])
    err = capsys.readouterr().err.strip()
    assert status == 1 and "are parts of different renders: tables" in err, err


def test04_good_parts_still_merge_and_a_part_of_a_plain_scene_says_none(thirds, tmp_path, capsys):
    assert main(["merge", *map(str, thirds), "-o", str(tmp_path / "m.exr")]) == 0
    image, identity = parts.merge_parts(thirds)
    assert image.shape == (24, 32, 4) and np.all(np.isfinite(image)) and identity.spp == 31
    assert parts.tables_fingerprint([]) == "none"
