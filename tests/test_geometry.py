"""The section data: defaults, exact areas, and one clear error per kind of bad input."""

import math
import re

import numpy as np
import pytest

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.section import (
    SECTIONS_DIR,
    Ellipse,
    MeshOptions,
    Section,
    load_section,
)


def shoelace(points: np.ndarray) -> float:
    x, y = points[:, 0], points[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_builtin_file_holds_the_documented_defaults():
    section = load_section("male-index")
    assert section == Section(name="male-index")
    assert (2 * section.outer.a, 2 * section.outer.b, section.skin_thickness) == (16, 14, 0.8)
    assert (2 * section.bone.a, 2 * section.bone.b, section.bone.cy) == (7, 4, 2)
    assert load_section(SECTIONS_DIR / "male-index.toml") == section


def test_exact_areas_match_independent_polygons():
    # Dense polygons through exact boundary points: their area error is O(n^-2) ~ 1e-9 here.
    s, u = Section(), np.linspace(0.0, 2 * math.pi, 200_000, endpoint=False)
    outer = shoelace(s.outer.point(u))
    inner = shoelace(s.outer.point(u) - s.skin_thickness * s.outer.normal(u))
    u0, u1 = s.nail_params
    arc = np.linspace(u0, u1, 100_000)
    nail = np.concatenate([s.outer.point(arc), s.nail_surface_point(arc[::-1])])
    areas = s.exact_areas()
    assert areas["skin"] == pytest.approx(outer - inner, rel=1e-8)
    assert areas["subcutaneous"] == pytest.approx(inner - math.pi * 3.5 * 2.0, rel=1e-8)
    assert areas["nail"] == pytest.approx(shoelace(nail), rel=1e-8)


def test_distance_to_ellipse_is_exact_on_parallel_curves():
    e, u = Ellipse(8.0, 7.0), np.linspace(0, 2 * math.pi, 97)
    for t in (-0.8, 0.3, 2.0):
        assert np.allclose(e.distance(e.point(u) + t * e.normal(u)), abs(t), atol=1e-12)


def test_points_below_the_pulp_lie_at_their_depth_inside_the_ellipse():
    e, x = Ellipse(8.0, 7.0, cy=1.0), np.linspace(-6.0, 6.0, 13)
    for depth in (0.25, 0.75, 1.5):
        p = e.below_palmar(x, depth)
        # along the inward normal from the palmar point at x: at exactly that distance
        assert np.allclose(e.distance(p), depth, atol=1e-12) and e.contains(p).all()
        assert np.all(p[:, 1] < e.cy)
    assert np.allclose(e.below_palmar(0.0, 0.75), [[0.0, 1.0 - 7.0 + 0.75]], atol=1e-15)


def test_spots_are_x_depth_pairs_finer_than_the_zone():
    assert MeshOptions(spots=[[0.0, 0.75], [1, 2]]).spots == ((0.0, 0.75), (1.0, 2.0))
    for bad in ([0.0, 0.75], [[0.0]], [[0.0, -0.5]], [[0.0, math.nan]], "0, 0.75"):
        with pytest.raises(InputError, match=r"mesh\.spots: must be a list of \[x, depth\]"):
            MeshOptions(spots=bad)
    with pytest.raises(InputError, match=r"mesh\.spot_size: 0\.2 mm is coarser than mesh\.min"):
        MeshOptions(min_size=0.1, spots=[[0.0, 0.75]], spot_size=0.2)


def test_fine_mesh_sizes_are_allowed():
    assert Section(mesh=MeshOptions(min_size=0.01)).mesh.min_size == 0.01


BASE = (SECTIONS_DIR / "male-index.toml").read_text()


def edited(tmp_path, table: str, key: str, value: str):
    """The built-in file with `key = value` set in [table] (added if absent)."""
    text, pattern = BASE, re.compile(rf"^{key} = .*$", re.M)
    head, sep, tail = text.partition(f"[{table}]\n")
    tail = pattern.sub(f"{key} = {value}", tail, count=1) if pattern.search(tail) else (
        f"{key} = {value}\n" + tail
    )
    path = tmp_path / "finger.toml"
    path.write_text(head + sep + tail)
    return path


BAD = {
    "non-positive size": ("outer", "width", "-16.0", r"outer\.width: must be positive"),
    "zero thickness": ("nail", "thickness", "0.0", r"nail\.thickness: must be positive"),
    "not a number": ("skin", "thickness", '"thin"', r"skin\.thickness: must be a finite number"),
    "skin thicker than the section": (
        "skin", "thickness", "6.5", r"skin\.thickness: 6\.5 mm is not smaller .* of curvature"
    ),
    "bone outside the tissue": (
        "bone", "width", "15.0", r"key bone: the bone ellipse leaves the subcutaneous tissue"
    ),
    "bone overlapping the nail": ("bone", "centre_y", "6.0", r"key bone: .* into the nail plate"),
    "nail angle above 90": ("nail", "half_angle", "95.0", r"nail\.half_angle: must lie strictly"),
    "nail angle zero": ("nail", "half_angle", "0.0", r"nail\.half_angle: must lie strictly"),
    "pulp reaching the nail": ("pulp", "half_angle", "125.0", r"pulp\.half_angle: must lie"),
    "unknown key": ("skin", "thicknes", "0.8", r"skin\.thicknes: is not a known .*only: thickness"),
    "mesh size non-positive": ("mesh", "min_size", "0.0", r"mesh\.min_size: must be positive"),
    "max below min": ("mesh", "max_size", "0.05", r"mesh\.max_size: 0\.05 mm is smaller than"),
    "coarse bone finer than the tissue": ("mesh", "bone_size", "0.2", r"mesh\.bone_size: 0\.2 mm"),
    "refinement beyond the pulp": (
        "mesh", "refine_half_width", "9.0", r"mesh\.refine_half_width: .* beyond the pulp"
    ),
    "quadrilateral not a boolean": ("mesh", "quadrilateral", "1", r"mesh\.quadrilateral: must be"),
    "tips not a list": ("mesh", "tips", "0.0", r"mesh\.tips: must be a list"),
    "tip outside the refinement zone": ("mesh", "tips", "[5.0]", r"mesh\.tips: .* outside the"),
}


def test_tip_refinement_must_be_finer_than_the_zone():
    with pytest.raises(InputError, match=r"mesh\.tip_size: 0\.5 mm is coarser than mesh\.min"):
        MeshOptions(tips=(0.0,), tip_size=0.5)
    assert MeshOptions(tips=[0.0, 1.0]).tips == (0.0, 1.0)


@pytest.mark.parametrize("table, key, value, message", BAD.values(), ids=BAD.keys())
def test_each_bad_input_has_its_own_message(tmp_path, table, key, value, message):
    path = edited(tmp_path, table, key, value)
    with pytest.raises(InputError, match=message) as error:
        load_section(path)
    assert str(path) in str(error.value) and "Fix:" in str(error.value)


def test_unknown_table_lists_the_allowed_ones(tmp_path):
    path = tmp_path / "finger.toml"
    path.write_text(BASE + "\n[skn]\nthickness = 0.8\n")
    with pytest.raises(InputError, match=r"skn: is not a table .* \[outer\], \[skin\]"):
        load_section(path)


def test_missing_file_names_the_path_and_the_builtin_ones(tmp_path):
    with pytest.raises(InputError, match=r"no-such-finger\.toml.*male-index"):
        load_section("no-such-finger")
    with pytest.raises(InputError, match="no such section file"):
        load_section(tmp_path / "absent.toml")
