"""The Python package's structure (issue 25): no import cycle between its
modules, function-local imports only for what is optional or deliberately
deferred, and ``beamid --help`` reads no deck."""
import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import beamid
import beamid.tables
from beamid.cli import _table_list, build_parser, main

PACKAGE = Path(beamid.__file__).parent
INPUTS = Path(__file__).resolve().parents[1] / "inputs"

#: Modules a function may import locally: optional (Dask; tqdm, whose absence
#: progress.py tolerates; pandas, which only Measurements.to_frame needs and
#: names when missing; pyuff, which only read_uff needs and names when
#: missing) or deliberately deferred (matplotlib: importing
#: pyplot picks a backend, which the command line sets to Agg first, and
#: costs more than the rest of ``import beamid``).
LOCAL_OK = ("matplotlib", "distributed", "dask", "tqdm", "pandas", "pyuff")
#: cli.py still imports its subcommands' modules in the handlers (issue 25:
#: to move to its top with the command-line work on that file).
LOCAL_EXEMPT = ("cli.py",)


def _imports(path: Path):
    """(relative target module, is it inside a function, line) of every
    import in a module of the package."""
    tree = ast.parse(path.read_text())
    local = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            local.update(id(sub) for sub in ast.walk(node)
                         if isinstance(sub, (ast.Import, ast.ImportFrom)))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            targets = [node.module.split(".")[0]] if node.module else \
                [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            targets = ["<" + node.module + ">"]
        elif isinstance(node, ast.Import):
            targets = ["<" + a.name + ">" for a in node.names]
        else:
            continue
        for t in targets:
            yield t, id(node) in local, node.lineno


def _graph() -> dict[str, set[str]]:
    modules = {p.stem for p in PACKAGE.glob("*.py")}
    return {p.stem: {t for t, _, _ in _imports(p) if t in modules and t != p.stem}
            for p in PACKAGE.glob("*.py")}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle_between_the_package_modules():
    """Module-level and function-local imports alike: a cycle hidden in a
    function is still a cycle."""
    graph = _graph()
    assert "dyn_diagnosis" in graph["plot_fit"] and "diagnosis" in graph["dyn_diagnosis"]
    assert _cycles(graph) == []


def test_function_local_imports_only_for_optional_or_deferred_modules():
    bad = []
    for path in sorted(PACKAGE.glob("*.py")):
        if path.name in LOCAL_EXEMPT:
            continue
        for target, local, line in _imports(path):
            if local and not target.strip("<>").split(".")[0] in LOCAL_OK:
                bad.append(f"{path.name}:{line} {target}")
    assert bad == []


def test_import_beamid_registers_the_dynamic_candidates():
    """In a fresh interpreter: the release family's effects and handlers are
    installed by ``import beamid`` alone."""
    code = ("import beamid, beamid.diagnosis as d; "
            "print(sorted(set(d.EFFECTS) & {'friction', 'drag', 'mesh'}), "
            "sorted(d._RELEASE_FAMILY))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split("] [")
    assert out[0] == "['drag', 'friction', 'mesh'"
    assert out[1].strip() == ("'candidate', 'compare', 'default_candidates', 'diagnosis', "
                              "'refine_mesh']")


def _help(argv, monkeypatch, capsys) -> tuple[str, int]:
    calls = []
    _table_list.cache_clear()      # the list is read once per process; count this read
    real = beamid.tables._all_seed_decks
    monkeypatch.setattr(beamid.tables, "_all_seed_decks",
                        lambda: calls.append(1) or real())
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    return capsys.readouterr().out, len(calls)


@pytest.mark.parametrize("argv", [["--help"], ["simulate", "--help"], ["fit", "--help"]])
def test_help_reads_no_seed_deck(argv, monkeypatch, capsys):
    text, reads = _help(argv, monkeypatch, capsys)
    assert "usage: beamid" in text
    assert reads == 0


def test_reproduce_help_still_lists_the_tables(monkeypatch, capsys):
    """The list is computed when that help is printed, not before."""
    text, reads = _help(["reproduce", "--help"], monkeypatch, capsys)
    assert reads == 1
    assert "one of: 2 3 4 6" in " ".join(text.split()) and "circle" in text
    build_parser()   # building the parser reads nothing
    assert reads == 1


@pytest.mark.skipif(shutil.which("strace") is None, reason="needs strace")
@pytest.mark.parametrize("argv, reads", [(["--help"], False), (["reproduce", "--help"], True)])
def test_help_opens_no_file_under_inputs(argv, reads):
    """The console command under strace: ``beamid --help`` opens no deck or
    CSV of inputs/ (the editable install's loader may list the folders:
    directories are not counted); ``beamid reproduce --help``, which lists
    the tables of the seed decks, does."""
    exe = Path(sys.executable).with_name("beamid")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "beamid"]
    run = subprocess.run(["strace", "-f", "-e", "trace=openat", "-o", "/dev/stderr", *cmd,
                          *argv], capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr[-2000:]
    opened = [line for line in run.stderr.splitlines()
              if str(INPUTS) in line and "O_DIRECTORY" not in line]
    assert "openat" in run.stderr and bool(opened) == reads
