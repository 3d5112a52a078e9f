"""The source passes `ruff check` with the rules pyproject.toml selects (ruff is in the dev extra)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_check_is_clean():
    pytest.importorskip("ruff", reason="ruff is in the dev extra")
    res = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise", str(ROOT)],
                         cwd=ROOT, capture_output=True, text=True, check=False)
    assert res.returncode == 0 and "All checks passed" in res.stdout, res.stdout[-4000:] + res.stderr[-2000:]
