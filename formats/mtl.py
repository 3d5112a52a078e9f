"""Wavefront material libraries (`.mtl`, named by an OBJ's `mtllib` lines): what a preview shader needs of
each material, and copies of a library beside an output whose texture paths still lead to the textures.

Nothing here stops a bake: a library that cannot be read is warned about and left out (the outputs then
name their materials only, as before).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from formats.atomic import atomic_file

log = logging.getLogger(__name__)

#: Statements whose argument ends with a file name (options such as `-s 1 1 1` or `-bm 0.5` may come first).
TEXTURE_KEYS = frozenset({"map_ka", "map_kd", "map_ks", "map_ke", "map_ns", "map_d", "map_bump", "bump", "disp",
                          "decal", "refl", "norm", "map_pr", "map_pm", "map_ps", "map_rma", "map_orm"})


@dataclass(frozen=True)
class MtlMaterial:
    """One `newmtl` of a library: diffuse colour Kd (r, g, b) in [0, 1] or None, opacity (`d`, or 1 - `Tr`) or
    None, and the diffuse texture (`map_Kd`) as an absolute path (which may not exist) or None."""

    name: str
    diffuse: tuple[float, float, float] | None = None
    opacity: float | None = None
    diffuse_texture: Path | None = None


def _texture_path(args: list[str], base: Path) -> tuple[int, Path]:
    """The file a texture statement names: (index of its first token in `args`, absolute path). The longest
    tail of the arguments that is a file under `base` (a name with spaces), else the last argument."""
    for start in range(len(args)):
        if not args[start].startswith("-") or start == len(args) - 1:
            candidate = base / " ".join(args[start:])
            if candidate.is_file():
                return start, candidate.resolve()
    return len(args) - 1, (base / args[-1]).resolve()


def _lines(path: Path) -> list[str] | None:
    try:
        return path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    except OSError as exc:
        log.warning("material library '%s': cannot be read (%s); its materials are written by name only", path,
                    exc.strerror or exc)
        return None


def read_mtl(path: str | os.PathLike) -> dict[str, MtlMaterial]:
    """{name: MtlMaterial} of the library at `path` ({} with a warning when it cannot be read; a value that is
    not a number is skipped)."""
    path = Path(path)
    lines = _lines(path)
    materials: dict[str, dict] = {}
    current = None
    for line in lines or ():
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        key = parts[0].lower()
        if key == "newmtl":
            current = materials.setdefault(" ".join(parts[1:]), {})
        elif current is None:
            continue
        elif key in ("kd", "d", "tr"):
            try:
                values = [float(v) for v in parts[1:4 if key == "kd" else 2]]
            except ValueError:
                continue
            if key == "kd" and len(values) in (1, 3):
                current["diffuse"] = tuple(float(np.clip(v, 0.0, 1.0)) for v in values * (3 // len(values)))
            elif key != "kd" and values:
                current["opacity"] = float(np.clip(values[0] if key == "d" else 1.0 - values[0], 0.0, 1.0))
        elif key == "map_kd" and len(parts) > 1:
            current["diffuse_texture"] = _texture_path(parts[1:], path.parent)[1]
    return {name: MtlMaterial(name, **fields) for name, fields in materials.items()}


def copy_mtl(source: str | os.PathLike, target: str | os.PathLike) -> bool:
    """Write the library `source` to `target` with each texture's relative path rewritten so that it leads,
    from `target`'s folder, to the file `source` names (absolute paths and missing textures kept as written).
    Returns False (warned) when `source` cannot be read."""
    source, target = Path(source), Path(target)
    lines = _lines(source)
    if lines is None:
        return False
    out = []
    for line in lines:
        parts = line.split()
        if len(parts) > 1 and parts[0].lower() in TEXTURE_KEYS:
            start, texture = _texture_path(parts[1:], source.parent)
            written = " ".join(parts[1 + start:])
            if texture.is_file() and not Path(written).is_absolute():
                relative = os.path.relpath(texture, target.parent.resolve()).replace(os.sep, "/")
                line = " ".join(parts[:1 + start] + [relative])
        out.append(line)
    with atomic_file(target) as tmp:
        Path(tmp).write_text("\n".join(out) + "\n", encoding="utf-8")
    return True


def copy_material_libraries(libraries, directory: str | os.PathLike) -> list[str]:
    """Copy each library (`copy_mtl`) into `directory` under its own file name; returns the names written, for
    the OBJ's `mtllib` line (a name already taken by an earlier library is skipped, warned)."""
    names: list[str] = []
    for library in libraries:
        name = Path(library).name
        if name in names:
            log.warning("material library '%s': another library of that name is already copied; skipped", library)
        elif copy_mtl(library, Path(directory) / name):
            names.append(name)
    return names


def write_mtl(target: str | os.PathLike, looks: dict[str, MtlMaterial]) -> None:
    """A library at `target` of `looks` (name -> MtlMaterial, as `formats.usd` reads a stage's preview materials):
    each one's diffuse colour, opacity and diffuse texture (by a path relative to `target`'s folder where it
    exists, else as it is)."""
    target = Path(target)
    out = []
    for name, look in looks.items():
        out.append(f"newmtl {name}")
        if look.diffuse is not None:
            out.append("Kd " + " ".join(f"{float(c):.6g}" for c in look.diffuse))
        if look.opacity is not None:
            out.append(f"d {float(look.opacity):.6g}")
        if look.diffuse_texture is not None:
            texture = Path(look.diffuse_texture)
            out.append("map_Kd " + (os.path.relpath(texture.resolve(), target.parent.resolve()).replace(os.sep, "/")
                                    if texture.is_file() else str(texture)))
        out.append("")
    with atomic_file(target) as tmp:
        Path(tmp).write_text("\n".join(out), encoding="utf-8")


def output_libraries(source, directory: str | os.PathLike, stem: str) -> list[str]:
    """The material libraries of an output written into `directory`, as its `mtllib` names them: the garment
    file's own (`source.libraries`, copied: `copy_material_libraries`), else, for a garment read from USD whose
    materials carry preview looks (`source.looks`), `<stem>.mtl` written of them; none without either."""
    if source is None:
        return []
    if source.libraries:
        return copy_material_libraries(source.libraries, directory)
    if source.looks:
        write_mtl(Path(directory) / f"{stem}.mtl", source.looks)
        return [f"{stem}.mtl"]
    return []


def read_libraries(libraries) -> dict[str, MtlMaterial]:
    """{name: MtlMaterial} over several libraries (`read_mtl`; the first definition of a name wins)."""
    looks: dict[str, MtlMaterial] = {}
    for library in libraries:
        for name, look in read_mtl(library).items():
            looks.setdefault(name, look)
    return looks
