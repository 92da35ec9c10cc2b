"""The ``beamid`` command line. Every subcommand calls the public Python API.

Exit codes, the same as ``beamid-batch``'s (docs/decks.md): 0 ok, 1 a published
value not reproduced (``reproduce``, ``demo``), 2 bad input (a bad deck, CSV or
value, a missing or unreadable input file, an unknown name), 3 a numerical
failure (no convergence), 4 an output file cannot be written, 5 an internal error.

A bad command-line option (unknown or mistyped, a value that is not a number,
NaN or infinity, a negative count, a missing value) is bad input: exit code 2,
the subcommand's usage and one line naming the option (with a suggestion for a
mistyped one); tests/test_cli_options.py sweeps every option of every
subcommand.
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Sequence

from .errors import _write_all
from .errors import BeamidError, InputError

#: exit codes (the table of docs/decks.md, shared with beamid-batch)
EXIT_OK, EXIT_NOT_REPRODUCED, EXIT_INPUT, EXIT_NUMERICAL, EXIT_OUTPUT, EXIT_INTERNAL = range(6)

#: defaults of ``beamid simulate`` without a deck: the dissertation's free
#: vibration (Chapter IV, Table 8): 8 N release, 8 elements, one period
SIMULATE_DEFAULTS = {"fy": 8.0, "t_end": 2.6, "n_out": 27, "elements_per_beam": 4,
                     "output": "out/simulate"}


def _number(low: float = -math.inf, strict: bool = False, what: str = "a number"):
    """An argparse type: a finite float (> low when strict, >= low otherwise);
    argparse's error names the option ("argument --fy: ...")."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number, expected {what}") \
                from None
        if not math.isfinite(value) or value < low or (strict and value == low):
            raise argparse.ArgumentTypeError(f"{text!r}, expected {what}")
        return value
    parse.__name__ = "number"
    return parse


def _count(low: int = 1, what: str | None = None):
    """An argparse type: an integer >= low."""
    what = what or f"an integer >= {low}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer, expected {what}") \
                from None
        if value < low:
            raise argparse.ArgumentTypeError(f"{text!r}, expected {what}")
        return value
    parse.__name__ = "count"
    return parse


FINITE = _number(what="a finite number")
POSITIVE = _number(0.0, strict=True, what="a finite number > 0")


def _print_files(files) -> None:
    for f in files:
        print(f"wrote {f}")


# --------------------------------------------------------------------- run

def _cmd_run(args: argparse.Namespace) -> int:
    """``beamid run DECK``: what ``beamid-batch DECK`` prints (the summary line
    of the Fortran run, then 'wrote PATH' per file), an estimation deck's
    table first and its figures' files after; ``--quiet``: nothing."""
    from ._core import run_deck_report
    from .decks import read_deck
    from .fit_decks import FitDeck, _run_fit_deck

    deck = read_deck(args.deck)
    if isinstance(deck, FitDeck):         # estimation decks: the deck's own task
        text, files, _, summary, figures = _run_fit_deck(deck, plots=not args.no_plots)
        if not args.quiet:
            print(text)
            print(summary)
            _print_files([*files, *figures])
        return EXIT_OK
    handle = deck.handle        # the deck as read, unless the reader's path differs from
    if handle is not None and handle.path == str(args.deck):    # the path as given,
        summary, files = handle.run_task()      # which the summary names, as the batch's
    else:
        summary, files = run_deck_report(str(args.deck))
    if not args.quiet:
        print(summary)
        _print_files(files)
    return EXIT_OK


def _run_line(source: str, run) -> str:
    return (f"{source}: {run.t.size} output times to {run.t[-1]:g} s ({run.integrator}, "
            f"friction {run.friction}); tip w at the end {run.tip_w[-1]:.7f} m, energy "
            f"change {run.energy_change[-1]:.8f} N m")


# ------------------------------------------------------------- estimation

def _report(result, one_line: bool = False) -> int:
    """Print the text of a ``(text, files, result)`` run and the files written."""
    text, files, _ = result
    print(text)
    if one_line:
        print("wrote " + ", ".join(str(f) for f in files))
    else:
        _print_files(files)
    return EXIT_OK


def _cmd_estimate(args: argparse.Namespace) -> int:
    from .fit_decks import chain_options, read_fit_deck, run_fit_deck

    # the subcommand overrides the deck's task (docs/decks.md): `beamid fit` fits only
    keys = chain_options(args.time_offset, args.bias, args.scale, args.loss, args.burn_in,
                         args.estimate_sigma, args.initial_velocity)
    deck = dataclasses.replace(read_fit_deck(args.deck, keys), task=args.command)
    return _report(run_fit_deck(deck, plots=not args.no_plots))


def _cmd_identify(args: argparse.Namespace) -> int:
    from .fit_decks import run_identify

    return _report(run_identify(list(args.decks), plots=not args.no_plots))


# --------------------------------------------------------------- simulate

def _times(text: str) -> list[float]:
    try:
        return [float(t) for t in text.replace(",", " ").split()]
    except ValueError:
        raise InputError(f"--t-out {text!r}: expected times in s separated by commas") from None


def _parameter(text: str) -> tuple[str, float]:
    name, eq, value = text.partition("=")
    if not eq:
        raise InputError(f"--set {text!r}: expected NAME=VALUE (e.g. mu_tip=0.02)")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise InputError(f"--set {text!r}: {value!r} is not a number") from None


def simulate_command(args: argparse.Namespace):
    """Set up and run ``beamid simulate`` (a deck and/or flags); returns
    ``(source, model, load, t_out, options, output_prefix)``."""
    import numpy as np

    from .loads import TipForce, TipLoad, TipMoment
    from .model import pace

    if args.deck is not None:
        from .decks import read_deck

        deck = read_deck(args.deck)
        if getattr(deck, "task", None) != "simulate" or not getattr(deck, "simulate", None):
            raise InputError(f"{args.deck}: task {deck.task!r} is not a dynamic deck (task "
                             f"'simulate'); run it with `beamid run {args.deck}`")
        model, load = deck.model, deck.load
        opts = dict(deck.simulate)
        t_out = np.asarray(opts.pop("t_out"), dtype=float)
        prefix = deck.output_prefix
        source = str(args.deck)
    else:
        # the dissertation's runs leave out the rotary inertias (docs/dynamics.md)
        model = pace(J_elbow=0.0, J_tip=0.0)
        load = TipForce(fy=SIMULATE_DEFAULTS["fy"])
        opts = {"elements_per_beam": SIMULATE_DEFAULTS["elements_per_beam"]}
        t_out = np.linspace(0.0, SIMULATE_DEFAULTS["t_end"], SIMULATE_DEFAULTS["n_out"])
        prefix = Path(SIMULATE_DEFAULTS["output"])
        source = "beamid simulate"
    if args.set:
        values = dict(_parameter(p) for p in args.set)
        try:
            model = model.replace(**values)
        except InputError as exc:
            raise InputError(f"--set {' '.join(args.set)}: {exc}") from None
    if (args.fx, args.fy, args.moment) != (None, None, None):
        base = load if isinstance(load, TipLoad) else TipLoad()
        load = TipForce(fx=base.fx if args.fx is None else args.fx,
                        fy=base.fy if args.fy is None else args.fy) + \
            TipMoment(base.moment if args.moment is None else args.moment)
    if args.t_out is not None and (args.t_end is not None or args.n_out is not None):
        raise InputError("--t-out gives the output times: give it without --t-end and --n-out")
    if args.t_out is not None:
        t_out = np.asarray(_times(args.t_out), dtype=float)
    elif args.t_end is not None or args.n_out is not None:
        t_end = float(t_out[-1]) if args.t_end is None else args.t_end
        n_out = t_out.size if args.n_out is None else args.n_out
        if not (0.0 < t_end < math.inf):
            raise InputError(f"--t-end {t_end:g}: expected a time > 0 (s)")
        if n_out < 2:
            raise InputError(f"--n-out {n_out}: expected at least 2")
        t_out = np.linspace(0.0, t_end, n_out)
    for name in ("elements_per_beam", "motor_gain", "integrator", "friction", "rtol", "dt"):
        value = getattr(args, name)
        if value is not None:
            opts[name] = value
    if args.integrator is not None and args.friction is None and args.deck is not None:
        opts.pop("friction", None)     # the new integrator's default law
    if getattr(args, "loads", None) is not None:
        from .load_histories import read_loads_csv

        opts["loads"] = read_loads_csv(args.loads)
    if args.output is not None:
        prefix = Path(args.output)
    return source, model, load, t_out, opts, prefix


def _cmd_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from .decks import history_columns
    from .dynamics import simulate
    from .history import series

    source, model, load, t_out, opts, prefix = simulate_command(args)
    run = simulate(model, load, t_out, **opts)
    # the columns of the history file beamid-batch writes for a dynamic deck
    columns = history_columns(model.nbeams, run)
    header = ",".join(columns)
    table = np.column_stack([run.t if c == "t" else series(run, c) for c in columns])

    def write_csv(tmp: str) -> None:
        np.savetxt(tmp, table, delimiter=",", fmt="%.16E", header=header, comments="")

    outputs = [(Path(f"{prefix}_history.csv"), write_csv)]
    if not args.no_plots:
        def write_png(tmp: str) -> None:
            from .plotting import agg_pyplot, plot_history

            plt = agg_pyplot()
            fig = plot_history(run)
            try:
                fig.savefig(tmp, dpi=110, format="png")
            finally:
                plt.close(fig)

        outputs.append((Path(f"{prefix}_history.png"), write_png))
    files = _write_all(outputs)
    print(_run_line(source, run))
    _print_files(files)
    return EXIT_OK


# ------------------------------------------------- reproduce, demo, figures

def _cmd_reproduce(args: argparse.Namespace) -> int:
    from .tables import format_checks, reproduce

    checks = reproduce(args.tables)
    print(format_checks(checks))
    return EXIT_NOT_REPRODUCED if any(c.status == "FAIL" for c in checks) else EXIT_OK


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import demo

    return demo(Path(args.out))


def _cmd_figures(args: argparse.Namespace) -> int:
    from .figures import write_figures

    _print_files(write_figures(Path(args.out), args.names))
    return EXIT_OK


# ------------------------------------------------------------------ parser

@functools.lru_cache(maxsize=None)
def _table_list() -> str:
    try:
        from .tables import table_names

        return " ".join(table_names())
    except Exception:  # noqa: BLE001 - help must print even with a broken install
        return "2 3 4 ..."


@functools.lru_cache(maxsize=None)
def _parameter_list() -> str:
    try:
        from .model import pace

        return " ".join(pace().names())
    except Exception:  # noqa: BLE001 - help must print even with a broken install
        return "see docs/static.md"


def _cmd_consistency(args: argparse.Namespace) -> int:
    from .consistency import run_consistency_deck

    try:
        return _report(run_consistency_deck(
            args.deck, replicates=args.replicates, seed=args.seed, scheduler=args.scheduler,
            out=args.out, workers=args.workers, plots=not args.no_plots), one_line=True)
    except ImportError as exc:  # Dask missing: a bad request, not a crash
        raise InputError(str(exc)) from None


def _cmd_design(args: argparse.Namespace) -> int:
    from .design import run_design_deck

    return _report(run_design_deck(
        args.deck, forces=args.force, moments=args.moment, wires=args.wire,
        quantities=args.quantities, sigma=args.sigma, target=args.target, out=args.out,
        top=args.top, plots=not args.no_plots, times=args.times), one_line=True)


def _commands() -> list:
    """Every subcommand: (name, handler, help, description, arguments), an
    argument (flags separated by spaces, keyword arguments of add_argument)."""
    from .figures import FIGURES

    def no_plots(text: str = "write the CSV file only"):
        return ("--no-plots", dict(action="store_true", help=text))

    deck = ("deck", dict(help="estimation deck (docs/decks.md, Estimation decks)"))
    out = ("--out", dict(default="out", help="folder for the PNG files (default: out)"))
    mc_out = ("--out", dict(default=None, help="folder for the CSV and PNG (default: the "
                                               "deck's output)"))

    def values(metavar: str, text: str, kind=FINITE):   # numbers, default a fresh []
        return dict(type=kind, nargs="*", default=[], metavar=metavar, help=text)

    # the measurement chain (docs/decks.md, "The measurement chain"): &fit items
    # the Fortran deck reader checks as the deck's own; they replace the deck's
    chain = [
        ("--time-offset", dict(nargs="+", default=(), metavar="EXPERIMENT", help="fit a clock "
                               "offset t0 of these releases' records (&fit time_offset)")),
        ("--bias", dict(nargs="+", default=(), metavar="CHANNEL", help="fit a bias of these "
                        "channels, experiment:quantity or a quantity (&fit bias)")),
        ("--scale", dict(nargs="+", default=(), metavar="CHANNEL", help="fit a scale of these "
                         "channels (&fit scale)")),
        ("--loss", dict(choices=("linear", "huber", "cauchy"), help="robust loss by "
                        "iteratively reweighted least squares (&fit loss)")),
        ("--burn-in", dict(type=_number(0.0, what="a time >= 0 (s)"), metavar="T",
                           help="rows of the releases before T predicted, not fitted "
                                "(&fit burn_in)")),
        ("--estimate-sigma", dict(nargs="*", default=None, metavar="CHANNEL", help="estimate "
                                  "the sigma of these channels from the residuals, without a "
                                  "CHANNEL of every channel (&fit estimate_sigma)")),
        ("--initial-velocity", dict(nargs="+", default=(), metavar="EXPERIMENT", help="fit the "
                                    "initial tip normal velocity v0 of these releases (&fit "
                                    "initial_velocity)")),
    ]
    estimation = [(name, _cmd_estimate, text, f"{text[0].upper()}{text[1:]}. The subcommand "
                   "overrides the deck's task (docs/decks.md); the measurement chain's "
                   "options replace the deck's &fit items.",
                   [deck, no_plots("write CSV files only"), *chain]) for name, text in (
        ("fit", "estimate parameters from a measurement deck (fit only)"),
        ("compare", "fit, then measured against model with residual tests"),
        ("diagnose", "fit, then rank the candidate missing effects"),
        ("improve", "fit, diagnose and add effects until none is significant"))]
    return [
        ("run", _cmd_run, "run a namelist deck of any task, as beamid-batch does",
         "Run a deck (docs/decks.md) with the deck's task: static, fe_static, fe_modes, "
         "simulate, fit, compare, diagnose, improve or identify; writes the files "
         "beamid-batch writes and prints what it prints (a summary line and the files), "
         "estimation decks their table first.",
         [("deck", dict(help="path of the deck")),
          ("--quiet -q", dict(action="store_true", help="print nothing (as beamid-batch "
                                                          "--quiet)")),
          no_plots("estimation decks: write the CSV files only")]),
        ("simulate", _cmd_simulate, "release the arm and integrate (dynamics); writes the "
         "history CSV and its figure",
         "Release the chain from its static shape under a tip load and follow it "
         "(docs/dynamics.md). Without a deck: the PACE arm without rotary inertia, released "
         "from fy = 8 N, 4 elements per beam, 27 outputs over 2.6 s, output prefix "
         "out/simulate. Flags override the deck.",
         [("deck", dict(nargs="?", help="a dynamic deck (task 'simulate'), optional")),
          ("--fx", dict(type=FINITE, help="release load: tip force x (N)")),
          ("--fy", dict(type=FINITE, help="release load: tip force y (N) (default 8)")),
          ("--moment", dict(type=FINITE, help="release load: tip moment (N m)")),
          ("--elements-per-beam -e", dict(dest="elements_per_beam", type=_count(1), help="elements "
                                          "per beam (default 4: the dissertation's 8-element "
                                          "arm)")),
          ("--motor-gain -g", dict(dest="motor_gain", type=FINITE, help="tip motor gain g, T = "
                                   "-r_motor g dPsi_tip/dt (Eq. 150) (default 0)")),
          ("--t-end", dict(type=POSITIVE, help="last output time (s) (default 2.6)")),
          ("--n-out", dict(type=_count(2), help="number of equally spaced output times from 0 to "
                                          "--t-end (default 27)")),
          ("--t-out", dict(help="output times instead, e.g. 0,0.1,0.5 (s)")),
          ("--integrator", dict(choices=("implicit", "rk4"), help="implicit (Radau IIA, "
                                "default) or rk4 (fixed step --dt)")),
          ("--friction", dict(choices=("sign", "smooth", "sign_literal"), help="friction law "
                              "(default: beamid.simulate's, docs/dynamics.md)")),
          ("--rtol", dict(type=POSITIVE, help="implicit tolerance (default: beamid.simulate's)")),
          ("--dt", dict(type=POSITIVE, help="RK4 step in s (default 1e-5, the dissertation's)")),
          ("--loads", dict(metavar="CSV", help="load histories (docs/loads.md): a CSV with a "
                           "column t and one column per target (tip_fx, tip_fy, tip_torque, "
                           "motor_open, hub), each a table acting from t = 0")),
          ("--set", dict(action="append", metavar="NAME=VALUE", help="a model parameter, "
                         "e.g. --set mu_tip=0.02 (repeatable); one of: " + _parameter_list())),
          ("--output -o", dict(help="output prefix (default: the deck's, or out/simulate): "
                                    "writes PREFIX_history.csv/.png")),
          no_plots()]),
        ("reproduce", _cmd_reproduce, "compare with the dissertation's published tables",
         "Run the bundled decks of the published tables and compare; exit 1 when a value "
         "is not reproduced.",
         [("tables", dict(nargs="*", help="tables to check, all if none; one of: ",
                          help_list=_table_list))]),
        ("demo", _cmd_demo, "reproduce the tables and draw the demo figures",
         "Reproduce the published tables (as `beamid reproduce`), find the hidden effects of "
         "the demo decks (inputs/demo) and draw the demo figures into --out.", [out]),
        ("figures", _cmd_figures, "draw the dynamic Figures 20-25 as PNG files",
         "Simulate and draw the dissertation's dynamic Figures 20-25 (docs/dynamics.md) as "
         "PNG files in --out.",
         [("names", dict(nargs="*", help="figures to draw, all if none; one of: "
                         + " ".join(n.replace("figure", "") for n in FIGURES))), out]),
        *estimation,
        ("identify", _cmd_identify, "run estimation decks as stages (static, free, forced), "
         "carrying estimates and covariance (docs/workflow.md)",
         "Fit estimation decks in order, each stage starting from the last one's estimates "
         "with its covariance as a priori information (Eq. 146-148, 164-166; "
         "docs/workflow.md); writes <output>_identify.csv and its figure.",
         [("decks", dict(nargs="+", help="estimation decks, one per stage, in order, or one "
                         "deck of task 'identify' holding its stages (docs/decks.md)")),
          no_plots()]),
        ("consistency", _cmd_consistency, "Monte Carlo check of a fit's sigmas "
         "(docs/consistency.md)",
         "Fit the deck, refit it to noisy replicates of its fitted data and compare the "
         "spread of the estimates with the fit's sigmas (docs/consistency.md); writes "
         "<prefix>_consistency.csv and its figure.",
         [deck, ("--replicates", dict(type=_count(2), default=200, help="noisy data sets (default "
                                                                  "200)")),
          ("--seed", dict(type=_count(0), default=7, help="seed of the replicates (default 7)")),
          ("--scheduler", dict(default=None, help="Dask scheduler address "
                               "(tcp://host:8786); local cores if not given")),
          ("--workers", dict(type=_count(1), default=None, help="local processes (default: all "
                             "cores; 1 = in this process)")),
          mc_out, no_plots("write the CSV only")]),
        ("design", _cmd_design, "rank candidate measurements by the sigma they would leave",
         "Fit the deck and rank candidate measurements (tip forces, moments, wires, the "
         "deck's own experiments and release times) by the sigma they would leave "
         "(docs/consistency.md); sigmas default to the deck's own rows of a quantity, else to "
         "a printed default; writes <prefix>_design.csv and its figure.",
         [deck, ("--force", values("FY", "candidate transverse tip forces (N)")),
          ("--moment", values("M", "candidate tip moments (N m)")),
          ("--wire", values("LW", "candidate radial wire lengths (m)", POSITIVE)),
          ("--quantities", dict(nargs="*", default=None, help="measured quantities (default: "
                                "x_tip y_tip tip_angle x_elbow y_elbow wire_force)")),
          ("--sigma", dict(nargs="*", default=None, metavar="[Q=]SIGMA", help="one sigma for "
                           "all, or QUANTITY=SIGMA items (default: the deck's own)")),
          ("--target", dict(default=None, help="parameter whose sigma to minimize (default: "
                            "D-criterion over all free)")),
          ("--top", dict(type=_count(1), default=20, help="rows to print (default 20)")),
          mc_out, no_plots("write the CSV only"),
          ("--times", values("T", "measurement times (s) of the deck's release "
                              "experiments as candidates (default: the deck's own)", POSITIVE))])]


class _Parser(argparse.ArgumentParser):
    """argparse with one error line that names the option, a suggestion for
    a mistyped option or subcommand, and the subcommand's own usage; an
    argument's help may end in a list computed only when that help is printed
    (an argument's ``help_list``): the table names of ``reproduce`` come from
    reading every seed deck, which ``beamid --help`` and every other
    subcommand must not pay for."""

    def format_help(self) -> str:
        for action in self._actions:
            fill = getattr(action, "help_list", None)
            if fill is not None:
                action.help = f"{action.help}{fill()}"
                action.help_list = None
        return super().format_help()

    def error(self, message: str):   # type: ignore[override]
        self.print_usage(sys.stderr)
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message}\n")

    def unknown(self, extra: Sequence[str]):
        """The error for arguments this (sub)parser does not take."""
        import difflib

        options = [o for a in self._actions for o in a.option_strings]
        opts = [x for x in extra if x.startswith("-")]
        if not opts:
            self.error(f"unexpected argument {' '.join(extra)}")
        word = opts[0].split("=", 1)[0]
        close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]}?)" if close else f" (options: {' '.join(options)})"
        self.error(f"unknown option {word}{hint}")




def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = _Parser(
        prog="beamid",
        description="Large deformation of flexible beam chains and the inverse problem "
                    "(after McVay 1996).",
        epilog="exit codes: 0 ok, 1 a published value not reproduced, 2 bad input, "
               "3 no convergence, 4 an output file cannot be written, 5 internal error")
    parser.add_argument("--version", action="version", version=f"beamid {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, func, text, description, arguments in _commands():
        p = sub.add_parser(name, help=text, description=description)
        for flags, options in arguments:
            options = dict(options)
            fill = options.pop("help_list", None)
            p.add_argument(*flags.split(), **options).help_list = fill
        p.set_defaults(func=func)
    return parser


def _subparser(parser: argparse.ArgumentParser, name: str) -> "_Parser":
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices[name]


def _in_option_words(message: str, parser: argparse.ArgumentParser, command: str) -> str:
    """An API refusal in the command line's words: a message that starts with
    a keyword the subcommand's option feeds (``elements_per_beam = ...``)
    names the option instead (``--elements-per-beam = ...``)."""
    for action in _subparser(parser, command)._actions:
        if action.option_strings and message.startswith(f"{action.dest} = "):
            longest = max(action.option_strings, key=len)
            return longest + message[len(action.dest):]
    return message


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``beamid`` console command; returns the exit code
    (module docstring). Argument errors exit 2 through argparse."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:      # an option the subcommand does not take: its usage, a suggestion
        _subparser(parser, args.command).unknown(extra)
    try:
        return int(args.func(args))
    except BrokenPipeError:
        # the reader of a pipe stopped early (`beamid reproduce | head`): stop quietly,
        # with the exit status of a process killed by SIGPIPE, as other Unix tools
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 128 + 13
    except BeamidError as exc:
        # the error's own exit code (beamid_status's table: 2 bad input, 3 numerical
        # failure, 4 an output that cannot be written); a BeamidError that is an
        # OSError is an unwritable output
        print(f"beamid: error: {_in_option_words(str(exc), parser, args.command)}",
              file=sys.stderr)
        code = getattr(exc, "exit_code", EXIT_INPUT)
        return EXIT_OUTPUT if isinstance(exc, OSError) else int(code)
    except OSError as exc:   # an output path that is a directory, a full disk, ...
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"beamid: error: cannot write {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_OUTPUT
    except KeyboardInterrupt:
        print("beamid: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug: say so, with the traceback
        traceback.print_exc()
        print(f"beamid: internal error ({type(exc).__name__}: {exc}); please report it",
              file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
