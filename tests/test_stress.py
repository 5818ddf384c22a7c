"""``tests/stress.py`` (``make test-stress``): runs, summary lines, stopping at the first failure."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

STRESS = Path(__file__).with_name("stress.py")


def stress(tmp_path, *arguments):
    return subprocess.run([sys.executable, str(STRESS), "--logs", str(tmp_path / "logs"), *arguments],
                          capture_output=True, text=True, timeout=300)


def test_summary_line_counts_are_read():
    # Loaded by path: a plain ``import stress`` finds whatever else is called ``stress`` first (a
    # checkout in a folder named so is itself a package of that name).
    spec = importlib.util.spec_from_file_location("stress_script", STRESS)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    summarise = module.summarise
    log = "....F\n=== short test summary info ===\nFAILED t.py::x\n= 1 failed, 280 passed, 2 deselected in 71.20s ="
    assert summarise(log) == {"failed": 1, "passed": 280, "deselected": 2}
    assert summarise("== 3 passed, 1 error in 0.5s ==") == {"passed": 3, "errors": 1}
    assert summarise("no summary") == {}


def test_runs_until_the_first_failure_and_summarises(tmp_path):
    tests = tmp_path / "suite"
    tests.mkdir()
    # Passes on the first run, fails on the second (a flaky test, made deterministic through a file).
    (tests / "test_flaky.py").write_text(
        "from pathlib import Path\n"
        f"MARK = Path({str(tmp_path / 'ran')!r})\n"
        "def test_stable():\n    pass\n"
        "def test_second_run_fails():\n"
        "    first = not MARK.exists()\n    MARK.touch()\n    assert first\n")
    result = stress(tmp_path, "--runs", "5", "--burners", "1", "--", str(tests))
    lines = result.stdout.splitlines()
    assert result.returncode == 1
    assert lines[1].startswith("run 1/5: 2 passed, 0 failed")
    assert lines[2].startswith("run 2/5: 1 passed, 1 failed")
    assert any("FAILED" in line and "test_second_run_fails" in line for line in lines)
    assert lines[-1] == "overall: 2 runs, 1 passed, 1 failed; 3 tests passed, 1 failed"
    assert (tmp_path / "logs" / "run-002.log").read_text().count("test_second_run_fails") >= 1


def test_all_green_exits_zero(tmp_path):
    tests = tmp_path / "suite"
    tests.mkdir()
    (tests / "test_ok.py").write_text("def test_ok():\n    pass\n")
    result = stress(tmp_path, "--runs", "2", "--burners", "0", "--", str(tests))
    assert result.returncode == 0, result.stdout
    assert result.stdout.splitlines()[-1] == "overall: 2 runs, 2 passed, 0 failed; 2 tests passed, 0 failed"


@pytest.mark.parametrize("arguments", [["--runs", "0"], ["--burners", "-1"]])
def test_bad_arguments_are_refused(tmp_path, arguments):
    result = stress(tmp_path, *arguments)
    assert result.returncode == 2 and "must be" in result.stderr
