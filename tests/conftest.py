"""Shared test helpers. Plots use the Agg backend."""
from __future__ import annotations

import os
import re
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


def figure_texts(fig) -> dict:
    """The title and axis labels a reader sees on a figure: ``title`` (the
    suptitle, else the first Axes' title), every Axes' titles, x and y labels."""
    sup = fig._suptitle.get_text() if getattr(fig, "_suptitle", None) else ""
    axes = [a for a in fig.axes if a.get_visible()]
    titles = [a.get_title() for a in axes]
    return {"title": sup or next((t for t in titles if t), ""), "titles": titles,
            "xlabels": [a.get_xlabel() for a in axes], "ylabels": [a.get_ylabel() for a in axes]}


@pytest.fixture
def saved_figures(monkeypatch) -> dict:
    """``{file name: figure_texts}`` of every figure saved while the test runs."""
    import matplotlib.figure

    saved: dict = {}
    savefig = matplotlib.figure.Figure.savefig

    def recording(fig, fname, *args, **kwargs):
        name = Path(str(fname)).name
        # files written all or none go through ".NAME.<random>.png" first
        name = re.sub(r"^\.(.+\.png)\.[^.]*\.png$", r"\1", name)
        saved[name] = figure_texts(fig)
        return savefig(fig, fname, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", recording)
    return saved
