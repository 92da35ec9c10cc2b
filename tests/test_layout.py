"""The Fortran layers (docs/development.md, Layers): every library module sits
in its layer's folder and uses only modules of its own layer or below
(tools/layout.py check)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _layout():
    spec = importlib.util.spec_from_file_location("layout", ROOT / "tools" / "layout.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_module_in_its_layer_folder_and_uses_go_down():
    layout = _layout()
    assert layout.check() == []
    assert layout.sources() == []          # nothing left directly under fortran/
    where = layout.placement()
    for name, path in layout.located().items():
        assert path.parent.name == where[name], name


def test_a_use_of_a_higher_layer_is_reported(tmp_path, monkeypatch):
    layout = _layout()
    where = layout.placement()
    files = layout.located()
    bad = tmp_path / "beamid_kinds.f90"
    bad.write_text(files["beamid_kinds.f90"].read_text().replace(
        "implicit none", "use beamid_ladder, only: ladder_t\n    implicit none", 1))
    files["beamid_kinds.f90"] = bad
    problems = layout.check_uses(where, files)
    assert any("beamid_kinds" in p and "beamid_ladder" in p for p in problems), problems
