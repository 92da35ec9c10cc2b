"""The demo that ``make demo`` runs: reproduce the published tables, draw the
PACE arm under the seed's loads (shear-only seed form beside the exact
elastica), run the compare-diagnose-improve workflow on the bundled deck
whose measurements hide the physics the starting model lacks, and redraw the
dynamic Figures 20-25 (beamid.figures)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from .figures import GAINS, figure_runs, write_figures
from .fit_decks import read_fit_deck, run_fit_deck
from .loads import RadialWire, TipForce
from .model import pace
from .plotting import plot_shapes, save_png
from .progress import progress
from .tables import format_checks, inputs_dir, reproduce
from .static import solve_static


def demo(out: Path) -> int:
    """Write the demo figures into ``out``; return 1 if a table failed."""
    import matplotlib

    matplotlib.use("Agg")

    checks = reproduce()
    print(format_checks(checks))
    out.mkdir(parents=True, exist_ok=True)

    # radial wire of Table 2 and Figure 9: several wire lengths, C1 = C2 = 0
    lengths = (1.45, 1.4, 1.3, 1.1, 0.9)
    written = [_forms_figure(
        out / "wire_shapes.png", "PACE arm, radial wire to the root (Figure 9, Table 2)",
        [RadialWire(lw) for lw in lengths],
        lambda r, i: f"Lw = {lengths[i]} m, T = {r.wire_force:.1f} N")]
    # directed transverse tip force, 3 to 8 N (Figure 11, Tables 4-5)
    forces = (3.0, 4.0, 6.0, 8.0)
    written.append(_forms_figure(
        out / "tip_force_shapes.png", "PACE arm, transverse tip force (Figure 11)",
        [TipForce(fy=f) for f in forces],
        lambda r, i: f"F = {forces[i]:g} N, tip y = {r.tip_y:.4f} m"))

    # the main job: find the hidden effects in inputs/demo/hidden_effect.csv
    # and the same on time histories: a release measured on a rig with rotary
    # inertia and tip drag (inputs/demo/dynamic_hidden_effect.csv)
    for name in ("hidden_effect", "dynamic_hidden_effect"):
        deck = read_fit_deck(inputs_dir("demo") / f"{name}.nml")
        deck = dataclasses.replace(deck, output=str((out / name).resolve()))
        print()
        print(f"beamid improve inputs/demo/{name}.nml")
        text, files, _ = run_fit_deck(deck)
        print(text)
        written += files

    # the dynamic Figures 20-25 (implicit integrator, about a second): the three
    # runs one by one, so that a terminal shows the progress
    runs = {}
    for gain in progress(GAINS, desc="figures 20-25"):
        runs.update(figure_runs([gain]))
    written += write_figures(out, runs=runs)

    for p in written:
        print(f"wrote {_shown(Path(p))}")
    return 1 if any(c.status == "FAIL" for c in checks) else 0


def _forms_figure(path: Path, title: str, loads, label) -> Path:
    """Shapes under `loads`, seed form (left) beside the exact elastica (right)."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 6))
    forms = {"seed form (axial_coupling = 0)": 0.0, "exact elastica (axial_coupling = 1)": 1.0}
    for ax, (form, a) in zip(axes, forms.items()):
        results = [solve_static(pace(axial_coupling=a), load) for load in loads]
        plot_shapes(results, [label(r, i) for i, r in enumerate(results)], ax=ax)
        ax.set_title(form, fontsize=10)
    fig.suptitle(title)
    fig.tight_layout()
    return save_png(fig, path)


def _shown(path: Path) -> Path:
    """``path`` relative to the current folder when it lies below it."""
    try:
        return path.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return path
