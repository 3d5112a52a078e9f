"""formats/fbx.py against ufbx, an open FBX library whose evaluation is checked against Autodesk's own tools: every
FBX 6 and 7 file of ufbx's test data (Maya, MotionBuilder, 3ds Max, Blender and others' exports, and files made to
stress readers), each Model's transform in the world at four times (0, 0.3, 0.75 and 1.5 s; its first animation
stack, every layer), as `formats.fbx.model_transforms` composes it and as ufbx does. Rotations must agree within
1e-4, places within 1e-4 of the scene's size; files either reader refuses are counted, with the reasons ours
gives.

ufbx is not a dependency of garment; it is built here from its own checkout (a C compiler needed):
    git clone https://github.com/ufbx/ufbx /tmp/ufbx
    python benchmarks/fbx_against_ufbx.py /tmp/ufbx
Results: benchmarks/results/fbx_against_ufbx.md.
"""
import argparse
import collections
import logging
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from core.errors import InputError  # noqa: E402
from formats.fbx import TICKS_PER_SECOND, _name, model_transforms, read_scene  # noqa: E402

TIMES = [0.0, 0.3, 0.75, 1.5]


def ufbx_worlds(tool: Path, path: Path) -> dict | None:
    """{node name: (T, 4, 4)} of ufbx's evaluation, None where ufbx cannot load the file."""
    try:
        out = subprocess.run([str(tool), str(path)] + [repr(t) for t in TIMES], capture_output=True, text=True,
                             timeout=120, errors="replace").stdout
    except subprocess.TimeoutExpired:
        return None
    worlds: dict = {}
    for line in out.splitlines():
        if line.startswith("ERROR"):
            return None
        if line.startswith("T "):
            head, values = line.rsplit("|", 1)
            name = head.split(" ", 2)[2]
            v = np.array(values.split(), dtype=np.float64)
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = v[:9].reshape(3, 3).T, v[9:]
            worlds.setdefault(name, []).append(M)
    return {name: np.array(Ms) for name, Ms in worlds.items()}


def our_worlds(path: Path) -> dict:
    """{node name: (T, 4, 4)} of formats.fbx's evaluation (names held by one Model only)."""
    scene = read_scene(path.read_bytes(), str(path))
    world, _ = model_transforms(scene, np.array(TIMES) * TICKS_PER_SECOND)
    names = collections.Counter(_name(m) for m in scene.models.values())
    return {_name(scene.models[i]): M for i, M in world.items() if names[_name(scene.models[i])] == 1}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("ufbx", type=Path, help="a checkout of github.com/ufbx/ufbx (ufbx.c, ufbx.h, data/)")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "fbx_against_ufbx.md")
    args = parser.parse_args()
    logging.disable(logging.CRITICAL)
    warnings.simplefilter("ignore")
    build = Path(tempfile.mkdtemp())
    tool = build / "world_transforms"
    subprocess.run(["cc", "-O1", "-o", str(tool), str(Path(__file__).parent / "ufbx_reference" / "world_transforms.c"),
                    str(args.ufbx / "ufbx.c"), f"-I{args.ufbx}", "-lm"], check=True)
    commit = subprocess.run(["git", "-C", str(args.ufbx), "rev-parse", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    files = sorted(p for p in (args.ufbx / "data").rglob("*") if p.suffix.lower() == ".fbx"
                   and not p.name.startswith("fuzz_") and "_fail" not in p.name and "fuzz" not in p.parent.name)
    agree, disagree, refused, ufbx_fails, nodes = [], [], collections.Counter(), [], 0
    worst = 0.0
    seconds = 0.0
    for path in files:
        reference = ufbx_worlds(tool, path)
        if reference is None:
            ufbx_fails.append(path.name)
            continue
        start = time.perf_counter()
        try:
            ours = our_worlds(path)
        except InputError as exc:
            refused[str(exc).split(": ", 1)[-1].split(":")[0][:90]] += 1
            continue
        seconds += time.perf_counter() - start
        errors = []
        for name, M in ours.items():
            R = reference.get(name)
            if R is None or len(R) != len(M):
                continue
            size = max(1.0, float(np.abs(R[:, :3, 3]).max()))
            errors.append(max(float(np.abs(M[:, :3, :3] - R[:, :3, :3]).max()),
                              float(np.abs(M[:, :3, 3] - R[:, :3, 3]).max()) / size))
        nodes += len(errors)
        error = max(errors, default=0.0)
        (agree if error <= 1e-4 else disagree).append((path.name, len(errors), error))
        worst = max(worst, error if error <= 1e-4 else worst)
    versions = collections.Counter(name.split("_")[-2] for name, *_ in agree if name.split("_")[-2].isdigit())
    lines = [
        "# formats/fbx.py against ufbx",
        "",
        f"`python benchmarks/fbx_against_ufbx.py /tmp/ufbx` (ufbx {commit[:12]}; {len(files)} FBX files of its",
        "test data, its fuzzed and must-fail files left out). Each Model's transform in the world at 0, 0.3, 0.75",
        "and 1.5 s, ours (`formats.fbx.model_transforms`) against ufbx's (`benchmarks/ufbx_reference/`).",
        "",
        "| | files | nodes |",
        "| --- | ---: | ---: |",
        f"| both read, every node within 1e-4 | {len(agree)} | {sum(n for _, n, _ in agree)} |",
        f"| both read, a node further off | {len(disagree)} | {sum(n for _, n, _ in disagree)} |",
        f"| ours refuses (below) | {sum(refused.values())} | |",
        f"| ufbx cannot load | {len(ufbx_fails)} | |",
        "",
        f"Largest difference among the agreeing files: {worst:.1e} (rotation, or place over the scene's size).",
        f"Their FBX versions: {', '.join(f'{v}: {n}' for v, n in sorted(versions.items()))}.",
        f"Our reading and evaluation of them took {seconds:.1f} s in all.",
        "",
    ]
    if disagree:
        lines += ["## Further off", "", "| file | nodes | largest difference |", "| --- | ---: | ---: |"]
        lines += [f"| {name} | {n} | {e:.2g} |" for name, n, e in disagree] + [""]
    lines += ["## Ours refuses", "", "| reason | files |", "| --- | ---: |"]
    lines += [f"| {reason} | {n} |" for reason, n in refused.most_common()] + [""]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
