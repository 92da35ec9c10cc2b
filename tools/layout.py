"""Move the Fortran sources into folders by layer (docs/development.md, Layers)
in one step: ``git mv`` of every file and the matching path edits in
``meson.build`` (and, with --refs, in the docs, tests and Python docstrings
that name a source file).

The move waits until the branches in flight are merged (a move in a branch
makes every other branch's edit of the same file a rename conflict):

    python tools/layout.py --check        # every file placed, none missing
    python tools/layout.py                # print the moves and edits (changes nothing)
    python tools/layout.py --move --refs  # move, edit meson.build and the references

Nothing moves without ``--move`` (a run with no argument once moved a whole
tree by mistake).

Run it at the top of a clean work tree; it refuses when a source file of
``fortran/`` has no layer here (a module added since: give it one in LAYERS)
or when the tree has uncommitted changes. The include files go with the
module that includes them (gfortran looks for an include file next to the
source first), so no include path changes. Afterwards: rebuild (``make
setup`` or ``import beamid``), ``make test``, commit.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The layers, lowest first: a module uses only modules of its own layer or
#: of a layer above it in this list (checked by check_uses).
LAYERS: dict[str, tuple[str, ...]] = {
    "base": ("beamid_kinds.f90", "beamid_status.f90", "beamid_lapack.f90",
             "beamid_band.F90", "beamid_band_generic.inc", "beamid_model.f90",
             "beamid_presets.f90"),
    "statics": ("beamid_arclength.f90",),
    "fe": ("beamid_fe_element.f90", "beamid_fe_assembly.f90", "beamid_fe_static.f90",
           "beamid_fe_modes.f90", "beamid_fe_nodes.f90"),
    "dynamics": ("beamid_forcing.f90", "beamid_loads.f90", "beamid_dynamics.f90",
                 "beamid_hub.f90", "beamid_integrators.f90", "beamid_radau_solve.inc",
                 "beamid_release.f90"),
    "inverse": ("beamid_estimation.f90", "beamid_chain_fit.f90", "beamid_design.f90",
                "beamid_observations.f90", "beamid_effects.f90",
                "beamid_static_experiments.f90", "beamid_dynamic_experiments.f90",
                "beamid_family.f90", "beamid_families.f90", "beamid_problem.f90",
                "beamid_inverse.f90", "beamid_dyn_diagnosis.f90", "beamid_ladder.f90",
                "beamid_modal.f90", "beamid_modal_experiments.f90", "beamid_replicates.f90"),
    "io": ("beamid_namelist.f90", "beamid_measurements.f90", "beamid_deck.f90",
           "beamid_tasks.f90", "beamid_deck_run.f90", "beamid_chain_deck.f90",
           "beamid_deck_history.f90"),
}
#: fortran/api and fortran/app keep their folders (already one layer each).
KEPT = ("api", "app")


def sources() -> list[str]:
    """The files directly under fortran/ (the ones still to move)."""
    return sorted(p.name for p in (ROOT / "fortran").iterdir() if p.is_file())


def located() -> dict[str, Path]:
    """Every library source by name: directly under fortran/ or already in
    a layer folder (after the move)."""
    found = {name: ROOT / "fortran" / name for name in sources()}
    for layer in LAYERS:
        folder = ROOT / "fortran" / layer
        if folder.is_dir():
            found.update({p.name: p for p in folder.iterdir() if p.is_file()})
    return found


def placement() -> dict[str, str]:
    """file name -> its layer folder."""
    where: dict[str, str] = {}
    for layer, names in LAYERS.items():
        for name in names:
            if name in where:
                raise SystemExit(f"layout: {name} is in two layers ({where[name]}, {layer})")
            where[name] = layer
    return where


def check() -> list[str]:
    """Problems: a source without a layer, a layer entry without a file, a
    module using one of a later layer."""
    where = placement()
    files = located()
    present = set(files)
    problems = [f"fortran/{n}: no layer in tools/layout.py LAYERS" for n in sorted(present)
                if n not in where]
    problems += [f"fortran/{n}: listed in LAYERS ({where[n]}) but absent"
                 for n in sorted(where) if n not in present]
    problems += check_uses(where, files)
    return problems


def check_uses(where: dict[str, str], files: dict[str, Path]) -> list[str]:
    """A module may use modules of its own layer and of lower layers only."""
    order = list(LAYERS)
    module_layer = {n.rsplit(".", 1)[0].lower(): where[n] for n in files if n in where}
    problems = []
    for name in sorted(files):
        if name not in where or name.endswith(".inc"):
            continue
        text = files[name].read_text()
        for used in sorted(set(re.findall(r"^\s*use\s+(beamid_\w+)", text, re.M | re.I))):
            layer = module_layer.get(used.lower())
            if layer and order.index(layer) > order.index(where[name]):
                problems.append(f"fortran/{name} ({where[name]}) uses {used} ({layer})")
    return problems


def moves() -> list[tuple[str, str]]:
    """(old, new) paths relative to the root."""
    where = placement()
    return [(f"fortran/{n}", f"fortran/{where[n]}/{n}") for n in sources()]


def rewrite(text: str, pairs: list[tuple[str, str]]) -> str:
    """text with every old path replaced by its new one (whole paths only)."""
    for old, new in pairs:
        text = re.sub(r"(?<![\w/])" + re.escape(old) + r"(?![\w.])", new, text)
    return text


def reference_files() -> list[Path]:
    """Text files that may name a source path: docs, README, tests, Python."""
    out = [ROOT / "README.md"]
    for pattern in ("docs/*.md", "tests/**/*.py", "tests/fortran/*.f90",
                    "pyfront/beamid/*.py", "tools/*.py", "benchmarks/**/*.py",
                    "fortran/**/*.f90", "Makefile"):
        out += [p for p in ROOT.glob(pattern) if p.is_file()]
    return sorted(set(out) - {Path(__file__).resolve()})


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="only check LAYERS against fortran/")
    ap.add_argument("--move", action="store_true",
                    help="perform the moves and edits (without it: print them only)")
    ap.add_argument("--dry-run", action="store_true",
                    help="print, change nothing (the default; kept for older notes)")
    ap.add_argument("--refs", action="store_true",
                    help="also rewrite the paths named in docs, tests and docstrings")
    args = ap.parse_args(argv)
    if args.move and args.dry_run:
        print("layout: --move and --dry-run contradict each other; give one", file=sys.stderr)
        return 2
    args.dry_run = not args.move
    problems = check()
    if problems:
        print("\n".join(problems), file=sys.stderr)
        return 1
    if args.check:
        print(f"layout: {len(located())} files in {len(LAYERS)} layers ({len(sources())} to "
              "move), uses in layer order")
        return 0
    pairs = moves()
    if not args.dry_run:
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, capture_output=True, text=True, check=True).stdout
        if dirty.strip():
            print("layout: commit or stash the changes first:\n" + dirty, file=sys.stderr)
            return 1
    for old, new in pairs:
        print(f"git mv {old} {new}")
        if not args.dry_run:
            (ROOT / new).parent.mkdir(exist_ok=True)
            subprocess.run(["git", "mv", old, new], cwd=ROOT, check=True)
    files = [ROOT / "meson.build"] + (reference_files() if args.refs else [])
    for path in files:
        text = path.read_text()
        new_text = rewrite(text, pairs)
        if new_text != text:
            print(f"edit {path.relative_to(ROOT)}")
            if not args.dry_run:
                path.write_text(new_text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
