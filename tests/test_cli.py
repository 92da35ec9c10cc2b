"""The ``beamid`` command: --version, simulate, help texts that list the valid
names, the subcommand overriding an estimation deck's task, and the exit codes
shared with beamid-batch (0 ok, 1 not reproduced, 2 bad input, 3 no
convergence, 4 an output cannot be written, 5 internal error)."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid.cli import build_parser, main
from beamid.tables import inputs_dir, table_names

PNG = b"\x89PNG\r\n\x1a\n"


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"beamid {beamid.__version__}"


def test_console_script_on_the_path():
    exe = Path(sys.executable).parent / "beamid"
    done = subprocess.run([str(exe), "--version"], capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == f"beamid {beamid.__version__}"


def test_unknown_table_lists_the_valid_names(capsys):
    assert main(["reproduce", "foo"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("beamid: error: unknown table 'foo', expected one of: ")
    for name in ("2", "12", "13", "V", "circle"):
        assert f" {name}" in err
    assert table_names()[:3] == ["2", "3", "4"]


def test_help_texts_list_the_valid_names():
    parser = build_parser()
    sub = {a.dest: a for a in parser._actions}["command"].choices
    reproduce_help = sub["reproduce"].format_help()
    assert "circle" in reproduce_help and " V" in reproduce_help
    assert "20 21 22 23 24 25" in sub["figures"].format_help()
    assert "{implicit,rk4}" in sub["simulate"].format_help()
    assert "mu_elbow" in sub["simulate"].format_help()
    assert "fe_modes" in sub["run"].format_help()
    assert "exit codes" in parser.format_help()


def test_reproduce_one_table(capsys):
    assert main(["reproduce", "circle"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1].endswith("0 failed")


@pytest.fixture
def demo_deck(tmp_path):
    for name in ("hidden_effect.nml", "hidden_effect.csv"):
        shutil.copy(inputs_dir("demo") / name, tmp_path / name)
    return tmp_path / "hidden_effect.nml"


def test_fit_subcommand_overrides_the_decks_task(demo_deck, capsys):
    # the deck says improve; `beamid fit` fits only (docs/decks.md)
    assert main(["fit", str(demo_deck), "--no-plots"]) == 0
    out = capsys.readouterr().out
    written = sorted(p.name for p in (demo_deck.parent / "out").iterdir())
    assert written == ["hidden_effect_covariance.csv", "hidden_effect_estimates.csv",
                       "hidden_effect_residuals.csv"]
    assert "EI1" in out and "axial_coupling" not in out.split("wrote")[0].split("chi2")[0]
    assert out.count("wrote ") == 3
    est = (demo_deck.parent / "out" / "hidden_effect_estimates.csv").read_text()
    assert "elbow_flex" not in est          # no improve rung was added


def test_compare_subcommand_writes_its_figure(demo_deck, capsys):
    assert main(["compare", str(demo_deck)]) == 0
    out_dir = demo_deck.parent / "out"
    assert (out_dir / "hidden_effect_compare.png").read_bytes()[:8] == PNG
    assert not (out_dir / "hidden_effect_ladder.csv").exists()


def test_run_estimation_deck_uses_its_task(demo_deck, capsys):
    assert main(["run", str(demo_deck), "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "residuals not explained by any known effect" in out
    assert (demo_deck.parent / "out" / "hidden_effect_ladder.csv").is_file()


def test_simulate_flags(tmp_path, capsys):
    prefix = tmp_path / "sub" / "run"
    assert main(["simulate", "--t-end", "0.2", "--n-out", "3", "--fy", "6",
                 "--elements-per-beam", "2", "--set", "mu_tip=0.02", "--motor-gain", "0.2",
                 "--output", str(prefix)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1:] == [f"wrote {prefix}_history.csv", f"wrote {prefix}_history.png"]
    run = beamid.simulate(beamid.pace(J_elbow=0.0, J_tip=0.0, mu_tip=0.02),
                          beamid.TipForce(fy=6.0), np.linspace(0, 0.2, 3),
                          elements_per_beam=2, motor_gain=0.2)
    table = np.loadtxt(f"{prefix}_history.csv", delimiter=",", skiprows=1)
    header = Path(f"{prefix}_history.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["t", "tip_u", "tip_w"] and header[-1] == "motor_torque"
    assert_allclose(table[:, 0], [0.0, 0.1, 0.2])
    assert_allclose(table[:, 2], run.tip_w, rtol=0, atol=1e-15)
    assert_allclose(table[:, -1], run.motor_torque, rtol=0, atol=1e-15)
    assert f"tip w at the end {run.tip_w[-1]:.7f} m" in out[0]
    assert Path(f"{prefix}_history.png").read_bytes()[:8] == PNG


def test_simulate_defaults_are_table8(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--no-plots", "--t-out", "0,0.1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == "wrote out/simulate_history.csv"
    table = np.loadtxt("out/simulate_history.csv", delimiter=",", skiprows=1)
    assert table[0, 2] == pytest.approx(0.627036, abs=1e-6)     # 8 N static shape
    assert table[1, 2] == pytest.approx(0.6046646, abs=2e-7)    # Table 8 at 0.1 s
    assert not Path("out/simulate_history.png").exists()


def test_simulate_deck_with_overrides(tmp_path, capsys):
    deck = tmp_path / "swing.nml"
    deck.write_text("&beamid task = 'simulate', output = 'res/swing', preset = 'pace' /\n"
                    "&model J_elbow = 0.0, J_tip = 0.0 /\n&load kind = 'tip', fy = 8.0 /\n"
                    "&simulate t_end = 0.3, n_out = 4, elements_per_beam = 2 /\n")
    assert main(["simulate", str(deck), "--n-out", "2", "--no-plots"]) == 0
    table = np.loadtxt(tmp_path / "res" / "swing_history.csv", delimiter=",", skiprows=1)
    assert_allclose(table[:, 0], [0.0, 0.3])
    same = beamid.simulate(beamid.pace(J_elbow=0.0, J_tip=0.0), beamid.TipForce(fy=8.0),
                           [0.0, 0.3], elements_per_beam=2)
    assert table[-1, 2] == same.tip_w[-1]


@pytest.mark.parametrize("argv, message", [
    (["simulate", "nothere.nml"], "cannot open nothere.nml"),
    (["run", "nothere.nml"], "cannot open nothere.nml"),
    (["fit", "nothere.nml"], "nothere.nml"),
    (["simulate", "--t-out", "0,soon"], "--t-out"),
    (["simulate", "--set", "mu_tip"], "NAME=VALUE"),
    (["simulate", "--set", "EI9=1"], "EI9"),
    (["simulate", "--t-out", "0,1", "--n-out", "3"], "--t-out"),
    (["figures", "19"], "unknown figure"),
])
def test_bad_input_exits_2_without_files(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("beamid: error: ") and message in err
    assert list(tmp_path.iterdir()) == []


def test_simulate_static_deck_is_bad_input(capsys):
    deck = inputs_dir("seed") / "table02_c05.nml"
    assert main(["simulate", str(deck)]) == 2
    assert "is not a dynamic deck" in capsys.readouterr().err


def test_unknown_subcommand_and_flag_exit_2(capsys):
    for argv in (["frobnicate"], ["simulate", "--elements-per-beam", "four"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
    assert "invalid" in capsys.readouterr().err


def test_unwritable_output_exits_4_and_leaves_no_file(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert main(["simulate", "--t-out", "0,0.05", "--output", str(blocker / "x")]) == 4
    assert "cannot write" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_figure_failure_leaves_no_history(tmp_path, monkeypatch, capsys):
    # all or nothing: the CSV is not left behind when the figure cannot be written
    import beamid.plotting

    def broken(run, fig=None):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(beamid.plotting, "plot_history", broken)
    assert main(["simulate", "--t-out", "0,0.05", "--output", str(tmp_path / "r")]) == 4
    assert list(tmp_path.iterdir()) == []


def test_internal_error_exits_5(monkeypatch, capsys):
    import beamid.tables

    def bug(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(beamid.tables, "reproduce", bug)
    assert main(["reproduce"]) == 5
    assert "internal error (ZeroDivisionError: a bug)" in capsys.readouterr().err


def test_no_convergence_exits_3(monkeypatch, capsys):
    import beamid.tables

    def stuck(*args, **kwargs):
        raise beamid.ConvergenceError("Newton did not converge (residual 1e-3)")

    monkeypatch.setattr(beamid.tables, "reproduce", stuck)
    assert main(["reproduce", "2"]) == 3
    assert capsys.readouterr().err == "beamid: error: Newton did not converge (residual 1e-3)\n"


def test_simulate_history_is_the_batch_programs(tmp_path, batch_exe, capsys):
    # one file format: `beamid simulate DECK` writes the bytes beamid-batch writes
    deck = tmp_path / "d.nml"
    deck.write_text("&beamid task = 'simulate', output = 'batch', preset = 'pace' /\n"
                    "&model J_elbow = 0.0, J_tip = 0.0, mu_tip = 0.02 /\n"
                    "&load kind = 'tip', fy = 8.0 /\n"
                    "&simulate t_end = 0.2, n_out = 3, elements_per_beam = 2 /\n")
    done = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert main(["simulate", str(deck), "--output", str(tmp_path / "cli"), "--no-plots"]) == 0
    assert (tmp_path / "cli_history.csv").read_bytes() == \
        (tmp_path / "batch_history.csv").read_bytes()


def test_closed_pipe_stops_quietly(monkeypatch, capsys):
    import beamid.tables

    def reader_gone(*args, **kwargs):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(beamid.tables, "reproduce", reader_gone)
    assert main(["reproduce"]) == 141
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("make_error, code", [
    (lambda: beamid.InputError("bad"), 2),
    (lambda: beamid.ConvergenceError("stuck"), 3),
    (lambda: beamid.OutputError("cannot write x"), 4),
    # an InputError carrying the Fortran table's exit code 4 (ERR_OUTPUT)
    (lambda: _with_code(beamid.InputError("output: cannot create x"), 4), 4),
])
def test_exit_code_is_the_errors(monkeypatch, capsys, make_error, code):
    import beamid.tables

    def fail(*args, **kwargs):
        raise make_error()

    monkeypatch.setattr(beamid.tables, "reproduce", fail)
    assert main(["reproduce"]) == code
    assert capsys.readouterr().err.startswith("beamid: error: ")


def _with_code(error, code):
    error.exit_code = code
    return error


def test_run_fe_deck_lists_its_files(tmp_path, capsys):
    deck = tmp_path / "fe.nml"
    deck.write_text((inputs_dir("seed") / "table12_fe_08.nml").read_text()
                    .replace("out/table12_fe_08", "res/fe"))
    assert main(["run", str(deck)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"{deck}: fe_static, 8 elements: tip w 0.6")
    written = [Path(line.split(" ", 1)[1]) for line in out[1:]]
    assert written and all(p.is_file() and p.name.startswith("fe_") for p in written)
    assert sorted(written) == sorted((tmp_path / "res").iterdir())
