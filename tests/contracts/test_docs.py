"""The documentation's examples run: every ```python block of the checked pages, in order.

The blocks of one page run as one script (later blocks use the names of earlier ones) in
a fresh interpreter, in an empty temporary directory, so an example can neither lean on
the test process's imports nor leave files in the checkout. A block that is not meant
to run (shell commands, an outline of a class) uses another fence language (```text,
```bash), never ```python. The README runs only its "In Python" section.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)
PAGES = ("docs/policies.md", "docs/design.md")


def python_blocks(text: str) -> list[str]:
    return FENCE.findall(text)


def readme_python_section() -> str:
    text = (ROOT / "README.md").read_text()
    match = re.search(r"^## In Python\n(.*?)(?=^## )", text, re.S | re.M)
    assert match, "README.md has no '## In Python' section; update tests/contracts/test_docs.py if it moved"
    return match.group(1)


def run_blocks(blocks: list[str], where: str, tmp_path: Path) -> None:
    assert blocks, f"{where} has no ```python block; the examples must stay runnable"
    script = tmp_path / "doc_examples.py"
    script.write_text("\n\n".join(blocks))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
               MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, (
        f"an example of {where} failed; fix the page or the code so they agree.\n"
        f"--- stdout ---\n{proc.stdout[-4000:]}\n--- stderr ---\n{proc.stderr[-4000:]}"
    )


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES)
def test_page_examples_run(page, tmp_path):
    run_blocks(python_blocks((ROOT / page).read_text()), page, tmp_path)


@pytest.mark.slow
def test_readme_in_python_example_runs(tmp_path):
    run_blocks(python_blocks(readme_python_section()), "README.md (In Python)", tmp_path)


def test_fence_finds_only_python_blocks():
    text = "```python\na = 1\n```\n\n```text\nnot run\n```\n\n```python\nb = a\n```\n"
    assert python_blocks(text) == ["a = 1\n", "b = a\n"]


def test_testing_page_maps_every_test_file():
    """docs/testing.md names every test file of tests/ in its table, and only files that exist."""
    import re

    page = (ROOT / "docs" / "testing.md").read_text()
    table = page[page.index("## How the suite is organized"):page.index("## The reference differential test")]
    named = set(re.findall(r"`(test_\w+\.py)`", table))
    files = {p.name for p in (ROOT / "tests").rglob("test_*.py")}
    assert files - named == set(), f"docs/testing.md's table does not name {sorted(files - named)}"
    assert named - files == set(), f"docs/testing.md's table names files that do not exist: {sorted(named - files)}"
