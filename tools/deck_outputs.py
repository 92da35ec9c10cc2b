"""Run every bundled deck (inputs/seed, inputs/demo) with beamid-batch into a
folder, for a before/after comparison of a refactoring ("same numbers": the
output files byte-identical).

    python tools/deck_outputs.py /tmp/before      # on the old commit
    python tools/deck_outputs.py /tmp/after       # on the new one
    python tools/deck_outputs.py --diff /tmp/before /tmp/after

The decks are copied with their data into FOLDER/inputs and run there (a
deck's output path is relative to the deck), so the working tree is not
touched; FOLDER/manifest.txt lists every output file with its SHA-256 and
every deck's exit code. --diff compares two manifests and names the files
that differ, are missing or are new; it exits 1 when any does.
"""
from __future__ import annotations

import argparse
import hashlib
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _batch() -> str:
    exe = shutil.which("beamid-batch") or str(ROOT / ".venv" / "bin" / "beamid-batch")
    if not Path(exe).exists():
        sys.exit("beamid-batch not found: run make setup")
    return exe


def run_all(folder: Path, jobs: int) -> int:
    inputs = folder / "inputs"
    if inputs.exists():
        shutil.rmtree(inputs)
    for sub in ("seed", "demo"):
        shutil.copytree(ROOT / "inputs" / sub, inputs / sub)
    decks = sorted(inputs.glob("*/*.nml"))
    # a copy of the program: a rebuild while the decks run does not touch it
    exe = str(folder / "beamid-batch")
    shutil.copy2(_batch(), exe)

    def one(deck: Path) -> str:
        run = subprocess.run([exe, deck.name], cwd=deck.parent, capture_output=True,
                             check=False)
        return f"{deck.relative_to(inputs)} exit {run.returncode}"

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        codes = list(pool.map(one, decks))
    lines = list(codes)
    for path in sorted(p for p in inputs.rglob("out/**/*") if p.is_file()):
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        lines.append(f"{path.relative_to(inputs)} {digest}")
    (folder / "manifest.txt").write_text("\n".join(lines) + "\n")
    print(f"{len(decks)} decks, {len(lines) - len(decks)} output files: {folder}/manifest.txt")
    return 0


def diff(before: Path, after: Path) -> int:
    def read(folder: Path) -> dict[str, str]:
        out = {}
        for line in (folder / "manifest.txt").read_text().splitlines():
            name, _, value = line.rpartition(" ")
            out[name] = value
        return out

    a, b = read(before), read(after)
    bad = [f"differs: {k}" for k in sorted(a.keys() & b.keys()) if a[k] != b[k]]
    bad += [f"missing after: {k}" for k in sorted(a.keys() - b.keys())]
    bad += [f"new after: {k}" for k in sorted(b.keys() - a.keys())]
    print("\n".join(bad) if bad else f"identical: {len(a)} entries")
    return 1 if bad else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="+", type=Path)
    parser.add_argument("--diff", action="store_true", help="compare two manifests")
    parser.add_argument("--jobs", type=int, default=2, help="decks run at once (default 2)")
    args = parser.parse_args()
    if args.diff:
        if len(args.folders) != 2:
            parser.error("--diff takes two folders")
        return diff(*args.folders)
    if len(args.folders) != 1:
        parser.error("give one folder to run the decks into")
    args.folders[0].mkdir(parents=True, exist_ok=True)
    return run_all(args.folders[0].resolve(), args.jobs)


if __name__ == "__main__":
    sys.exit(main())
