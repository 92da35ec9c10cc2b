"""The ``beamid`` command line. Every subcommand calls the public Python API."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from .errors import BeamidError, ConvergenceError, InputError


def _cmd_run(args: argparse.Namespace) -> int:
    from .decks import read_deck, run

    from .static import StaticResult

    deck = read_deck(args.deck)
    result = run(deck)
    prefix = deck.output_prefix
    if isinstance(result, StaticResult):
        print(f"{args.deck}: tip ({result.tip_x:.6f}, {result.tip_y:.6f}) m, angle "
              f"{result.tip_angle:.6f} rad, wire force {result.wire_force:.4f} N")
        print(f"wrote {prefix}_summary.csv" + (f" and {prefix}_shape.csv"
                                                 if deck.shape_points >= 2 else ""))
    elif deck.task == "simulate":
        print(f"{args.deck}: {result.t.size} output times to {result.t[-1]:g} s "
              f"({result.integrator}, friction {result.friction}); tip w at the end "
              f"{result.tip_w[-1]:.7f} m, energy change {result.energy_change[-1]:.8f} N m")
        print(f"wrote {prefix}_history.csv")
    else:
        print(f"{args.deck}: task {deck.task} done; wrote {prefix}_*.csv")
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from .tables import format_checks, reproduce

    checks = reproduce(args.tables)
    if not checks:
        raise InputError(f"no published values for tables {' '.join(args.tables)}")
    print(format_checks(checks))
    return 1 if any(c.status == "FAIL" for c in checks) else 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import demo

    return demo(Path(args.out))


def _cmd_figures(args: argparse.Namespace) -> int:
    from .figures import write_figures

    for path in write_figures(Path(args.out), args.names):
        print(f"wrote {path}")
    return 0


def _cmd_estimate(args: argparse.Namespace) -> int:
    from .fit_decks import read_fit_deck, run_fit_deck

    deck = read_fit_deck(args.deck)
    if args.command != deck.task and args.command != "fit":
        deck = type(deck)(**{**deck.__dict__, "task": args.command})
    text, files, _ = run_fit_deck(deck, plots=not args.no_plots)
    print(text)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="beamid",
        description="Large deformation of flexible beam chains and the inverse problem.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run a namelist deck (as beamid-batch does)")
    p.add_argument("deck", help="path of the deck (docs/decks.md)")
    p.set_defaults(func=_cmd_run)
    p = sub.add_parser("reproduce", help="compare with the dissertation's published tables")
    p.add_argument("tables", nargs="*", help="tables to check (e.g. 2 4 12 circle); all if none")
    p.set_defaults(func=_cmd_reproduce)
    p = sub.add_parser("demo", help="reproduce the tables and draw the demo figures")
    p.add_argument("--out", default="out", help="folder for the PNG files (default: out)")
    p.set_defaults(func=_cmd_demo)
    p = sub.add_parser("figures", help="draw the dynamic Figures 20-25 as PNG files")
    p.add_argument("names", nargs="*", help="figures to draw (e.g. 20 22 figure25); all if none")
    p.add_argument("--out", default="out", help="folder for the PNG files (default: out)")
    p.set_defaults(func=_cmd_figures)
    for name, text in (("fit", "estimate parameters from a measurement deck (task from the deck)"),
                       ("compare", "fit, then measured against model with residual tests"),
                       ("diagnose", "fit, then rank the candidate missing effects"),
                       ("improve", "fit, diagnose and add effects until none is significant")):
        p = sub.add_parser(name, help=text)
        p.add_argument("deck", help="estimation deck (docs/decks.md, Estimation decks)")
        p.add_argument("--no-plots", action="store_true", help="write CSV files only")
        p.set_defaults(func=_cmd_estimate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``beamid`` console command; returns the exit code
    (0 ok, 1 a published value not reproduced, 2 input error, 3 no convergence)."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except InputError as exc:
        print(f"beamid: error: {exc}", file=sys.stderr)
        return 2
    except ConvergenceError as exc:
        print(f"beamid: error: {exc}", file=sys.stderr)
        return 3
    except BeamidError as exc:  # pragma: no cover - future error kinds
        print(f"beamid: error: {exc}", file=sys.stderr)
        return 4


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
