"""Run every deck of inputs/seed and inputs/demo with two beamid-batch programs and
compare their output files byte for byte (the "same numbers" rule of a refactor).

    python benchmarks/compare_decks.py OLD_BATCH NEW_BATCH [--jobs 2] [--keep]

Each program runs on its own copy of inputs/ in a temporary directory (decks write
their outputs relative to themselves); the two trees are then compared file by file.
Prints one line per deck (its exit codes, the files that differ) and exits 1 if any
file differs or is missing on one side.
"""
from __future__ import annotations

import argparse
import filecmp
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(batch: str, deck: Path) -> int:
    proc = subprocess.run([batch, "--quiet", deck.name], cwd=deck.parent,
                          capture_output=True, text=True)
    return proc.returncode


def _tree_files(top: Path) -> set[Path]:
    return {p.relative_to(top) for p in top.rglob("*") if p.is_file()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--keep", action="store_true", help="keep the temporary trees")
    args = ap.parse_args(argv)
    args.old, args.new = (str(Path(b).resolve()) for b in (args.old, args.new))
    tmp = Path(tempfile.mkdtemp(prefix="beamid_decks_"))
    trees = {}
    for side in ("old", "new"):
        trees[side] = tmp / side / "inputs"
        shutil.copytree(ROOT / "inputs", trees[side])
    decks = sorted(p.relative_to(trees["old"]) for sub in ("seed", "demo")
                   for p in (trees["old"] / sub).glob("*.nml"))
    before = {side: _tree_files(trees[side]) for side in trees}
    jobs = [(side, getattr(args, side), trees[side] / d) for d in decks for side in trees]
    with ThreadPoolExecutor(args.jobs) as pool:
        codes = list(pool.map(lambda j: _run(j[1], j[2]), jobs))
    rc = {(j[0], j[2].relative_to(trees[j[0]])): c for j, c in zip(jobs, codes)}
    after = {side: _tree_files(trees[side]) - before[side] for side in trees}
    bad = 0
    for name in sorted(after["old"] | after["new"]):
        if name not in after["old"] or name not in after["new"]:
            print(f"MISSING on one side: {name}")
            bad += 1
        elif not filecmp.cmp(trees["old"] / name, trees["new"] / name, shallow=False):
            print(f"DIFFERS: {name}")
            bad += 1
    for d in decks:
        if rc[("old", d)] != rc[("new", d)]:
            print(f"EXIT CODE differs: {d}: {rc[('old', d)]} vs {rc[('new', d)]}")
            bad += 1
    print(f"{len(decks)} decks, {len(after['new'])} output files, {bad} differences")
    if not args.keep:
        shutil.rmtree(tmp)
    else:
        print(f"trees kept in {tmp}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
