import logging
from pathlib import Path

import pytest

from formats.mtl import MtlMaterial, copy_material_libraries, copy_mtl, read_libraries, read_mtl

LIBRARY = """# exported by a pattern tool
newmtl front cotton
Kd 0.9 0.1 0.2
d 0.75
map_Kd -s 1 1 1 textures/cotton weave.png
map_Bump -bm 0.5 textures/bump.png

newmtl lining
Kd 0.5
Tr 0.25
Ka oops
map_Kd C:/assets/elsewhere.png

newmtl broken
Kd red green blue
"""


@pytest.fixture
def library(tmp_path):
    folder = tmp_path / "asset"
    (folder / "textures").mkdir(parents=True)
    (folder / "textures" / "cotton weave.png").write_bytes(b"png")
    (folder / "textures" / "bump.png").write_bytes(b"png")
    path = folder / "shirt.mtl"
    path.write_text(LIBRARY)
    return path


def test_read_mtl_colour_opacity_and_texture(library):
    """Kd (one value is grey), d or 1 - Tr, map_Kd after its options and with a space in its name; a value that
    is not a number is skipped; a texture that is not there is still named."""
    looks = read_mtl(library)
    assert list(looks) == ["front cotton", "lining", "broken"]
    assert looks["front cotton"] == MtlMaterial("front cotton", (0.9, 0.1, 0.2), 0.75,
                                                (library.parent / "textures" / "cotton weave.png").resolve())
    assert looks["lining"].diffuse == (0.5, 0.5, 0.5) and looks["lining"].opacity == 0.75
    assert looks["lining"].diffuse_texture.name == "elsewhere.png"
    assert looks["broken"] == MtlMaterial("broken")


def test_copy_mtl_keeps_textures_reachable(library, tmp_path):
    """The copy's relative texture paths lead from its own folder to the library's textures; a texture that is
    not there and every other line are written as they were."""
    target = tmp_path / "out" / "bake" / "obj" / "shirt.mtl"
    assert copy_mtl(library, target)
    lines = target.read_text().splitlines()
    kd = next(line for line in lines if line.startswith("map_Kd -s"))
    assert kd.startswith("map_Kd -s 1 1 1 ")
    assert (target.parent / kd[len("map_Kd -s 1 1 1 "):]).resolve() == (library.parent / "textures" / "cotton weave.png").resolve()
    bump = next(line for line in lines if line.startswith("map_Bump"))
    assert (target.parent / bump.split()[-1]).resolve() == (library.parent / "textures" / "bump.png").resolve()
    assert "map_Kd C:/assets/elsewhere.png" in lines and "Kd red green blue" in lines
    assert read_mtl(target)["front cotton"] == read_mtl(library)["front cotton"]


def test_an_unreadable_library_is_warned_and_skipped(tmp_path, library, caplog):
    with caplog.at_level(logging.WARNING, logger="formats.mtl"):
        assert read_mtl(tmp_path / "missing.mtl") == {}
        names = copy_material_libraries([tmp_path / "missing.mtl", library, tmp_path / "asset" / "shirt.mtl"],
                                        tmp_path / "copies")
    assert names == ["shirt.mtl"] and (tmp_path / "copies" / "shirt.mtl").is_file()
    assert "missing.mtl' : cannot be read" not in caplog.text and "missing.mtl': cannot be read" in caplog.text
    assert "already copied" in caplog.text
    other = tmp_path / "other.mtl"
    other.write_text("newmtl lining\nKd 0 0 1\nnewmtl extra\n")
    looks = read_libraries([library, other])
    assert looks["lining"].diffuse == (0.5, 0.5, 0.5) and "extra" in looks  # the first definition wins
    assert not Path(tmp_path / "copies" / "missing.mtl").exists()
