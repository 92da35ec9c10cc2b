"""beamid.progress: a tqdm bar on a terminal only, the plain iterable otherwise."""
from __future__ import annotations

import builtins
import io
import sys

import pytest

from beamid.progress import bar_enabled, progress


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_no_bar_when_stderr_is_not_a_terminal(monkeypatch):
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    items = [1, 2, 3]
    assert progress(items, desc="x") is items          # unchanged, nothing drawn
    assert not bar_enabled()
    assert sys.stderr.getvalue() == ""


def test_bar_on_a_terminal(monkeypatch):
    pytest.importorskip("tqdm")
    tty = _Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    assert bar_enabled()
    assert list(progress(range(4), desc="decks")) == [0, 1, 2, 3]
    text = tty.getvalue()
    assert "decks" in text and "/4" in text


def test_enabled_overrides_the_terminal_test(monkeypatch):
    pytest.importorskip("tqdm")
    tty = _Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    items = (5, 6)
    assert progress(items, enabled=False) is items
    out = io.StringIO()
    monkeypatch.setattr(sys, "stderr", out)
    assert list(progress(iter(items), total=2, desc="forced", enabled=True)) == [5, 6]
    assert "forced" in out.getvalue() and "/2" in out.getvalue()


def test_without_tqdm_plain_iteration(monkeypatch):
    real_import = builtins.__import__

    def no_tqdm(name, *args, **kwargs):
        if name == "tqdm" or name.startswith("tqdm."):
            raise ImportError("no tqdm here")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_tqdm)
    monkeypatch.setattr(sys, "stderr", _Tty())
    items = ["a", "b"]
    assert progress(items, enabled=True) is items


def _simulate_rk4():
    import numpy as np

    import beamid

    return beamid.simulate(beamid.pace(J_elbow=0.0, J_tip=0.0), beamid.TipForce(fy=8.0),
                           np.linspace(0.0, 0.4, 5), elements_per_beam=2,
                           integrator="rk4")


def test_simulate_bar_follows_the_fortran_run(monkeypatch):
    # the Fortran integrator writes each output time it reaches into the slot
    # while it runs without Python's lock; a thread draws the bar from it
    pytest.importorskip("tqdm")
    import beamid._core_dynamics as cd
    import beamid.progress as bp

    slots = []

    def watched(total, desc="", **_):
        cm = bp.watch(total, desc, enabled=None, delay=0.0)
        slot = cm.__enter__()
        slots.append(slot)

        class _Ctx:
            def __enter__(self):
                return slot

            def __exit__(self, *exc):
                return cm.__exit__(*exc)
        return _Ctx()

    tty = _Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    monkeypatch.setattr(cd, "watch", watched)
    run = _simulate_rk4()
    assert len(slots) == 1 and slots[0][0] == pytest.approx(0.4)   # the last output time
    text = tty.getvalue()
    assert "simulate" in text and "0.4/0.4 s" in text
    quiet = io.StringIO()                                            # not a terminal
    monkeypatch.setattr(sys, "stderr", quiet)
    monkeypatch.undo()
    monkeypatch.setattr(sys, "stderr", quiet)
    again = _simulate_rk4()
    assert quiet.getvalue() == ""
    assert again.tip_w[-1] == run.tip_w[-1]                           # the bar changes nothing
