"""The examples in README.md and docs/*.md run, and the doctests hold."""
from __future__ import annotations

import doctest
import re
from pathlib import Path

import pytest

import beamid
import beamid.model
import beamid.static

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


PAGES = [p for p in DOCS if _python_blocks(p)]


@pytest.mark.parametrize("path", PAGES, ids=[p.name for p in PAGES])
def test_python_examples_run(path, tmp_path, monkeypatch):
    # the blocks of a page build on each other, as a reader types them in order,
    # from the top of a checkout (paths like inputs/demo/... are relative to it)
    (tmp_path / "inputs").symlink_to(ROOT / "inputs")
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__doc_example__"}
    for index, code in enumerate(_python_blocks(path)):
        exec(compile(code, f"{path.name}[{index}]", "exec"), namespace)


@pytest.mark.parametrize("module", [beamid, beamid.model, beamid.static])
def test_doctests(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
