"""Shared test helpers. Plots use the Agg backend."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def batch_exe() -> Path:
    """The beamid-batch executable of this build (editable install or installed)."""
    candidates = [ROOT / ".venv" / "bin" / "beamid-batch",
                  ROOT / "build" / "cp311" / "beamid-batch"]
    candidates += sorted((ROOT / "build").glob("*/beamid-batch"))
    found = shutil.which("beamid-batch")
    if found:
        candidates.insert(0, Path(found))
    if os.environ.get("BEAMID_BATCH"):   # the checking build (make test-check)
        candidates.insert(0, Path(os.environ["BEAMID_BATCH"]))
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    pytest.fail("beamid-batch was not built (run make setup)")


@pytest.fixture(autouse=True)
def _close_figures():
    """Close the figures a test opened (examples and plot helpers draw on new ones)."""
    yield
    import matplotlib.pyplot as plt

    plt.close("all")
