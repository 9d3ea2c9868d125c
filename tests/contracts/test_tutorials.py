"""The tutorials run: every docs/tutorials/*.py executes as a notebook and as a script without an error.

The tutorials are jupytext percent files. Each test reads one with jupytext and runs it,
cell by cell, in a fresh IPython kernel through nbclient, as Jupyter would: from its own
folder, with ``WFBENCH_TUTORIAL_QUICK=1`` (fewer seeds, a training run of seconds instead
of minutes) and with the scratch folders it makes under pytest's ``tmp_path``. A cell that
raises, an ``assert`` in a tutorial included, fails the test with that cell and its
traceback. The site (mkdocs.yml) renders the tutorials without running them, and mkdocs
does not check the links inside a notebook, so the last test checks them against the
site's layout. jupytext, nbclient and ipykernel come with the ``docs`` extra (in ``dev``).

Each tutorial also runs as a plain script, ``python docs/tutorials/NN_*.py`` (a reader who
does not use Jupyter, issue #26), from an empty working folder: there a cell magic is only
a comment, so the tutorials use none (tutorial 02 writes its policy module with
``Path.write_text``). The four take about 30 s this way on two idle cores.
"""

from __future__ import annotations

import importlib
import os
import posixpath
import re
import subprocess
import sys
import tempfile
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
TUTORIALS = sorted((DOCS / "tutorials").glob("[0-9][0-9]_*.py"))
CELL_TIMEOUT_S = 300


def _jupytext():
    """jupytext, or a failure saying how to get it: CI installs the dev extra, so a missing one is a bug."""
    try:
        return importlib.import_module("jupytext")
    except ImportError:
        pytest.fail("jupytext is not installed: `.venv/bin/pip install -e '.[docs]'` (the dev extra includes it)")


def test_there_are_four_tutorials():
    assert [p.stem[:2] for p in TUTORIALS] == ["01", "02", "03", "04"], TUTORIALS


@pytest.mark.slow
@pytest.mark.parametrize("path", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_runs(path, tmp_path, monkeypatch):
    jupytext = _jupytext()
    from nbclient import NotebookClient

    # Ray keeps its sockets under its temporary folder: a long pytest path would overflow their names
    monkeypatch.setenv("RAY_TMPDIR", tempfile.gettempdir())
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the tutorials' scratch folders (tempfile.mkdtemp)
    monkeypatch.setenv("WFBENCH_TUTORIAL_QUICK", "1")
    nb = jupytext.read(path)
    client = NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                            resources={"metadata": {"path": str(path.parent)}})
    client.execute()  # raises CellExecutionError, naming the cell, when a cell raises
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    # a figure, or (the leaderboard's page) HTML with its figures embedded
    pictures = [o for o in outputs if "image/png" in o.get("data", {})
                or "data:image/png;base64," in str(o.get("data", {}).get("text/html", ""))]
    assert pictures, f"{path.name} shows no picture"


@pytest.mark.slow
@pytest.mark.parametrize("path", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_runs_as_a_script(path, tmp_path):
    """``python docs/tutorials/NN_*.py`` from an empty folder ends with 0, and writes its scratch files under TMPDIR."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "ORLIB"}  # tutorial 04 finds the checkout's instances itself
    env |= {"WFBENCH_TUTORIAL_QUICK": "1", "MPLBACKEND": "Agg", "TMPDIR": str(tmp_path),
            "RAY_TMPDIR": tempfile.gettempdir()}
    out = subprocess.run([sys.executable, str(path)], cwd=cwd, env=env, capture_output=True, text=True,
                         timeout=CELL_TIMEOUT_S)
    assert out.returncode == 0, f"{path.name} failed as a script:\n{out.stderr[-3000:]}"
    assert "Traceback" not in out.stderr, out.stderr[-3000:]
    assert not list(cwd.iterdir()), f"{path.name} wrote into the working folder: {list(cwd.iterdir())}"
    if path.stem.startswith("02_"):  # the module the leaderboard imports by name, written without %%writefile
        written = list(tmp_path.glob("wfbench-tutorial-*/my_policy.py"))
        assert len(written) == 1 and "class LongestDownFirst" in written[0].read_text(), written


def _slug(text: str) -> str:
    """The anchor Python-Markdown's toc extension gives a heading (its default slugify)."""
    text = unicodedata.normalize("NFKD", text.replace("`", "")).encode("ascii", "ignore").decode()
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def _anchors(md: Path) -> set[str]:
    return {_slug(m.group(1)) for m in re.finditer(r"^#{1,6}\s+(.+?)\s*$", md.read_text(), re.MULTILINE)}


@pytest.mark.parametrize("path", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_links_resolve_in_the_site(path):
    """A relative link in a Markdown cell names a page of the site (``../../metrics/``, ``../02_.../``) or the source.

    The page of docs/tutorials/NAME.py is tutorials/NAME/ in the site, and the plugin copies the
    source next to it (``include_source``), so ``NAME.py`` links to the file itself.
    """
    nb = _jupytext().read(path)
    page = f"/tutorials/{path.stem}/"
    broken = []
    for cell in nb.cells:
        if cell.cell_type != "markdown":
            continue
        for target in re.findall(r"\]\(([^)\s]+)\)", cell.source):
            if re.match(r"[a-z]+://", target) or target.startswith("#"):
                continue
            url, _, anchor = target.partition("#")
            resolved = posixpath.normpath(posixpath.join(page, url))
            if url == f"{path.stem}.py":
                continue  # the source, copied beside the page
            name = resolved.strip("/")
            source = DOCS / f"{name}.md"
            if name.startswith("tutorials/"):
                source = DOCS / f"{name}.py"
            if not url.endswith("/") or not source.is_file():
                broken.append(f"{target} (no page {name}/)")
            elif anchor and source.suffix == ".md" and anchor not in _anchors(source):
                broken.append(f"{target} (no heading with the anchor #{anchor} in {source.relative_to(ROOT)})")
    assert not broken, f"{path.name} links to what the site does not have: {broken}"
