"""The wheel a user installs: the runtime assets and the licence in it, nothing of the repository's work."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_wheel_holds_the_runtime_assets_and_the_licence(tmp_path):
    """Built as `pip wheel` builds it: the default body, model, model card and calibration, the package's modules,
    the Apache-2.0 text (none before 2026-12-07); no tests, benchmarks or data."""
    source = tmp_path / "source"  # a copy: the build writes build/ and *.egg-info where it builds
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(".*", "build", "dist", "*.egg-info", "data", "__pycache__",
                                                                 "out"))
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(source)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    (wheel,) = tmp_path.glob("garment-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for asset in ("default_body.npz", "default_model.pt", "default_model.json", "default_model.calibration.json"):
        assert f"core/assets/{asset}" in names
    assert {"garmentcli/main.py", "core/body.py", "formats/obj.py"} <= names
    licence = [n for n in names if n.endswith("LICENSE") and ".dist-info/" in n]
    assert licence and "Apache License" in zipfile.ZipFile(wheel).read(licence[0]).decode()
    assert not [n for n in names if n.split("/")[0] in ("tests", "benchmarks", "data", "examples", "docs")]
