"""Map images as nav2's map_server reads them (PGM 8 and 16 bit, PNG, BMP, JPEG, color and
alpha, inclusive thresholds), and map YAML files that must be refused before they hang the
loader or exhaust memory."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from active_loc.maps import FREE, OCCUPIED, UNKNOWN, MapFileError, OccupancyGrid

# nav2's map_server unit-test map (test_constants.cpp): 10 x 10 at 0.1 m, rows listed from
# the BOTTOM of the map (lower-left pixel first), 100 occupied and 0 free
NAV2_TESTMAP_BOTTOM_UP = np.array([
    [0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
    [100, 100, 100, 100, 0, 0, 100, 100, 100, 0],
    [100, 100, 100, 100, 0, 0, 100, 100, 100, 0],
    [100, 0, 0, 0, 0, 0, 0, 0, 0, 0],
    [100, 0, 0, 0, 0, 0, 0, 0, 0, 0],
    [100, 0, 0, 0, 0, 0, 100, 100, 0, 0],
    [100, 0, 0, 0, 0, 0, 100, 100, 0, 0],
    [100, 0, 0, 0, 0, 0, 100, 100, 0, 0],
    [100, 0, 0, 0, 0, 0, 100, 100, 0, 0],
    [100, 0, 0, 0, 0, 0, 0, 0, 0, 0],
], dtype=np.int8)

YAML = ("image: {image}\nresolution: 0.1\norigin: [2.0, 3.0, 1.0]\nnegate: 0\n"
        "occupied_thresh: {occ}\nfree_thresh: {free}\nmode: {mode}\n")


def write_map(folder: Path, image: Image.Image, name: str, occ: float = 0.65,
              free: float = 0.196, mode: str = "trinary") -> Path:
    image.save(folder / name)
    yaml_path = folder / f"{Path(name).stem}_{Path(name).suffix[1:]}.yaml"
    yaml_path.write_text(YAML.format(image=name, occ=occ, free=free, mode=mode))
    return yaml_path


def nav2_testmap_pixels() -> np.ndarray:
    """The nav2 test map as an 8-bit image, row 0 at the top: black occupied, white free."""
    return np.where(NAV2_TESTMAP_BOTTOM_UP[::-1] == 100, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("name", ["testmap.png", "testmap.bmp", "testmap.pgm", "testmap.tif"])
def test_the_nav2_test_map_loads_cell_by_cell_from_every_format(tmp_path: Path,
                                                                name: str) -> None:
    path = write_map(tmp_path, Image.fromarray(nav2_testmap_pixels()), name)
    grid = OccupancyGrid.load(path)
    assert grid.shape == (10, 10) and grid.resolution == 0.1
    assert grid.origin == (2.0, 3.0, 1.0)
    np.testing.assert_array_equal(grid.values, NAV2_TESTMAP_BOTTOM_UP)


def test_a_jpeg_map_loads_its_blocks(tmp_path: Path) -> None:
    # JPEG is lossy: 8 x 8 blocks of pure black and white survive it within a few levels
    blocks = np.kron(NAV2_TESTMAP_BOTTOM_UP[::-1] == 100, np.ones((8, 8), dtype=bool))
    image = Image.fromarray(np.where(blocks, 0, 255).astype(np.uint8))
    grid = OccupancyGrid.load(write_map(tmp_path, image, "m.jpg"))
    np.testing.assert_array_equal(grid.values[4::8, 4::8], NAV2_TESTMAP_BOTTOM_UP)


def test_color_pixels_take_the_mean_of_red_green_and_blue(tmp_path: Path) -> None:
    # means 0 (black), 255 (white), 170 (p = 0.333: unknown), 85 (p = 0.667: occupied)
    rgb = np.array([[[0, 0, 0], [255, 255, 255], [255, 255, 0], [255, 0, 0]]], dtype=np.uint8)
    grid = OccupancyGrid.load(write_map(tmp_path, Image.fromarray(rgb), "c.png"))
    np.testing.assert_array_equal(grid.values, [[OCCUPIED, FREE, UNKNOWN, OCCUPIED]])


def test_alpha_below_full_opacity_is_unknown(tmp_path: Path) -> None:
    rgba = np.array([[[0, 0, 0, 255], [255, 255, 255, 255], [0, 0, 0, 254],
                      [255, 255, 255, 0]]], dtype=np.uint8)
    grid = OccupancyGrid.load(write_map(tmp_path, Image.fromarray(rgba), "a.png"))
    np.testing.assert_array_equal(grid.values, [[OCCUPIED, FREE, UNKNOWN, UNKNOWN]])


def test_gray_with_alpha_and_palette_images(tmp_path: Path) -> None:
    la = np.array([[[0, 255], [255, 255], [255, 10]]], dtype=np.uint8)
    grid = OccupancyGrid.load(write_map(tmp_path, Image.fromarray(la), "la.png"))
    np.testing.assert_array_equal(grid.values, [[OCCUPIED, FREE, UNKNOWN]])
    palette = Image.new("P", (2, 1))
    palette.putpalette([0, 0, 0, 255, 255, 255])
    palette.putdata([0, 1])
    grid = OccupancyGrid.load(write_map(tmp_path, palette, "p.png"))
    np.testing.assert_array_equal(grid.values, [[OCCUPIED, FREE]])


def test_16_bit_pgm_and_png_keep_their_depth(tmp_path: Path) -> None:
    # 65535 white, 0 black, 32768: p = 0.49999 (unknown), 13107: p = 0.8 (occupied)
    values = np.array([[65535, 0, 32768, 13107]], dtype=np.uint16)
    expected = [[FREE, OCCUPIED, UNKNOWN, OCCUPIED]]
    pgm = tmp_path / "d.pgm"
    pgm.write_bytes(b"P5\n4 1\n65535\n" + values.astype(">u2").tobytes())
    (tmp_path / "d.yaml").write_text(YAML.format(image="d.pgm", occ=0.65, free=0.196,
                                                 mode="trinary"))
    np.testing.assert_array_equal(OccupancyGrid.load(tmp_path / "d.yaml").values, expected)
    png = Image.fromarray(values.astype(np.uint16))
    grid = OccupancyGrid.load(write_map(tmp_path, png, "d16.png"))
    np.testing.assert_array_equal(grid.values, expected)


def test_thresholds_are_inclusive_as_in_nav2(tmp_path: Path) -> None:
    # p = 0 (white), 0.2 (204), 0.6 (102), 1 (black)
    gray = np.array([[255, 204, 102, 0]], dtype=np.uint8)
    image = Image.fromarray(gray)
    grid = OccupancyGrid.load(write_map(tmp_path, image, "s.png", occ=1.0, free=0.0,
                                        mode="scale"))
    np.testing.assert_array_equal(grid.values, [[FREE, UNKNOWN, UNKNOWN, OCCUPIED]])
    grid = OccupancyGrid.load(write_map(tmp_path, image, "t.png", occ=0.6, free=0.2))
    np.testing.assert_array_equal(grid.values, [[FREE, FREE, OCCUPIED, OCCUPIED]])


def test_a_file_that_is_no_image_is_refused_naming_it(tmp_path: Path) -> None:
    (tmp_path / "x.png").write_bytes(b"this is not an image")
    (tmp_path / "x.yaml").write_text(YAML.format(image="x.png", occ=0.65, free=0.196,
                                                 mode="trinary"))
    with pytest.raises(MapFileError, match=r"x.png: not an image map_server reads"):
        OccupancyGrid.load(tmp_path / "x.yaml")


# --- YAML files that must not hang the loader ------------------------------------------------

GOOD_FIELDS = "image: m.pgm\nresolution: 0.05\nnegate: 0\noccupied_thresh: 0.65\n" \
              "free_thresh: 0.196\n"


@pytest.fixture
def pgm_folder(tmp_path: Path) -> Path:
    (tmp_path / "m.pgm").write_bytes(b"P5\n2 2\n255\n" + bytes([0, 254, 254, 0]))
    return tmp_path


def alias_bomb(depth: int = 12) -> str:
    lines = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    for i in range(1, depth):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("field", ["origin", "image", "resolution"])
def test_an_alias_bomb_is_refused_at_once(pgm_folder: Path, field: str) -> None:
    fields = {"origin": "origin: [0.0, 0.0, 0.0]\n"}
    text = alias_bomb() + GOOD_FIELDS + fields["origin"]
    text = text.replace(f"{field}: ", f"{field}: *a11\nold_{field}: ", 1)
    (pgm_folder / "m.yaml").write_text(text)
    start = time.perf_counter()
    with pytest.raises(MapFileError, match="anchors and aliases are not allowed"):
        OccupancyGrid.load(pgm_folder / "m.yaml")
    assert time.perf_counter() - start < 2.0  # refused from the events, never expanded


def test_deep_nesting_is_refused_without_recursion_error(pgm_folder: Path) -> None:
    (pgm_folder / "m.yaml").write_text(GOOD_FIELDS + "origin: " + "[" * 5000 + "]" * 5000
                                       + "\n")
    with pytest.raises(MapFileError, match="nested deeper"):
        OccupancyGrid.load(pgm_folder / "m.yaml")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_device_as_the_image_or_the_yaml_is_refused(pgm_folder: Path) -> None:
    (pgm_folder / "m.yaml").write_text(GOOD_FIELDS.replace("m.pgm", "/dev/zero")
                                       + "origin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match=r"/dev/zero: not a regular file"):
        OccupancyGrid.load(pgm_folder / "m.yaml")
    with pytest.raises(MapFileError, match=r"/dev/zero: not a regular file"):
        OccupancyGrid.load("/dev/zero")


def test_an_oversized_yaml_is_refused(pgm_folder: Path) -> None:
    (pgm_folder / "m.yaml").write_text(GOOD_FIELDS + "origin: [0, 0, 0]\n" + "#" * 2**21)
    with pytest.raises(MapFileError, match="larger than the limit"):
        OccupancyGrid.load(pgm_folder / "m.yaml")


def test_an_image_with_too_many_pixels_is_refused_from_its_header(pgm_folder: Path) -> None:
    (pgm_folder / "m.pgm").write_bytes(b"P5\n100000 100000\n255\n")
    (pgm_folder / "m.yaml").write_text(GOOD_FIELDS + "origin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="exceeds the limit of 100000000 pixels"):
        OccupancyGrid.load(pgm_folder / "m.yaml")


def test_yaml_1_2_numbers_are_read_in_origin_as_in_resolution(pgm_folder: Path) -> None:
    (pgm_folder / "m.yaml").write_text(GOOD_FIELDS.replace("0.05", "5e-2")
                                       + "origin: [5e-2, -1e1, 0]\n")
    grid = OccupancyGrid.load(pgm_folder / "m.yaml")
    assert grid.resolution == 0.05 and grid.origin == (0.05, -10.0, 0.0)
