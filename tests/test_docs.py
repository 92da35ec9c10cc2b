"""The examples in README.md and docs/*.md run, and the values they show hold.

- ```python blocks run in order, one namespace per page (as a reader types them);
  and print nothing (what a page prints, it shows: in a ```pycon block);
- ```pycon blocks (``>>>`` prompts and the output shown) run as doctests in the
  same namespace; the output must be the text shown, character for character
  (examples round their numbers themselves, with f-strings);
- shell blocks (```sh, ```console, ```shell, ```bash, and bare ``` blocks whose
  first line is a command) run in a temporary copy of the inputs with .venv/bin on
  the PATH: each command must exit 0, the lines shown after it must appear in its
  output in order, each a whole line as printed (``...`` stands for anything),
  and a ``# writes PATH`` comment
  must name files it wrote. ``make`` lines are checked with ``make -n`` (make test
  is what runs this suite; CI runs make demo).

Bare blocks that are not commands (namelist decks, tables of output) are data.
"""
from __future__ import annotations

import contextlib
import doctest
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import beamid
import beamid.model
import beamid.progress
import beamid.static

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

SHELL_LANGS = {"sh", "console", "shell", "bash"}
#: first words that make a bare ``` block a shell block
COMMANDS = {"beamid", "beamid-batch", "make", "python", "python3", "source", "cd", "ls",
            "cat", "head", "tail", "pip"}
#: placeholders of syntax lines (docs/decks.md) and what the test runs instead
PLACEHOLDERS = {"DECK": "inputs/seed/table02_c05.nml"}

FENCE = re.compile(r"^```([A-Za-z0-9_+-]*)[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)


@dataclass
class Block:
    page: Path
    lang: str
    text: str
    line: int

    @property
    def name(self) -> str:
        return f"{self.page.name}:{self.line}"


def blocks(path: Path) -> list[Block]:
    text = path.read_text()
    return [Block(path, m.group(1).lower(), m.group(2), text.count("\n", 0, m.start()) + 1)
            for m in FENCE.finditer(text)]


def _first_word(line: str) -> str:
    """The command of a line, or "" for output (programs' messages start with
    "beamid simulate:", "beamid: error:" ...)."""
    line = line.strip()
    if line.startswith("$ "):
        line = line[2:]
    words = line.split()
    if not words or any(w.endswith(":") for w in words[:2]):
        return ""
    return words[0]


def is_shell(block: Block) -> bool:
    if block.lang in SHELL_LANGS:
        return True
    if block.lang:
        return False
    first = next((ln for ln in block.text.splitlines() if ln.strip()), "")
    return first.startswith("$ ") or _first_word(first) in COMMANDS


# ----------------------------------------------------------------- python


@dataclass
class Page:
    path: Path
    namespace: dict = field(default_factory=lambda: {"__name__": "__doc_example__"})


class TextChecker(doctest.OutputChecker):
    """doctest output check that compares text exactly: no numeric tolerance, no
    whitespace normalization, no ellipsis. A reader compares what the page
    shows with what Python prints; so does this test."""

    def check_output(self, want, got, optionflags):
        return want == got


def run_python(block: Block, page: Page) -> None:
    if block.lang == "python":
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            exec(compile(block.text, block.name, "exec"), page.namespace)
        assert not printed.getvalue(), (
            f"{block.name}: a python block printed (show it in a pycon block):\n"
            f"{printed.getvalue()[:2000]}")
        return
    parser = doctest.DocTestParser()
    test = parser.get_doctest(block.text, page.namespace, block.name, str(block.page),
                              block.line)
    runner = doctest.DocTestRunner(checker=TextChecker(), optionflags=0)
    out: list[str] = []
    runner.run(test, out=out.append, clear_globs=False)
    assert runner.failures == 0, "".join(out)
    page.namespace.update(test.globs)


PY_PAGES = [p for p in DOCS if any(b.lang in ("python", "pycon") for b in blocks(p))]

# ---------------------------------------------------------------- figures

#: Every image the docs show (docs/img/NAME), the page whose example draws it,
#: the file that example writes, and what its title and axis labels say
#: (substrings; "title" is the figure's suptitle or its first Axes' title).
#: ``python tests/test_docs.py --write-images`` runs the pages and copies the
#: files into docs/img, so the images are the examples' own.
DOC_IMAGES = {
    "modal_mac.png": ("modal.md", "mac.png", dict(
        title="MAC, measured vs model modes", xlabel="model mode", ylabel="measured mode")),
    "workflow_compare_start.png": ("workflow.md", "compare_start.png", dict(
        title="start: measured vs model: chi2 = 4.392e+04, dof 13, chi2/dof = 3378",
        xlabel="experiment", ylabel="x_tip (m)")),
    "workflow_ladder.png": ("workflow.md", "ladder.png", dict(
        title="error against step", xlabel="improvement step", ylabel="chi2 / dof")),
    "workflow_compare_final.png": ("workflow.md", "compare_final.png", dict(
        title="final fit (step 2: axial_coupling, elbow_flex added): measured vs model: "
              "chi2 = 14.55, dof 11", xlabel="experiment",
        ylabel="tip_angle (rad)")),
    "workflow_identify.png": ("workflow.md", "identify.png", dict(
        title="relative sigma after", xlabel="parameter",
        ylabel="sigma / estimate after the stage (-)")),
    "workflow_identify_free.png": ("workflow.md", "identify_free.png", dict(
        title="free stage: measured vs model: chi2 = 10.78", xlabel="t (s)",
        ylabel="w_tip (m)")),
    "consistency_table05.png": ("consistency.md", "table05_mc.png", dict(
        title="EI1: sigma/spread", xlabel="(EI1 - truth) / sigma (-)",
        ylabel="probability density")),
    "design_table05.png": ("consistency.md", "table05_design.png", dict(
        title="which measurement next", xlabel="predicted sigma of EI2 (N m^2)", ylabel="")),
}

IMAGE_LINK = re.compile(r"!\[[^\]]*\]\((img/[^)\s]+)\)")


def check_figure(texts: dict, want: dict, name: str) -> None:
    assert texts["title"], f"{name}: no title"
    assert want["title"] in texts["title"], f"{name}: title {texts['title']!r}"
    assert want["xlabel"] in texts["xlabels"], f"{name}: x labels {texts['xlabels']}"
    if want["ylabel"]:
        assert want["ylabel"] in texts["ylabels"], f"{name}: y labels {texts['ylabels']}"


def doc_image_links() -> list[tuple[Path, str]]:
    return [(page, m.group(1)) for page in DOCS for m in IMAGE_LINK.finditer(page.read_text())]


@pytest.mark.parametrize("path", PY_PAGES, ids=[p.name for p in PY_PAGES])
def test_python_examples_run(path, tmp_path, monkeypatch, saved_figures):
    # the blocks of a page build on each other, as a reader types them in order,
    # from the top of a checkout (paths like inputs/demo/... are relative to it);
    # what they write lands in tmp_path
    (tmp_path / "inputs").symlink_to(ROOT / "inputs")
    monkeypatch.chdir(tmp_path)
    page = Page(path)
    for block in blocks(path):
        if block.lang in ("python", "pycon"):
            run_python(block, page)
    # the images the docs show are this page's figures: written, titled, labelled
    for image, (page_name, written, want) in DOC_IMAGES.items():
        if page_name == path.name:
            assert (tmp_path / written).is_file(), f"{path.name} did not write {written}"
            check_figure(saved_figures[written], want, f"{path.name}: {written} ({image})")


def test_every_image_the_docs_show_is_made_by_an_example():
    links = doc_image_links()
    assert links, "no images found in the docs"
    for page, link in links:
        name = Path(link).name
        assert (ROOT / "docs" / link).is_file(), f"{page.name} shows {link}, which is missing"
        assert name in DOC_IMAGES, f"{page.name} shows {link}: no example makes it (DOC_IMAGES)"
        assert DOC_IMAGES[name][0] == page.name, f"{link} is shown on {page.name}"
    shown = {Path(link).name for _, link in links}
    assert set(DOC_IMAGES) == shown
    assert {p.name for p in (ROOT / "docs" / "img").glob("*.png")} == shown, \
        "docs/img holds images no page shows"


def write_doc_images() -> None:
    """Run the pages that draw the docs' images and copy what they write into
    docs/img (``python tests/test_docs.py --write-images``)."""
    import tempfile

    import matplotlib

    matplotlib.use("Agg")
    for page_name in sorted({page for page, _, _ in DOC_IMAGES.values()}):
        path = ROOT / "docs" / page_name
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "inputs").symlink_to(ROOT / "inputs")
            cwd = os.getcwd()
            os.chdir(tmp)
            try:
                page = Page(path)
                for block in blocks(path):
                    if block.lang in ("python", "pycon"):
                        run_python(block, page)
            finally:
                os.chdir(cwd)
            for image, (p, written, _) in DOC_IMAGES.items():
                if p == page_name:
                    shutil.copy(Path(tmp) / written, ROOT / "docs" / "img" / image)
                    print(f"wrote docs/img/{image}")


@pytest.mark.parametrize("module", [beamid, beamid.model, beamid.static, beamid.progress])
def test_doctests(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0


# ------------------------------------------------------------------ shell


@dataclass
class Command:
    line: str          # as shown
    run: str           # what runs (placeholders replaced)
    comment: str
    expected: list[str]


def commands(block: Block) -> list[Command]:
    cmds: list[Command] = []
    for raw in block.text.splitlines():
        if not raw.strip():
            continue
        prompt = raw.startswith("$ ")
        is_cmd = prompt if block.lang == "console" else (
            prompt or _first_word(raw) in COMMANDS)
        if is_cmd:
            line = raw[2:] if prompt else raw
            code, _, comment = line.partition(" #")
            run = " ".join(PLACEHOLDERS.get(w, w) for w in shlex.split(code))
            cmds.append(Command(line, run, comment.strip(), []))
        elif cmds:
            cmds[-1].expected.append(raw)
        else:
            raise AssertionError(f"{block.name}: output {raw!r} before any command")
    return cmds


def _pattern(expected: str) -> re.Pattern:
    """A shown output line as a pattern for a whole printed line: the text
    exactly, with ``...`` standing for anything."""
    return re.compile(".*".join(re.escape(p) for p in expected.rstrip().split("...")))


def assert_output(cmd: Command, output: str) -> None:
    lines = output.splitlines()
    k = 0
    for want in cmd.expected:
        if want.strip() in ("...", ""):
            continue
        pat = _pattern(want)
        while k < len(lines) and not pat.fullmatch(lines[k].rstrip()):
            k += 1
        assert k < len(lines), f"{cmd.line!r}: no line {want!r} (in order) in\n{output}"
        k += 1


def _env() -> dict:
    env = dict(os.environ)
    path = [str(Path(sys.executable).parent)]
    if env.get("BEAMID_BATCH"):               # the checking build (make test-check)
        path.insert(0, str(Path(env["BEAMID_BATCH"]).parent))
    env["PATH"] = os.pathsep.join(path + [env.get("PATH", "")])
    env.setdefault("MPLBACKEND", "Agg")
    return env


def run_command(cmd: Command, cwd: Path) -> None:
    words = shlex.split(cmd.run)
    if words[0] == "make":
        done = subprocess.run(["make", "-n", "-C", str(ROOT), *words[1:]], capture_output=True,
                              text=True)
        assert done.returncode == 0, f"{cmd.line}: {done.stderr}"
        return
    done = subprocess.run(cmd.run, shell=True, cwd=cwd, env=_env(), capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, f"{cmd.line!r} exited {done.returncode}:\n{done.stderr}"
    assert_output(cmd, done.stdout)
    m = re.match(r"writes (\S+)", cmd.comment)
    if m:
        target = m.group(1)
        assert list(cwd.glob(target)), f"{cmd.line!r} did not write {target}"


SHELL_BLOCKS = [b for p in DOCS for b in blocks(p) if is_shell(b)]


@pytest.mark.parametrize("block", SHELL_BLOCKS, ids=[b.name for b in SHELL_BLOCKS])
def test_shell_examples_run(block, tmp_path):
    # a temporary copy of the inputs: outputs land there, not in the checkout
    shutil.copytree(ROOT / "inputs", tmp_path / "inputs")
    cmds = commands(block)
    assert cmds, f"{block.name}: a shell block without commands"
    for cmd in cmds:
        run_command(cmd, tmp_path)


# --------------------------------------------------------- the harness itself


def test_block_classification():
    deck = Block(Path("x.md"), "", "&beamid\n  task = 'static'\n/\n", 1)
    table = Block(Path("x.md"), "", "rank effect  score\n1 axial 3\n", 1)
    shell = Block(Path("x.md"), "", "beamid reproduce 2\ntable row\n", 1)
    assert [c.expected for c in commands(Block(Path("x.md"), "", "beamid simulate\n"
                                                "beamid simulate: 27 output times\n", 1))] \
        == [["beamid simulate: 27 output times"]]
    console = Block(Path("x.md"), "console", "$ beamid --version\nbeamid 0.1.0\n", 1)
    assert not is_shell(deck) and not is_shell(table)
    assert is_shell(shell) and is_shell(console)
    (c,) = commands(console)
    assert c.run == "beamid --version" and c.expected == ["beamid 0.1.0"]
    (c,) = commands(Block(Path("x.md"), "", "beamid-batch DECK   # Fortran only\n", 1))
    assert c.run == f"beamid-batch {PLACEHOLDERS['DECK']}" and c.comment == "Fortran only"


def test_output_matching():
    cmd = Command("x", "x", "", ["step  effect   chi2", "1  axial  296.18 ...", "...",
                                 "residuals ... 0.01 ..."])
    assert_output(cmd, "head\nstep  effect   chi2\n1  axial  296.18 12 more\n"
                       "residuals at 0.01 z\n")
    with pytest.raises(AssertionError, match="no line"):      # a digit off
        assert_output(cmd, "step  effect   chi2\n1  axial  296.19 12\nresiduals at 0.01 z\n")
    with pytest.raises(AssertionError, match="no line"):      # other spacing
        assert_output(cmd, "step effect chi2\n1  axial  296.18 12\nresiduals at 0.01 z\n")
    with pytest.raises(AssertionError, match="no line"):      # part of a line
        assert_output(cmd, "step  effect   chi2\n0 1  axial  296.18 12\nresiduals at 0.01 z\n")
    with pytest.raises(AssertionError, match="in order"):
        assert_output(cmd, "1  axial  296.18 12\nstep  effect   chi2\nresiduals at 0.01 z\n")


def test_text_checker():
    check = TextChecker().check_output
    assert check("0.5881 1.1594 66.00\n", "0.5881 1.1594 66.00\n", 0)
    assert not check("0.5881 1.1594 66.00\n", "0.58813 1.15943 66.0041\n", 0)
    assert not check("0.5881\n", "0.5881 \n", 0)
    assert not check("[2.42882 11.0030]\n", "[ 2.42882 11.0030]\n", 0)
    assert not check("np.float64(0.5)\n", "0.5\n", 0)


def test_python_blocks_print_nothing(tmp_path):
    block = Block(Path("x.md"), "python", "print(0.58813)\n", 1)
    with pytest.raises(AssertionError, match="printed"):
        run_python(block, Page(Path("x.md")))


# ------------------------------------------------------------- deck examples

DECK_BLOCKS = [b for p in DOCS for b in blocks(p)
               if not b.lang and b.text.lstrip().startswith("&beamid")]


@pytest.mark.parametrize("block", [pytest.param(b, id=b.name) for b in DECK_BLOCKS])
def test_deck_examples_run(block, tmp_path, batch_exe):
    # complete decks shown in the docs run in both programs, next to the demo data
    for f in (ROOT / "inputs" / "demo").iterdir():
        if f.is_file():   # not the out/ folder a demo run leaves
            shutil.copy(f, tmp_path / f.name)
    deck = tmp_path / "example.nml"
    deck.write_text(block.text)
    beamid.run(str(deck))
    done = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr


if __name__ == "__main__" and sys.argv[1:] == ["--write-images"]:
    write_doc_images()
