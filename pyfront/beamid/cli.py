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


def _cmd_consistency(args: argparse.Namespace) -> int:
    # issue 17 (mc helper): implementation in beamid.consistency
    from .consistency import run_consistency_deck

    try:
        text, files, _ = run_consistency_deck(args.deck, replicates=args.replicates,
                                              seed=args.seed, scheduler=args.scheduler,
                                              out=args.out, workers=args.workers,
                                              plots=not args.no_plots)
    except ImportError as exc:  # Dask missing: a bad request, not a crash
        raise InputError(str(exc)) from None
    print(text)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def _cmd_design(args: argparse.Namespace) -> int:
    # issue 17 (mc helper): implementation in beamid.design
    from .design import run_design_deck

    text, files, _ = run_design_deck(args.deck, forces=args.force, moments=args.moment,
                                     wires=args.wire, quantities=args.quantities,
                                     sigma=args.sigma, target=args.target, out=args.out,
                                     top=args.top, plots=not args.no_plots)
    print(text)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def _add_mc_parsers(sub) -> None:
    # issue 17 (mc helper): beamid consistency / beamid design
    p = sub.add_parser("consistency", help="Monte Carlo check of a fit's sigmas (docs/consistency.md)")
    p.add_argument("deck", help="estimation deck (docs/decks.md, Estimation decks)")
    p.add_argument("--replicates", type=int, default=200, help="noisy data sets (default 200)")
    p.add_argument("--seed", type=int, default=7, help="seed of the replicates (default 7)")
    p.add_argument("--scheduler", default=None,
                   help="Dask scheduler address (tcp://host:8786); local cores if not given")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes (default: all cores; 1 = in this process)")
    p.add_argument("--out", default=None, help="folder for the CSV and PNG (default: the deck's output)")
    p.add_argument("--no-plots", action="store_true", help="write the CSV only")
    p.set_defaults(func=_cmd_consistency)
    p = sub.add_parser("design", help="rank candidate measurements by the sigma they would leave")
    p.add_argument("deck", help="estimation deck (docs/decks.md, Estimation decks)")
    p.add_argument("--force", type=float, nargs="*", default=[], metavar="FY",
                   help="candidate transverse tip forces (N)")
    p.add_argument("--moment", type=float, nargs="*", default=[], metavar="M",
                   help="candidate tip moments (N m)")
    p.add_argument("--wire", type=float, nargs="*", default=[], metavar="LW",
                   help="candidate radial wire lengths (m)")
    p.add_argument("--quantities", nargs="*", default=None,
                   help="measured quantities (default: x_tip y_tip tip_angle x_elbow y_elbow wire_force)")
    p.add_argument("--sigma", nargs="*", default=None, metavar="[Q=]SIGMA",
                   help="one sigma for all, or QUANTITY=SIGMA items (default: the deck's own)")
    p.add_argument("--target", default=None,
                   help="parameter whose sigma to minimize (default: D-criterion over all free)")
    p.add_argument("--top", type=int, default=20, help="rows to print (default 20)")
    p.add_argument("--out", default=None, help="folder for the CSV and PNG (default: the deck's output)")
    p.add_argument("--no-plots", action="store_true", help="write the CSV only")
    p.set_defaults(func=_cmd_design)


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
    _add_mc_parsers(sub)
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
