"""Damaged command lines (issue 32, command-line part) and what both programs
print (issue 31).

For every subcommand of the ``beamid`` parser (discovered from argparse, not
listed by hand) and every option it takes, damaged values -- an unknown or
mistyped option, text for a number, NaN, infinity, a negative count, a
missing value, a missing deck file -- exit with code 2 (docs/decks.md, "Exit
codes") and ONE error line that names the option; argparse's usage lines are
those of the subcommand. All in-process through ``beamid.cli.main``: the
errors come before any computation, so the whole sweep takes about a second.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import beamid
from beamid.cli import EXIT_INPUT, build_parser, main
from beamid.tables import inputs_dir

BEAMID = Path(sys.executable).parent / "beamid"
#: values a typed option must refuse when its type refuses them
PROBES = ("abc", "nan", "inf", "-inf", "-3", "0", "1e400", "2.5")


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _positionals(sub: argparse.ArgumentParser, deck: str) -> list[str]:
    """Valid positional arguments, so that only the damaged option fails."""
    args = []
    for a in sub._actions:
        if not a.option_strings and a.nargs in (None, "+"):
            args.append(deck)
    return args


def _cases() -> list[tuple[str, list[str], str]]:
    """(subcommand, argv, the word the error line must name) for every damage."""
    deck = str(inputs_dir("seed") / "table05_fit.nml")
    cases = []
    for name, sub in _subcommands().items():
        pos = _positionals(sub, deck)
        cases.append((name, [name, *pos, "--no-such-option", "1"], "--no-such-option"))
        for a in sub._actions:
            if not a.option_strings or a.nargs == 0 or isinstance(a, argparse._HelpAction):
                continue
            opt = max(a.option_strings, key=len)
            if a.nargs is None:                   # one value: give none
                cases.append((name, [name, *pos, opt], opt))
            if a.choices is not None:
                cases.append((name, [name, *pos, opt, "bogus"], opt))
            if callable(a.type):
                for value in PROBES:
                    try:
                        a.type(value)
                    except (argparse.ArgumentTypeError, ValueError, TypeError):
                        cases.append((name, [name, *pos, opt, value], opt))
        for a in sub._actions:                    # a deck file that is not there
            if not a.option_strings and a.nargs in (None, "+", "?") and a.dest in ("deck",
                                                                                  "decks"):
                cases.append((name, [name, "not_there.nml"], "not_there.nml"))
            elif not a.option_strings and a.nargs == "*":   # names: tables, figures
                cases.append((name, [name, "bogus"], "bogus"))
    return cases


CASES = _cases()


def test_every_subcommand_and_typed_option_is_swept():
    subs = _subcommands()
    assert {c[0] for c in CASES} == set(subs)
    # every numeric option of every subcommand refuses at least one probe
    typed = {(n, max(a.option_strings, key=len)) for n, s in subs.items() for a in s._actions
             if a.option_strings and callable(a.type)}
    assert typed and typed <= {(c[0], c[2]) for c in CASES}
    assert {"--replicates", "--top", "--n-out", "--fy", "--times"} <= {o for _, o in typed}


@pytest.mark.parametrize("name, argv, named", CASES,
                         ids=[" ".join(c[1][:1] + c[1][-2:]) for c in CASES])
def test_damaged_option_exits_2_with_one_line_naming_it(name, argv, named, tmp_path,
                                                        monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code == EXIT_INPUT, err
    lines = err.splitlines()
    errors = [ln for ln in lines if ": error: " in ln]
    assert len(errors) == 1, err
    assert named in errors[0], err
    assert "Traceback" not in err and out == ""
    # anything else on stderr is the subcommand's usage
    others = [ln for ln in lines if ln not in errors]
    if others:
        assert others[0].startswith(f"usage: beamid {name} "), err
    assert list(tmp_path.iterdir()) == []         # nothing written


def test_mistyped_option_suggests_the_right_one(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "--motor-gian", "0.2"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: beamid simulate ")
    assert err.splitlines()[-1] == ("beamid simulate: error: unknown option --motor-gian "
                                    "(did you mean --motor-gain?)")


def test_every_subcommand_has_a_description_and_identify_is_a_task(batch_exe):
    subs = _subcommands()
    for name, sub in subs.items():
        assert sub.description and len(sub.description) > 40, name
    assert "identify" in subs["run"].description
    usage = subprocess.run([str(batch_exe), "--help"], capture_output=True, text=True)
    assert usage.returncode == 0 and "identify" in usage.stdout


def test_a_measurement_csv_given_as_a_deck_is_one_line(batch_exe, tmp_path):
    csv = tmp_path / "table16_data.csv"
    shutil.copy(inputs_dir("seed") / "table16_data.csv", csv)
    for argv in ([str(BEAMID), "run", csv.name], [str(batch_exe), csv.name]):
        done = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path)
        assert done.returncode == 2
        lines = done.stderr.splitlines()
        assert len(lines) == 1 and "a measurement CSV file" in lines[0], done.stderr
        assert csv.name in lines[0]


# ------------------------------------------------ the same output from both programs

SIMULATE = ("&beamid task = 'simulate', output = 'out/swing', preset = 'pace' /\n"
            "&model J_elbow = 0.0, J_tip = 0.0 /\n&load kind = 'tip', fy = 8.0 /\n"
            "&simulate t_end = 0.1, n_out = 3, elements_per_beam = 2 /\n")


@pytest.mark.parametrize("deck", ["table02_c05.nml", "directed_force_3N.nml",
                                  "table12_fe_04.nml", "table09_fe_04.nml", "swing.nml",
                                  "table05_fit.nml", "hidden_effect.nml",
                                  "identify_three_stages.nml"])
def test_both_programs_print_the_same(deck, batch_exe, tmp_path):
    for name in ("table05_fit.nml", "table05_data.csv", "table02_c05.nml",
                 "directed_force_3N.nml", "table12_fe_04.nml", "table09_fe_04.nml",
                 "identify_three_stages.nml", "table16_data.csv", "table23_data.csv"):
        shutil.copy(inputs_dir("seed") / name, tmp_path / name)
    for name in ("hidden_effect.nml", "hidden_effect.csv"):
        shutil.copy(inputs_dir("demo") / name, tmp_path / name)
    (tmp_path / "swing.nml").write_text(SIMULATE)

    def run(*argv):
        done = subprocess.run([str(a) for a in argv], capture_output=True, text=True,
                              cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        return done.stdout.splitlines()

    batch = run(batch_exe, deck)
    cli = run(BEAMID, "run", "--no-plots", deck)
    assert batch[0].startswith(f"{deck}: ") and len(batch) >= 2
    assert all(line.startswith("wrote ") for line in batch[1:])
    assert cli[-len(batch):] == batch           # an estimation deck's table comes first
    if deck.endswith("_fit.nml") or deck in ("hidden_effect.nml",
                                             "identify_three_stages.nml"):
        assert len(cli) > len(batch)
    else:
        assert cli == batch
    assert "nan" not in batch[0]
    if deck == "directed_force_3N.nml":          # a tip force: no wire force to print
        assert "wire force" not in batch[0]
    if deck == "table02_c05.nml":
        assert batch[0].endswith("wire force 53.3313 N")
    if deck == "swing.nml":   # the line of `beamid simulate` for the same run
        same = run(BEAMID, "simulate", deck, "--no-plots")
        assert same == batch
    assert run(batch_exe, "--quiet", deck) == []
    assert run(BEAMID, "run", "--quiet", "--no-plots", deck) == []


def test_fit_summary_line_names_the_weak_estimates(batch_exe, tmp_path):
    shutil.copy(inputs_dir("seed") / "identify_three_stages.nml", tmp_path / "id.nml")
    for name in ("table05_data.csv", "table16_data.csv", "table23_data.csv"):
        shutil.copy(inputs_dir("seed") / name, tmp_path / name)
    done = subprocess.run([str(batch_exe), "id.nml"], capture_output=True, text=True,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    first = done.stdout.splitlines()[0]
    assert first.startswith("id.nml: identify, 3 stages (static, free, forced); the last "
                            "fit converged after ")
    assert first.endswith("flagged: mu_elbow weak, rho1 weak")
    rows = (tmp_path / "out" / "identify_three_stages_identify.csv").read_text().splitlines()
    assert rows[0].endswith(",flag")
    forced = {r.split(",")[1]: r for r in rows if r.startswith("forced,")}
    assert forced["rho1"].endswith(",weak") and forced["EI1"].endswith(",ok")
    est = (tmp_path / "out" / "identify_three_stages_forced_estimates.csv").read_text()
    assert "rho1," in est and [r for r in est.splitlines()
                               if r.startswith("rho1,")][0].endswith(",weak")


def test_version_and_help_still_exit_0(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["design", "--help"])
    assert exc.value.code == 0
    assert "sigmas default to the deck's own" in capsys.readouterr().out
    assert beamid.__version__
