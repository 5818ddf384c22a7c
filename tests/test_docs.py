"""The physics the code cites lives in the repository: every ``docs/model.md §N`` names a real section."""
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg"}
CITATION = re.compile(r"model\.md\]?(?:\([^)]*\))?\s*§\s*(\d+(?:\.\d+)?)(?:\s*[–-]\s*(\d+(?:\.\d+)?))?")
HEADING = re.compile(r"^#{2,3}\s+(\d+(?:\.\d+)?)\.?\s", re.MULTILINE)


def tracked_text_files():
    names = subprocess.run(["git", "ls-files"], capture_output=True, text=True, cwd=ROOT).stdout.split()
    if not names:
        pytest.skip("not a git checkout")
    return [ROOT / name for name in names
            if (Path(name).suffix in TEXT_SUFFIXES or Path(name).name == "Makefile") and (ROOT / name).is_file()]


def model_sections() -> set[str]:
    return set(HEADING.findall((ROOT / "docs" / "model.md").read_text()))


def test_model_sections_are_numbered_in_order():
    sections = HEADING.findall((ROOT / "docs" / "model.md").read_text())
    top = [int(s) for s in sections if "." not in s]
    assert top == list(range(1, len(top) + 1)) and len(top) >= 10, sections
    for sub in (s for s in sections if "." in s):
        assert sub.split(".")[0] in sections, sub


def test_every_model_citation_points_to_an_existing_section():
    sections = model_sections()
    cited = []
    for path in tracked_text_files():
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            for match in CITATION.finditer(line):
                for section in filter(None, match.groups()):
                    cited.append((f"{path.relative_to(ROOT)}:{number}", section))
    assert len(cited) >= 30, cited  # the code cites the model throughout
    missing = [(where, section) for where, section in cited if section not in sections]
    assert not missing, f"citations of sections docs/model.md does not have: {missing}"


def test_nothing_refers_to_files_outside_the_repository():
    # (spelt in pieces so that this file does not match itself)
    pattern = re.compile("|".join([r"MODEL" + r"\.md", r"\.\./" + "shared", r"(?<![\w.])sha" + "red/",
                                   "/wo" + "rk/"]))
    offenders = []
    for path in tracked_text_files():
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if pattern.search(line):
                offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:100]}")
    assert not offenders, offenders
