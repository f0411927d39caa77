"""Indenter shapes: exact signed distances and normals (numpy and UFL alike), data validation."""

import dataclasses
import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.mesh import create_box, create_rectangle
from mpi4py import MPI
from scipy.spatial import cKDTree

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.indenters import (
    BUILTIN_DIR,
    Bar,
    Cylinder,
    Grating,
    Plate,
    Sphere,
    Wedge,
    load_indenter,
    make_indenter,
    penetration,
)

WEDGE = Wedge(tip_radius=0.025, base=1.2, height=3.0, centre_x=0.3)
# Four ridges (centres at 0.2 ± 0.55, ± 1.65): points over |x| <= 1.5 meet ridges, grooves,
# the outermost ridges' outer flanks and the rounded corners.
GRATING = Grating(width=0.6, period=1.1, ridges=4, corner_radius=0.1, centre_x=0.2)
SHAPES = [WEDGE, Bar(width=1.0, centre_x=-0.2), Cylinder(radius=2.0, centre_x=0.5), Plate(),
          GRATING]
Y_TIP = -0.4


def boundary(shape, y_tip: float, n: int = 200_001) -> np.ndarray:
    """Dense points on the shape's boundary (flanks down to 5 mm), built independently."""
    if isinstance(shape, Grating):
        return grating_boundary(shape, y_tip, n)
    if isinstance(shape, Plate):
        return np.column_stack((np.linspace(-10, 10, n), np.full(n, y_tip)))
    if isinstance(shape, Cylinder):
        t = np.linspace(0, 2 * np.pi, n)
        c = np.array([shape.centre_x, y_tip - shape.radius])
        return c + shape.radius * np.column_stack((np.cos(t), np.sin(t)))
    if isinstance(shape, Wedge):
        r, alpha = shape.tip_radius, shape.half_angle
    else:
        r, alpha = shape.width / 2, 0.0
    c = np.array([shape.centre_x, y_tip - r])
    t = np.linspace(alpha, np.pi - alpha, n)
    arc = c + r * np.column_stack((np.cos(t), np.sin(t)))
    s = np.linspace(0, 5, n)[:, None]
    tangent_point = c + r * np.array([math.cos(alpha), math.sin(alpha)])
    right = tangent_point + s * [math.sin(alpha), -math.cos(alpha)]
    left = right * [-1, 1] + [2 * c[0], 0]
    return np.vstack((arc, right, left))


def grating_boundary(g: Grating, y_tip: float, n: int) -> np.ndarray:
    """Each ridge as its pieces: the flat top, two quarter circles (n/10 points each), two
    flanks down 5 mm (n points each)."""
    r, a = g.corner_radius, g.width / 2 - g.corner_radius
    pieces = []
    for c in g.centre_x + (np.arange(g.ridges) - (g.ridges - 1) / 2) * g.period:
        t, s = np.linspace(0, np.pi / 2, n // 10), np.linspace(-a, a, n // 10)
        down = np.linspace(0, 5, n)
        for side in (-1, 1):
            pieces.append(np.column_stack((c + side * (a + r * np.cos(t)),
                                           y_tip - r + r * np.sin(t))))
            pieces.append(np.column_stack((np.full(n, c + side * (a + r)), y_tip - r - down)))
        pieces.append(np.column_stack((c + s, np.full(len(s), y_tip))))
    return np.vstack(pieces)


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.shape)
def test_distance_magnitude_matches_brute_force_and_normal_is_its_gradient(shape):
    rng = np.random.default_rng(1)
    points = np.column_stack((rng.uniform(-1.5, 1.5, 300), rng.uniform(-2.5, 0.6, 300)))
    phi, n = shape.signed_distance_np(points, Y_TIP)
    edge = boundary(shape, Y_TIP)
    nearest, _ = cKDTree(edge).query(points)
    assert np.allclose(np.abs(phi), nearest, atol=1e-6)
    # n = ∇φ, of unit length, wherever φ is differentiable (off the medial axis).
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    step = 1e-6
    for k in range(2):
        shift = np.zeros(2)
        shift[k] = step
        fd = (shape.signed_distance_np(points + shift, Y_TIP)[0]
              - shape.signed_distance_np(points - shift, Y_TIP)[0]) / (2 * step)
        smooth = np.abs(points[:, 0] - shape.centre_x) > 1e-3  # the axis is a medial line
        assert np.allclose(fd[smooth], n[smooth, k], atol=1e-5)


def test_wedge_values_at_tip_flanks_and_base_corners():
    w, r, a = WEDGE, WEDGE.tip_radius, WEDGE.half_angle
    c = np.array([w.centre_x, Y_TIP - r])
    flank_normal = np.array([math.cos(a), math.sin(a)])
    tangent_point = c + r * flank_normal
    down_flank = np.array([math.sin(a), -math.cos(a)])
    points = np.array([
        [w.centre_x, Y_TIP],  # the tip itself
        [w.centre_x, Y_TIP + 0.01],  # just above it, where the sharp wedge's apex would be
        c + (r + 0.02) * np.array([math.cos(1.2), math.sin(1.2)]),  # off the round tip
        c + 0.5 * r * np.array([0.0, 1.0]),  # inside the tip, nearer the arc than the flanks
        tangent_point + 1.0 * down_flank + 0.05 * flank_normal,  # outside the right flank
        tangent_point + 1.0 * down_flank - 0.05 * flank_normal,  # inside, near the right flank
        [w.centre_x + w.base / 2, Y_TIP - w.height],  # base corners lie on the flanks
        [w.centre_x - w.base / 2, Y_TIP - w.height],
    ])
    phi, n = w.signed_distance_np(points, Y_TIP)
    assert phi == pytest.approx([0.0, 0.01, 0.02, -0.5 * r, 0.05, -0.05, 0.0, 0.0], abs=1e-12)
    assert n[1] == pytest.approx([0.0, 1.0])
    assert n[4] == pytest.approx(flank_normal)
    assert n[7] == pytest.approx(flank_normal * [-1, 1])
    # The paper's wedge: a thin blade, flanks about 10.9° off vertical.
    assert math.degrees(a) == pytest.approx(10.93, abs=0.01)


def test_bar_cylinder_and_plate_values():
    bar = Bar(width=1.0)  # tip circle: centre (0, -0.5), radius 0.5
    phi, _ = bar.signed_distance_np([[0, 1], [1, -3], [0.25, -3], [-1, -3], [1, 0.5]], 0.0)
    assert phi == pytest.approx([1.0, 0.5, -0.25, 0.5, math.sqrt(2) - 0.5])
    cyl = Cylinder(radius=2.0, centre_x=0.5)  # centre (0.5, -1)
    phi, n = cyl.signed_distance_np([[0.5, 3.0], [2.5, -1.0], [0.5, 0.0]], 1.0)
    assert phi == pytest.approx([2.0, 0.0, -1.0])
    assert n[1] == pytest.approx([1.0, 0.0])
    phi, n = Plate().signed_distance_np([[5.0, 0.3], [-2.0, -0.1]], 0.1)
    assert phi == pytest.approx([0.2, -0.2])
    assert np.allclose(n, [[0, 1], [0, 1]])


def test_a_grating_is_the_union_of_its_ridges_and_one_ridge_is_a_flat_topped_bar():
    """The fold onto the nearest ridge gives min over the ridges' own distances (each a
    one-ridge grating), and that ridge's normal; a ridge with corner_radius = width/2 is the
    round-tipped bar."""
    rng = np.random.default_rng(3)
    points = np.column_stack((rng.uniform(-3, 3, 2000), rng.uniform(-2.5, 0.6, 2000)))
    singles = [dataclasses.replace(GRATING, ridges=1, centre_x=GRATING.centre_x + c)
               for c in GRATING.centres()]
    each = [g.signed_distance_np(points, Y_TIP) for g in singles]
    distances = np.array([phi for phi, _ in each])
    nearest = np.argmin(distances, axis=0)
    phi, n = GRATING.signed_distance_np(points, Y_TIP)
    assert np.allclose(phi, distances.min(axis=0), rtol=0, atol=1e-14)  # x − c rounded apart
    two = np.sort(distances, axis=0)[:2]
    clear = two[1] - two[0] > 1e-9  # off the groove's medial line, where two ridges tie
    assert np.allclose(n[clear], np.array([each[k][1][i] for i, k in enumerate(nearest)])[clear],
                       rtol=0, atol=1e-12)
    round_ridge = Grating(width=1.0, period=1.0, ridges=1, corner_radius=0.5, centre_x=-0.2)
    bar = Bar(width=1.0, centre_x=-0.2)
    assert np.allclose(round_ridge.signed_distance_np(points, Y_TIP)[0],
                       bar.signed_distance_np(points, Y_TIP)[0], atol=1e-14)
    # a point 0.3 mm above the middle of the flat top of a ridge, and one in the groove
    top = GRATING.centre_x + GRATING.centres()[1]
    phi, n = GRATING.signed_distance_np([[top + 0.15, Y_TIP + 0.3], [top + 0.55, -1.0]], Y_TIP)
    assert phi == pytest.approx([0.3, 0.25]) and n[0] == pytest.approx([0.0, 1.0])


def test_penetration_is_the_depth_inside_and_zero_outside():
    depth = penetration(Bar(width=1.0), np.array([[0.0, -0.1], [0.0, 0.2], [0.4, -2.0]]), 0.0)
    assert depth == pytest.approx([0.1, 0.0, 0.1])


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.shape)
def test_ufl_and_numpy_agree_at_the_deformed_position(shape):
    domain = create_rectangle(MPI.COMM_WORLD, [[-1.5, -2.0], [1.5, 0.5]], [12, 10])
    V = fem.functionspace(domain, ("Lagrange", 2, (2,)))
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack((0.05 * np.sin(x[1]), 0.1 * x[0] * x[1])))
    y_tip = fem.Constant(domain, Y_TIP)
    x = ufl.SpatialCoordinate(domain) + u
    phi, n = shape.signed_distance(x, y_tip)
    reference_points = np.array([[1 / 3, 1 / 3], [0.1, 0.2], [0.7, 0.2]])
    expr = fem.Expression(ufl.as_vector((x[0], x[1], phi, n[0], n[1])), reference_points)
    cells = np.arange(domain.topology.index_map(2).size_local, dtype=np.int32)
    values = expr.eval(domain, cells).reshape(-1, 5)
    phi_np, n_np = shape.signed_distance_np(values[:, :2], Y_TIP)
    assert np.allclose(values[:, 2], phi_np, atol=1e-13)
    assert np.allclose(values[:, 3:], n_np, atol=1e-12)


def test_builtins_load_by_name_with_the_papers_sizes():
    assert load_indenter("wedge") == Wedge(tip_radius=0.025, base=1.2, height=3.0)
    assert load_indenter("bar") == Bar(width=1.0)
    assert isinstance(load_indenter("plate"), Plate)
    assert isinstance(load_indenter(BUILTIN_DIR / "cylinder.toml"), Cylinder)


def test_a_user_file_loads(tmp_path):
    path = tmp_path / "thin_bar.toml"
    path.write_text('shape = "bar"\nwidth = 0.5\ncentre_x = 1.5\n')
    assert load_indenter(path) == Bar(width=0.5, centre_x=1.5)


@pytest.mark.parametrize(
    "data, message",
    [
        ({"shape": "bar", "width": 0.0}, "bar.width: must be positive"),
        ({"shape": "cylinder", "radius": -1.0}, "cylinder.radius: must be positive"),
        ({"shape": "bar", "width": "1"}, "bar.width: must be a number"),
        ({"shape": "bar", "width": float("inf")}, "bar.width: must be finite"),
        ({"shape": "wedge", "tip_radius": 0.7, "base": 1.2, "height": 3.0},
         "larger than half the base"),
        ({"shape": "wedge", "tip_radius": 0.1, "base": 1.2, "height": 0.1},
         "does not exceed tip_radius"),
        ({"shape": "bar", "width": 1.0, "colour": "red"},
         "colour: unknown key.*keys of a bar are: shape, centre_x, centre_z, friction, "
         "axis, width"),
        ({"shape": "wedge", "base": 1.2}, "tip_radius, height: missing for a wedge"),
        ({"shape": "pyramid"}, "shape: got 'pyramid'.*one of wedge, bar, plate, cylinder"),
        ({"width": 1.0}, "shape: got None"),
        ({"shape": "grating", "width": 1.0, "period": 1.0, "ridges": 3, "corner_radius": 0.1},
         "grating.period: 1.0 mm does not exceed the ridge width"),
        ({"shape": "grating", "width": 1.0, "period": 2.0, "ridges": 3.0, "corner_radius": 0.1},
         "grating.ridges: must be a whole number"),
        ({"shape": "grating", "width": 1.0, "period": 2.0, "ridges": 3, "corner_radius": 0.6},
         "grating.corner_radius: 0.6 mm is larger than half the ridge width"),
    ],
)
def test_each_bad_value_gets_its_own_message(data, message):
    with pytest.raises(InputError, match=message):
        make_indenter(data, where="test.toml")


def test_a_missing_file_names_the_builtins_and_where_they_are():
    names = r"no such file.*bar, cylinder, grating, plate, sphere, wedge"
    with pytest.raises(InputError, match=names) as info:
        load_indenter("pyramid")
    assert str(BUILTIN_DIR) in str(info.value)


def test_bad_toml_is_reported_with_its_path(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("shape = bar\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_indenter(path)


# ---- 3D: prisms along z or x, the sphere -----------------------------------------------------

SPHERE = Sphere(radius=2.0, centre_x=0.3, centre_z=0.7)
SHAPES_3D = [SPHERE, Cylinder(radius=2.0, centre_x=0.5, axis="x", centre_z=1.0),
             Wedge(tip_radius=0.025, base=1.2, height=3.0, centre_x=0.3, axis="x", centre_z=-0.4),
             Bar(width=1.0, centre_x=-0.2), Plate(axis="x")]


def random_points_3d(n=300, seed=2):
    rng = np.random.default_rng(seed)
    return np.column_stack((rng.uniform(-1.5, 1.5, n), rng.uniform(-2.5, 0.6, n),
                            rng.uniform(-1.5, 1.5, n)))


def test_sphere_distance_matches_brute_force_and_normal_is_its_gradient():
    points = random_points_3d()
    phi, n = SPHERE.signed_distance_np(points, Y_TIP)
    # Dense points on the sphere (a Fibonacci lattice, spacing ~ 2 R sqrt(π/N) = 3.5e-3 mm):
    # the nearest of them is within spacing²/(8 R) ≈ 1e-6 mm of the exact distance... plus
    # the lattice's holes, half the spacing at most: compare at 2e-3 mm.
    k = np.arange(1_000_000) + 0.5
    polar, azimuth = np.arccos(1 - 2 * k / len(k)), math.pi * (1 + 5**0.5) * k
    centre = np.array([SPHERE.centre_x, Y_TIP - SPHERE.radius, SPHERE.centre_z])
    surface = centre + SPHERE.radius * np.column_stack(
        (np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)))
    nearest, _ = cKDTree(surface).query(points)
    assert np.abs(np.abs(phi) - nearest).max() < 2e-3
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert_normal_is_gradient(SPHERE, points, n)


def assert_normal_is_gradient(shape, points, n, step=1e-6):
    for k in range(3):
        shift = np.zeros(3)
        shift[k] = step
        fd = (shape.signed_distance_np(points + shift, Y_TIP)[0]
              - shape.signed_distance_np(points - shift, Y_TIP)[0]) / (2 * step)
        assert np.allclose(fd, n[:, k], atol=1e-5)


@pytest.mark.parametrize("shape", SHAPES_3D[1:], ids=lambda s: f"{s.shape}-{s.axis}")
def test_prisms_in_3d_are_the_2d_profile_extruded_along_their_axis(shape):
    """A "z" prism: φ(x, y, z) = φ2D(x, y), n = (n_x, n_y, 0). An "x" prism: the profile in the
    (z, y) plane at z = centre_z: φ = φ2D(centre_x + z − centre_z, y), n = (0, n_y, n_a)."""
    points = random_points_3d()
    phi, n = shape.signed_distance_np(points, Y_TIP)
    a = points[:, 0] if shape.axis == "z" else shape.centre_x + points[:, 2] - shape.centre_z
    phi2, n2 = dataclasses.replace(shape, axis="z").signed_distance_np(
        np.column_stack((a, points[:, 1])), Y_TIP)
    assert np.allclose(phi, phi2, rtol=0, atol=1e-14)  # a: the same sum in another order
    expected = (np.column_stack((n2, np.zeros(len(a)))) if shape.axis == "z"
                else np.column_stack((np.zeros(len(a)), n2[:, 1], n2[:, 0])))
    assert np.allclose(n, expected, rtol=0, atol=1e-14)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    smooth = np.abs(a - shape.centre_x) > 1e-3  # the axis plane is a medial surface
    assert_normal_is_gradient(shape, points[smooth], n[smooth])


@pytest.mark.parametrize("shape", SHAPES_3D, ids=lambda s: f"{s.shape}-{getattr(s, 'axis', '')}")
def test_ufl_and_numpy_agree_in_3d(shape):
    domain = create_box(MPI.COMM_WORLD, [[-1.5, -2.0, -1.0], [1.5, 0.5, 1.5]], [4, 4, 4])
    V = fem.functionspace(domain, ("Lagrange", 2, (3,)))
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack((0.05 * np.sin(x[1]), 0.1 * x[0] * x[1], 0.07 * x[2] * x[0])))
    x = ufl.SpatialCoordinate(domain) + u
    phi, n = shape.signed_distance(x, fem.Constant(domain, Y_TIP))
    reference_points = np.array([[0.25, 0.25, 0.25], [0.1, 0.2, 0.3], [0.6, 0.2, 0.1]])
    expr = fem.Expression(ufl.as_vector((x[0], x[1], x[2], phi, n[0], n[1], n[2])),
                          reference_points)
    cells = np.arange(domain.topology.index_map(3).size_local, dtype=np.int32)
    values = expr.eval(domain, cells).reshape(-1, 7)
    phi_np, n_np = shape.signed_distance_np(values[:, :3], Y_TIP)
    assert np.allclose(values[:, 3], phi_np, atol=1e-13)
    assert np.allclose(values[:, 4:], n_np, atol=1e-12)


def test_sphere_and_x_prisms_are_refused_in_2d_and_bad_axes_named():
    with pytest.raises(InputError, match="sphere.*needs a 3D mesh"):
        SPHERE.signed_distance_np(np.zeros((1, 2)), 0.0)
    with pytest.raises(InputError, match="'x' prism.*needs a 3D mesh"):
        Bar(width=1.0, axis="x").signed_distance_np(np.zeros((1, 2)), 0.0)
    with pytest.raises(InputError, match="bar.axis: got 'y'"):
        make_indenter({"shape": "bar", "width": 1.0, "axis": "y"})
    assert load_indenter("sphere") == Sphere(radius=2.0)


# ---- oriented gratings (3D), their floor and their profile ---------------------------------

GRATING_3D = Grating(width=1.0, period=2.0, ridges=5, corner_radius=0.1, centre_x=0.0,
                     centre_z=9.0)


def test_an_oriented_grating_has_its_exact_distance_at_chosen_points():
    """Ridges along the finger ("z"): centres at x = 0, ±2, ±4, tops 1 mm wide, corners of
    0.1 mm. Above a top φ is the height; in a groove's middle (x = 1) at y below the corners'
    centres it is the horizontal distance to the flank, 0.5 mm; 0.2 mm beside a corner's centre
    and 0.2 mm above it, the distance to that centre minus the radius."""
    y = Y_TIP
    points = np.array([[0.0, y + 0.3, 2.0], [2.2, y + 0.05, -7.0], [1.0, y - 1.0, 0.0],
                       [0.6, y - 0.1 + 0.2, 30.0], [5.0, y - 2.0, 9.0]])
    phi, n = GRATING_3D.signed_distance_np(points, y)
    corner = math.hypot(0.2, 0.2) - 0.1
    assert phi == pytest.approx([0.3, 0.05, 0.5, corner, 0.5], abs=1e-14)
    assert n[0] == pytest.approx([0, 1, 0]) and n[2] == pytest.approx([-1, 0, 0])
    assert n[3] == pytest.approx([math.sqrt(0.5), math.sqrt(0.5), 0])


def test_turning_a_grating_across_the_finger_swaps_x_and_z_about_its_centre():
    """axis "x" at (centre_x, centre_z): φ(x, y, z) = φ_z(centre_x + z − centre_z, y, ·) and
    the normal's x and z components swap."""
    across = dataclasses.replace(GRATING_3D, axis="x")
    points = random_points_3d(500, seed=5) * [3.0, 1.0, 3.0] + [0.0, 0.0, 9.0]
    swapped = np.column_stack((points[:, 2] - 9.0, points[:, 1], points[:, 0] + 9.0))
    phi_x, n_x = across.signed_distance_np(points, Y_TIP)
    phi_z, n_z = GRATING_3D.signed_distance_np(swapped, Y_TIP)
    assert np.allclose(phi_x, phi_z, rtol=0, atol=1e-14)
    assert np.allclose(n_x, n_z[:, [2, 1, 0]], rtol=0, atol=1e-14)


def test_a_grating_floor_caps_the_grooves_and_inf_leaves_the_grating_unchanged():
    """depth = inf (the default) is the grating without a floor, value for value; a floor
    0.5 mm down is min(φ, y − (y_tip − 0.5)) with the floor's normal (0, 1) where it wins."""
    rng = np.random.default_rng(7)
    points = np.column_stack((rng.uniform(-3, 3, 2000), rng.uniform(-2.5, 0.6, 2000)))
    same = dataclasses.replace(GRATING, depth=math.inf)
    assert np.array_equal(same.signed_distance_np(points, Y_TIP)[0],
                          GRATING.signed_distance_np(points, Y_TIP)[0])
    floored = dataclasses.replace(GRATING, depth=0.5)
    phi, n = floored.signed_distance_np(points, Y_TIP)
    open_phi, open_n = GRATING.signed_distance_np(points, Y_TIP)
    floor = points[:, 1] - (Y_TIP - 0.5)
    assert np.allclose(phi, np.minimum(open_phi, floor), rtol=0, atol=1e-15)
    wins = floor < open_phi
    assert np.allclose(n[wins], [0.0, 1.0]) and np.array_equal(n[~wins], open_n[~wins])
    # a groove's middle, 0.3 mm above the floor: 0.3 from the floor, 0.25 from the flanks
    groove = GRATING.centre_x + GRATING.centres()[1] + 0.55
    assert floored.signed_distance_np([[groove, Y_TIP - 0.2]], Y_TIP)[0] == pytest.approx(0.25)
    assert floored.signed_distance_np([[groove, Y_TIP - 0.4]], Y_TIP)[0] == pytest.approx(0.1)


@pytest.mark.parametrize("depth", [math.inf, 0.3])
def test_the_profile_is_the_surface_the_distance_sees(depth):
    """At every s across the ridges, (s, y_tip + profile(s)) lies on the indenter (φ = 0),
    in 2D and on an "x" grating in 3D, where s is measured from centre_z; over a groove
    without a floor the profile is −inf."""
    g = dataclasses.replace(GRATING, depth=depth)
    s = np.linspace(-3.0, 3.0, 4001)
    h = g.profile(s)
    finite = np.isfinite(h)
    phi, _ = g.signed_distance_np(np.column_stack((g.centre_x + s, Y_TIP + h))[finite], Y_TIP)
    assert np.abs(phi).max() < 1e-12
    assert np.all(h <= 0) and np.all(h >= -depth) and (depth < math.inf) == finite.all()
    across = dataclasses.replace(g, axis="x", centre_z=4.0)
    points = np.column_stack((np.full(finite.sum(), 7.0), Y_TIP + h[finite], 4.0 + s[finite]))
    assert np.abs(across.signed_distance_np(points, Y_TIP)[0]).max() < 1e-12


def test_shifting_a_prism_moves_it_across_its_edge():
    along, across = GRATING_3D, dataclasses.replace(GRATING_3D, axis="x")
    assert along.shifted(0.5).centre_x == 0.5 and along.shifted(0.5).centre_z == 9.0
    assert across.shifted(0.5).centre_z == 9.5 and across.shifted(0.5).centre_x == 0.0
    points = random_points_3d(200, seed=9)
    assert np.allclose(across.shifted(0.5).signed_distance_np(points + [0, 0, 0.5], Y_TIP)[0],
                       across.signed_distance_np(points, Y_TIP)[0], rtol=0, atol=1e-14)


def test_gratings_of_any_width_and_orientation_share_one_compiled_form():
    """A grating's numbers (width, period, centres, corners) and its orientation are
    Constants in the form: two gratings with the same ridge count have the same form signature
    (FFCx's cache key, so the second reuses the first's compiled code), and each form still
    evaluates its own grating's exact distance. The ridge count is the form's structure."""
    domain = create_box(MPI.COMM_WORLD, [[-3.0, -2.0, 6.0], [3.0, 0.5, 12.0]], [3, 2, 3])
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 2, (3,))))
    u.interpolate(lambda x: np.vstack((0.05 * np.sin(x[1]), 0.1 * x[0] * x[1], 0.07 * x[0])))
    x = ufl.SpatialCoordinate(domain) + u
    along = dataclasses.replace(GRATING_3D, ridges=13)
    across = dataclasses.replace(along, width=1.5, period=3.0, axis="x", centre_z=8.0)
    fewer = dataclasses.replace(across, ridges=9)
    forms = [shape.signed_distance(x, fem.Constant(domain, Y_TIP))[0] * ufl.ds
             for shape in (along, across, fewer)]
    assert forms[0].signature() == forms[1].signature() != forms[2].signature()
    points = np.array([[0.25, 0.25, 0.25], [0.1, 0.2, 0.3], [0.6, 0.2, 0.1]])
    cells = np.arange(domain.topology.index_map(3).size_local, dtype=np.int32)
    for shape in (along, across):
        phi, n = shape.signed_distance(x, fem.Constant(domain, Y_TIP))
        expr = fem.Expression(ufl.as_vector((x[0], x[1], x[2], phi, *n)), points)
        values = expr.eval(domain, cells).reshape(-1, 7)
        phi_np, n_np = shape.signed_distance_np(values[:, :3], Y_TIP)
        assert np.allclose(values[:, 3], phi_np, rtol=0, atol=1e-13)
        assert np.allclose(values[:, 4:], n_np, rtol=0, atol=1e-12)
    assert not np.allclose(*(s.signed_distance_np(values[:, :3], Y_TIP)[0]
                             for s in (along, across)))  # the two differ where evaluated


@pytest.mark.parametrize(
    "data, message",
    [
        ({"depth": 0.1}, "grating.depth: 0.1 mm does not exceed the corner radius"),
        ({"depth": -1.0}, "grating.depth: must be positive"),
        ({"depth": float("nan")}, "grating.depth: must be finite"),
        ({"axis": "y"}, "grating.axis: got 'y'"),
        ({"width": 0.0}, "grating.width: must be positive"),
        ({"period": "2"}, "grating.period: must be a number"),
    ],
)
def test_bad_grating_keys_are_named(data, message):
    table = {"shape": "grating", "width": 1.0, "period": 2.0, "ridges": 3,
             "corner_radius": 0.1, **data}
    with pytest.raises(InputError, match=message):
        make_indenter(table, where="test.toml")


def test_ufl_and_numpy_agree_on_a_floored_grating_across_the_finger():
    test_ufl_and_numpy_agree_in_3d(Grating(width=1.0, period=2.0, ridges=3, corner_radius=0.1,
                                           depth=0.4, axis="x", centre_z=0.3))


# ---- a tilted grating (a finger exploring a surface at a contact angle) ---------------------

TILTED = dataclasses.replace(GRATING_3D, axis="x", tilt=30.0)


def test_a_tilted_grating_has_its_exact_distance_at_chosen_points():
    """Tilted by θ = 30° about x (rising towards +z) about the line (y_tip, centre_z): a point
    at h along the plane (h = 0: the middle ridge's centre line, the grating's middle) and v
    above it lies at (y, z) = (y_tip + h sin θ + v cos θ, centre_z + h cos θ − v sin θ). Above
    a ridge's top φ = v and n is the plane's normal (0, cos θ, −sin θ); in a groove's middle
    (h = 1) below the corners' centres φ = 0.5 (the flank), n along the plane (∓ its
    direction (0, sin θ, cos θ)); beside and above a corner's centre, the distance to it."""
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    hv = np.array([[0.0, 0.3], [2.2, 0.05], [1.0, -0.6], [0.6, 0.1], [-4.0, -0.01]])
    x = np.array([0.7, -3.0, 0.0, 11.0, 2.0])  # any x: a prism along x
    points = np.column_stack((x, Y_TIP + hv[:, 0] * s + hv[:, 1] * c,
                              9.0 + hv[:, 0] * c - hv[:, 1] * s))
    phi, n = TILTED.signed_distance_np(points, Y_TIP)
    corner = math.hypot(0.2, 0.2) - 0.1
    assert phi == pytest.approx([0.3, 0.05, 0.5, corner, -0.01], abs=1e-14)
    assert n[0] == pytest.approx([0, c, -s]) and n[4] == pytest.approx([0, c, -s])
    assert np.abs(n[2]) == pytest.approx([0, s, c])  # the flank's normal lies along the plane
    assert n[3] == pytest.approx(math.sqrt(0.5) * np.array([0, s + c, c - s]))


def test_a_tilted_grating_is_the_flat_one_rotated_and_tilt_zero_is_the_flat_one():
    """φ is invariant under the rotation: φ_tilted(R p) = φ_flat(p) about the pivot line, and
    n_tilted = R n_flat; tilt = 0 (the default) is the untilted grating, value for value."""
    flat = dataclasses.replace(TILTED, tilt=0.0)
    assert flat == dataclasses.replace(GRATING_3D, axis="x")
    points = random_points_3d(500, seed=7) * [3.0, 1.0, 3.0] + [0.0, 0.0, 9.0]
    angle = math.radians(TILTED.tilt)
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(angle), math.sin(angle)],
                         [0.0, -math.sin(angle), math.cos(angle)]])  # (y, z) by +θ about x
    pivot = np.array([0.0, Y_TIP, 9.0])
    phi, n = flat.signed_distance_np(points, Y_TIP)
    phi_t, n_t = TILTED.signed_distance_np((points - pivot) @ rotation.T + pivot, Y_TIP)
    assert np.allclose(phi_t, phi, rtol=0, atol=1e-13)
    assert np.allclose(n_t, n @ rotation.T, rtol=0, atol=1e-13)
    assert rotation @ [0, 0, 1.0] == pytest.approx(TILTED.z_direction())  # moves along it
    assert flat.z_direction() is None
    with pytest.raises(InputError, match="grating.tilt: a tilted grating moved along its plane"):
        TILTED.shifted(0.5)


def test_ufl_and_numpy_agree_on_a_tilted_floored_grating():
    test_ufl_and_numpy_agree_in_3d(dataclasses.replace(TILTED, depth=0.4, centre_z=0.3))


@pytest.mark.parametrize("data, message", [
    ({"tilt": 20.0}, "grating.tilt: 20.0° needs ridges across the finger"),
    ({"tilt": 20.0, "axis": "x", "centre_z": 1.0, "friction": 0.5}, None),
    ({"tilt": -10.0, "axis": "x"}, "grating.tilt: must be between 0 and 60 degrees"),
    ({"tilt": 75.0, "axis": "x"}, "grating.tilt: must be between 0 and 60 degrees"),
    ({"tilt": float("inf"), "axis": "x"}, "grating.tilt: must be finite"),
])
def test_bad_tilts_are_named(data, message):
    table = {"shape": "grating", "width": 1.0, "period": 2.0, "ridges": 3,
             "corner_radius": 0.1, **data}
    if message is None:
        assert make_indenter(table).tilt == 20.0
        return
    with pytest.raises(InputError, match=message):
        make_indenter(table, where="test.toml")
