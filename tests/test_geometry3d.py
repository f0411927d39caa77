"""The 3D fingertip as data: the built-in file, its closed-form volumes against independent
exact values, and one clear error per kind of impossible input."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.fingertip3d import (
    Fingertip3D,
    half_ellipsoid_area_and_mean_curvature,
    load_fingertip3d,
    section_dimension,
)
from fingertip_dolfinx.geometry.section import Ellipse, Section, load_section


def test_the_builtin_file_is_3d_and_its_cross_section_is_the_2d_section():
    tip = load_fingertip3d("male-index-3d")
    assert section_dimension("male-index-3d") == 3 and section_dimension("male-index") == 2
    two_d = load_section("male-index")
    for part in ("outer", "skin_thickness", "bone", "nail"):
        assert getattr(tip.section, part) == getattr(two_d, part), part
    assert tip.total_length == tip.cylinder_length + tip.tip_length
    assert not tip.half and load_fingertip3d(overrides={"half": True}).half


def test_the_2d_reader_refuses_a_3d_file():
    with pytest.raises(InputError, match="dimension") as err:
        load_section("male-index-3d")
    assert "load_fingertip3d" in err.value.fix


def test_skin_volume_of_a_round_finger_is_the_exact_spherical_shell():
    # a = b = c = r: the skin is a cylindrical tube plus a hemispherical shell, exactly.
    r, t, L = 7.0, 0.8, 14.0
    section = Section(outer=Ellipse(r, r), bone=Ellipse(3.5, 2.0, 2.0),
                      mesh=Fingertip3D().section.mesh)
    tip = Fingertip3D(section=section, cylinder_length=L, tip_length=r)
    exact = math.pi * (r**2 - (r - t) ** 2) * L + 2 * math.pi * (r**3 - (r - t) ** 3) / 3
    assert tip.exact_volumes()["skin"] == pytest.approx(exact, rel=1e-12)


def test_half_ellipsoid_curvature_integrals_reach_round_off():
    # Hemisphere: area 2 pi r^2 and total mean curvature 2 pi r; a prolate spheroid's area has
    # a closed form too.
    area, mean = half_ellipsoid_area_and_mean_curvature(3.0, 3.0, 3.0)
    assert area == pytest.approx(2 * math.pi * 9, rel=1e-13)
    assert mean == pytest.approx(2 * math.pi * 3, rel=1e-13)
    a, c = 3.0, 5.0  # prolate spheroid: area = 2 pi a^2 (1 + c / (a e) asin e), e^2 = 1 - a^2/c^2
    e = math.sqrt(1 - a**2 / c**2)
    full = 2 * math.pi * a**2 * (1 + c / (a * e) * math.asin(e))
    assert half_ellipsoid_area_and_mean_curvature(a, a, c)[0] == pytest.approx(full / 2, rel=1e-12)


def test_bone_and_outer_volumes_are_the_integrals_of_their_cross_sections():
    tip = load_fingertip3d()
    bone = tip.section.bone
    area = lambda z: math.pi * bone.a * bone.b * float(tip.bone_scale(z)) ** 2  # noqa: E731
    breaks = [0.0, tip.bone_cap_start, tip.bone_length]
    integral = sum(quad(area, z0, z1, epsrel=1e-12)[0] for z0, z1 in zip(breaks, breaks[1:]))
    assert tip.exact_volumes()["bone"] == pytest.approx(integral, rel=1e-9)
    outer = sum(tip.exact_volumes().values()) - tip.exact_volumes()["nail"]
    a_b = lambda z: math.pi * np.prod(tip.outer_semi_axes(z))  # noqa: E731
    L = tip.cylinder_length
    assert outer == pytest.approx(quad(a_b, 0, L)[0] + quad(a_b, L, tip.total_length)[0],
                                  rel=1e-9)


def test_sampled_distance_to_the_outer_surface_is_within_its_stated_bound():
    tip = load_fingertip3d()
    # On the axis 3 mm before the tip the apex is the nearest point (the apex's radii of
    # curvature, a^2/c and b^2/c, exceed 3 mm); the sampling bound is spacing^2 / (4 d).
    d = tip.distance_to_outer([[0.0, 0.0, tip.total_length - 3.0]])[0]
    assert 3.0 <= d + 1e-12 and d - 3.0 <= 0.25**2 / (4 * 3.0)


@pytest.mark.parametrize("overrides, key, words", [
    ({"outer": {"tip_length": 1.0}}, "skin.thickness", "radius of curvature"),
    ({"outer": {"cylinder_length": -1.0}}, "outer.cylinder_length", "positive"),
    ({"bone": {"length": 22.0}}, "bone.length", "past the tip"),
    ({"bone": {"length": 20.7}}, "bone", "inside the skin's inner surface"),
    ({"bone": {"taper": 1.5}}, "bone.taper", "(0, 1]"),
    ({"bone": {"taper": 0.0}}, "bone.taper", "positive"),
    ({"bone": {"end_length": 18.0}}, "bone.end_length", "not shorter"),
    ({"bone": {"centre_y": 4.5}}, "bone", "tissue"),  # the 2D section's check at z = 0
    ({"nail": {"half_angle": 95.0}}, "nail.half_angle", "between 0 and 90"),
    ({"nail": {"end_z": 14.0}}, "nail.end_z", "cylindrical part"),
    ({"nail": {"start_z": 14.0}}, "nail.start_z", "start_z < nail.end_z"),
    ({"mesh": {"min_size": 0.0}}, "mesh.min_size", "positive"),
    ({"mesh": {"max_size": 0.2}}, "mesh.max_size", "smaller than mesh.min_size"),
    ({"mesh": {"refine_half_width": 9.0}}, "mesh.refine_half_width", "beyond the pulp"),
    ({"mesh": {"refine_z_max": 20.5}}, "mesh.refine_z_max", "outside the pulp"),
    ({"mesh": {"refine_z_min": 17.0}}, "mesh.refine_z_min", "refine_z_min < refine_z_max"),
    ({"mesh": {"tips": [0.0]}}, "mesh.tips", "unknown"),
    ({"pulp": {"half_angle": 80.0}}, "pulp", "unknown"),
    ({"half": 1}, "half", "true or false"),
])
def test_each_impossible_input_names_its_key_and_the_fix(overrides, key, words):
    with pytest.raises(InputError) as err:
        load_fingertip3d(overrides=overrides)
    assert f"key {key}" in err.value.where and words in err.value.problem, str(err.value)
    assert err.value.fix


def test_a_file_without_dimension_3_is_refused(tmp_path):
    path = tmp_path / "flat.toml"
    path.write_text("[outer]\nwidth = 16.0\n")
    with pytest.raises(InputError, match="dimension = 3"):
        load_fingertip3d(path)
    path.write_text("dimension = 4\n")
    with pytest.raises(InputError, match="must be 2 or 3"):
        section_dimension(path)


def test_the_half_model_halves_every_volume():
    full, half = load_fingertip3d(), load_fingertip3d(overrides={"half": True})
    v_full, v_half = full.exact_volumes(), half.exact_volumes()
    assert all(v_half[k] == pytest.approx(v_full[k] / 2, rel=1e-15) for k in v_full)
    assert dataclasses.replace(full, half=True).exact_volumes() == v_half


def test_ellipsoid_distance_is_exact_on_spheres_and_at_the_apex():
    from fingertip_dolfinx.geometry.fingertip3d import ellipsoid_distance

    p = np.array([[1.0, 2.0, 2.0], [0.3, -0.2, 6.5], [-4.0, 1.0, 8.0]])
    assert ellipsoid_distance(p, (5.0, 5.0, 5.0)) == pytest.approx(
        np.abs(5.0 - np.linalg.norm(p, axis=1)), rel=1e-12)
    # Near the apex (0, 0, c), within its smallest radius of curvature b^2 / c, the apex is
    # the nearest point (to second order in the offset from the axis).
    assert ellipsoid_distance([[1e-6, 1e-6, 6.5]], (8.0, 7.0, 7.0))[0] == pytest.approx(0.5,
                                                                                         rel=1e-9)
