"""Run the whole test suite again and again with every core busy, to catch flaky tests.

``make test-stress`` (or ``python tests/stress.py``) runs what ``make test`` runs
(``pytest -m "not slow"``) ``--runs`` times in a row, each in a fresh process,
while one CPU burner per core spins beside it: a test whose outcome depends on
timing or on the machine's load shows up here long before it bites a user.  It
stops at the first failing run, prints its failing tests and keeps its full
log, and ends with one summary line::

    run 1/20: 292 passed, 0 failed, 2 deselected (412.3 s)
    ...
    overall: 20 runs, 20 passed, 0 failed; 5840 tests passed, 0 failed

The exit status is 0 when every run passed.  Logs go to ``out/stress/``.
Extra arguments after ``--`` go to pytest (``-- tests/addon`` stresses one folder).
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: A burner: spins until killed, or until its parent (this script) is gone, so none outlives a crash.
_BURNER = """
import os
parent = os.getppid()
while os.getppid() == parent:
    for _ in range(200_000):
        pass
"""

_COUNT = re.compile(r"(\d+) (passed|failed|errors?|skipped|deselected|xfailed|xpassed)")


def start_burners(count: int) -> list[subprocess.Popen]:
    """``count`` busy processes (one per core by default)."""
    return [subprocess.Popen([sys.executable, "-c", _BURNER], stdin=subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(count)]


def stop_burners(burners: list[subprocess.Popen]) -> None:
    """Terminate the burners this script started (by their process, never by name)."""
    for process in burners:
        if process.poll() is None:
            process.terminate()
    for process in burners:
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def summarise(log: str) -> dict[str, int]:
    """Counts of pytest's final summary line ("3 failed, 280 passed, 2 deselected in 71.2s")."""
    lines = [line for line in log.splitlines() if re.search(r"\b(passed|failed|error|errors|no tests ran)\b", line)
             and " in " in line]
    counts: dict[str, int] = {}
    if lines:
        for number, word in _COUNT.findall(lines[-1]):
            counts["errors" if word.startswith("error") else word] = int(number)
    return counts


def run_once(index: int, runs: int, pytest_args: list[str], logs: Path) -> tuple[bool, dict[str, int]]:
    """One run of the suite; prints its summary line.  Returns (passed, counts)."""
    started = time.perf_counter()
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *pytest_args]
    log = logs / f"run-{index:03d}.log"
    with open(log, "w") as stream:  # written as it goes: `tail -f` follows a long run
        returncode = subprocess.run(command, cwd=ROOT, stdin=subprocess.DEVNULL, stdout=stream,
                                    stderr=subprocess.STDOUT).returncode
    seconds = time.perf_counter() - started
    output = log.read_text(errors="replace")
    counts = summarise(output)
    failed = counts.get("failed", 0) + counts.get("errors", 0)
    passed = returncode == 0 and failed == 0 and counts.get("passed", 0) > 0
    extras = "".join(f", {counts[k]} {k}" for k in ("errors", "skipped", "deselected") if counts.get(k))
    print(f"run {index}/{runs}: {counts.get('passed', 0)} passed, {counts.get('failed', 0)} failed{extras} "
          f"({seconds:.1f} s, exit status {returncode})", flush=True)
    if not passed:
        for line in output.splitlines():
            if line.startswith(("FAILED", "ERROR")):
                print(f"    {line}")
        print(f"    full log: {log}")
    return passed, counts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=int(os.environ.get("STRESS_RUNS", 20)),
                        help="how many times to run the suite (default 20, or $STRESS_RUNS)")
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    parser.add_argument("--burners", type=int, default=cores,
                        help="CPU burner processes beside the suite (default: one per core)")
    parser.add_argument("--logs", type=Path, default=ROOT / "out" / "stress", help="folder for the run logs")
    parser.add_argument("pytest_args", nargs="*", help="after --: pytest arguments (default: -m 'not slow')")
    args = parser.parse_args(argv)
    if args.runs < 1 or args.burners < 0:
        parser.error("--runs must be >= 1 and --burners >= 0")
    pytest_args = args.pytest_args or ["-m", "not slow"]
    args.logs.mkdir(parents=True, exist_ok=True)

    print(f"stress: {args.runs} runs of pytest {' '.join(pytest_args)} beside {args.burners} CPU burners; "
          f"logs in {args.logs}", flush=True)
    burners = start_burners(args.burners)
    good = bad = tests_passed = tests_failed = 0
    try:
        for index in range(1, args.runs + 1):
            passed, counts = run_once(index, args.runs, pytest_args, args.logs)
            tests_passed += counts.get("passed", 0)
            tests_failed += counts.get("failed", 0) + counts.get("errors", 0)
            if passed:
                good += 1
            else:
                bad += 1
                break  # the first failure is what we are looking for
    except KeyboardInterrupt:
        print("interrupted", flush=True)
    finally:
        stop_burners(burners)
    print(f"overall: {good + bad} runs, {good} passed, {bad} failed; "
          f"{tests_passed} tests passed, {tests_failed} failed")
    return 0 if bad == 0 and good == args.runs else 1


if __name__ == "__main__":
    sys.exit(main())
