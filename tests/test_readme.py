"""The README's install and test commands are exactly the ones CI runs."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def readme_blocks():
    return re.findall(r"```\n(.*?)\n```", (ROOT / "README.md").read_text(), flags=re.S)


def test_ci_runs_the_readme_install_and_test_commands():
    blocks = [b.strip() for b in readme_blocks()]
    install = next(b for b in blocks if b.startswith("pip install"))
    test = next(b for b in blocks if "pytest" in b)
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert install in ci and "torch==2.13.0" in install
    assert test in ci


def test_readme_quick_start_bakes_an_example_that_exists():
    bake = next(b for b in readme_blocks() if b.startswith("garment bake"))
    for token in bake.split():
        if token.startswith("examples/"):
            assert (ROOT / token).is_file(), token
