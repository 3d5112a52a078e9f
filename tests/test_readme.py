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


def github_anchor(heading: str, seen: dict) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation but '-' and '_' dropped, spaces as '-', a
    repeated one numbered (-1, -2, ...)."""
    base = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
    n = seen.get(base, 0)
    seen[base] = n + 1
    return base if n == 0 else f"{base}-{n}"


def readme_contents() -> list[str]:
    """The contents list of the README's sections (## and ###) as it should read, in order."""
    text = re.sub(r"```.*?```", "", (ROOT / "README.md").read_text(), flags=re.S)
    seen: dict = {}
    entries = []
    for hashes, title in re.findall(r"^(#{2,4}) (.+)$", text, flags=re.M):
        anchor = github_anchor(title, seen)
        if title != "Contents" and len(hashes) <= 3:
            entries.append(f"{'  ' * (len(hashes) - 2)}- [{title}](#{anchor})")
    return entries


def test_readme_contents_lists_every_section():
    """The README is long (2,600 lines): its contents list leads to every section, kept with the headings."""
    text = (ROOT / "README.md").read_text()
    listed = text.split("## Contents\n\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert listed == readme_contents()
