"""The public Python API never lets anything but a beamid.BeamidError out
(issue 32): the property-based fuzz of tests/fuzz_api.py, run in a
subprocess so that a crash (a signal from the Fortran core) fails this test
instead of ending the pytest run.

``BEAMID_FUZZ_PROFILE=long`` (what ``make test-check`` sets) draws many more
examples per callable; the default profile keeps the run near half a
minute.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import beamid

HERE = Path(__file__).resolve().parent
FUZZ = HERE / "fuzz_api.py"
PROFILE = os.environ.get("BEAMID_FUZZ_PROFILE", "default")
TIMEOUT = {"default": 600, "long": 5400}


def _python() -> list[str]:
    """This interpreter as it runs (the checking build runs python -S)."""
    return [sys.executable] + (["-S"] if sys.flags.no_site else [])


def run_isolated(command: list[str], progress: Path, timeout: float) -> str:
    """Run ``command``; '' when it exited (any code), else why not: the
    signal that ended it or the timeout, and the call in flight (``progress``)."""
    def in_flight() -> str:
        return progress.read_text().strip() if progress.exists() else "(none yet)"

    try:
        proc = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"no answer within {timeout} s; the call in flight: {in_flight()}"
    if proc.returncode < 0:
        name = signal.Signals(-proc.returncode).name
        return (f"the process ended with signal {name} in the call {in_flight()}\n"
                f"{proc.stderr[-3000:]}")
    return ""


def test_a_crash_fails_the_test_and_names_the_call(tmp_path):
    progress = tmp_path / "progress.txt"
    progress.write_text("beamid.somewhere(n=-1)\n")
    why = run_isolated([*_python(), "-c", "import os, signal; os.kill(os.getpid(), "
                        "signal.SIGSEGV)"], progress, 60)
    assert "signal SIGSEGV" in why and "beamid.somewhere(n=-1)" in why
    assert run_isolated([*_python(), "-c", "raise SystemExit(1)"], progress, 60) == ""


def test_new_public_functions_join_the_fuzz_by_being_public(monkeypatch):
    sys.path.insert(0, str(HERE))
    try:
        import fuzz_api
    finally:
        sys.path.remove(str(HERE))

    def sensors(model, count: int = 3):
        return None

    monkeypatch.setattr(beamid, "sensors", sensors, raising=False)
    monkeypatch.setattr(beamid, "__all__", [*beamid.__all__, "sensors"])
    targets, skipped, records = fuzz_api.public_targets()
    labels = {t.label for t in targets}
    assert "beamid.sensors" in labels and "beamid.improve" in labels
    assert [p.name for t in targets if t.label == "beamid.sensors" for p in t.params] == \
        ["model", "count"]
    # exception classes and aliases are left out, each with its reason
    reasons = dict(skipped)
    assert "exception" in reasons["InputError"]
    assert "alias" in reasons["simulate_dynamics"]
    assert beamid.FitResult in records


def test_public_api_fuzz(tmp_path):
    report, progress = tmp_path / "report.json", tmp_path / "progress.txt"
    why = run_isolated([*_python(), str(FUZZ), "--profile", PROFILE, "--report", str(report),
                        "--progress", str(progress)], progress, TIMEOUT[PROFILE])
    assert not why, why
    rep = json.loads(report.read_text())
    assert rep["finished"]
    assert not rep["missing_examples"], rep["missing_examples"]
    failures = "\n".join(f"{f['callable']}({f['call']}): {f['exception']}: {f['message']} "
                         f"[{f['where']}]" for f in rep["failures"])
    assert not rep["failures"], f"{len(rep['failures'])} calls raised a non-beamid " \
                                f"exception:\n{failures}"
    # it ran: the public functions and the methods of their results were called
    fuzzed = {label for label, _ in rep["fuzzed"]}
    for label in ("beamid.improve", "beamid.simulate", "beamid.fit", "beamid.Model",
                  "Run.profiles", "StaticResult.shape", "Measurements.from_rows",
                  "Consistency.to_csv", "FEModes.modal_cost"):
        assert label in fuzzed, label
    assert rep["calls"] > 1500 and rep["beamid_errors"] > 1000
