"""Two-point discrimination from the SA1 population (sweep.dip_ratio, population_threshold):
synthetic two-Gaussian profiles against the exact continuous answer, and one coarse 2pt run
per spacing against what the site geometry implies."""

import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from scipy.optimize import brentq, minimize_scalar

from fingertip_dolfinx.studies.sweep import (
    RESOLVED,
    dip_ratio,
    population_profile,
    population_threshold,
)


def two_gaussians(x, d, sigma=1.0, ratio=1.0):
    return np.exp(-((x - d / 2) / sigma) ** 2 / 2) + ratio * np.exp(-((x + d / 2) / sigma) ** 2 / 2)


def exact_ratio(d, sigma=1.0):
    """Equal Gaussians: dip at 0, 2 e^{−d²/8σ²}, over the peak found by a bounded search."""
    if d <= 2 * sigma:  # the sum of two equal Gaussians has one maximum for d <= 2σ
        return 1.0
    peak = -minimize_scalar(lambda x: -two_gaussians(x, d, sigma), bounds=(0, d),
                            method="bounded", options={"xatol": 1e-12}).fun
    return 2 * math.exp(-d**2 / (8 * sigma**2)) / peak


def test_rayleigh_fraction_is_the_slit_pattern_dip():
    """8/π²: two sinc² (first zero at ±1) one unit apart dip to 2 sinc²(1/2) at the middle."""
    x = np.linspace(-0.5, 1.5, 200001)
    profile = np.sinc(x) ** 2 + np.sinc(x - 1) ** 2
    assert dip_ratio(profile) == pytest.approx(RESOLVED, rel=1e-9)


def test_dip_ratio_of_two_gaussians_is_exact():
    """On a grid of step 1e-3 the sampled maxima lie within h²|p''|/8 ~ 1e-7 of the true ones."""
    x = np.linspace(-10, 10, 20001)
    for d in (2.5, 3.0, 4.0):
        assert dip_ratio(two_gaussians(x, d)) == pytest.approx(exact_ratio(d), rel=1e-6)
    assert dip_ratio(two_gaussians(x, 1.9)) == 1.0  # one maximum (d < 2σ)
    # unequal peaks: the smaller one sets the ratio; a third, lower bump does not count
    profile = two_gaussians(x, 4.0, ratio=0.5) + 0.1 * np.exp(-((x - 8) ** 2) / 0.5)
    i0 = np.argmin(np.abs(x + 2.0))
    assert dip_ratio(profile) < 1 and dip_ratio(profile) == pytest.approx(
        profile[(x > -2) & (x < 2)].min() / profile[i0 - 50:i0 + 50].max(), rel=1e-9)


def test_population_threshold_interpolates_the_crossing():
    """Spacings 0.02 apart over [2, 4]σ: the interpolated crossing of 8/π² agrees with the
    exact root of the continuous dip ratio to the linear-interpolation error (~Δd² r''/8)."""
    x = np.linspace(-10, 10, 20001)
    spacings = np.arange(2.0, 4.0001, 0.02)
    ratios = [dip_ratio(two_gaussians(x, d)) for d in spacings]
    got = population_threshold(spacings, ratios)
    exact = brentq(lambda d: exact_ratio(d) - RESOLVED, 2.05, 4.0, xtol=1e-12)
    assert got["threshold_mm"] == pytest.approx(exact, abs=1e-3)
    assert got["smallest_resolved_mm"] == pytest.approx(spacings[spacings > exact][0])
    # not bracketed: all pass, or the largest fails
    assert population_threshold([3.0, 4.0], [0.5, 0.2])["threshold_mm"] is None
    assert population_threshold([3.0, 4.0], [0.9, 0.95]) == {"smallest_resolved_mm": None,
                                                               "threshold_mm": None}


@pytest.fixture(scope="module")
def two_point_runs(tmp_path_factory):
    from fingertip_dolfinx.runner import run
    from fingertip_dolfinx.scene import load_scene

    coarse = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
              "section.mesh.bone_size=2.0", "output.pictures=false",
              'output.receptors="default"']
    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("2pt-population"), root=0)
    for d in (1.2, 2.0, 3.0):
        run(load_scene("2pt", coarse, spacing=d), Path(out) / f"d{d:g}", progress=False)
    return Path(out)


def test_a_coarse_two_point_run_resolves_what_the_sites_can(two_point_runs):
    """SA1 sites are 1.195 mm apart with one at x = 0: bars at ±0.6 mm share that site (one
    maximum, at x = 0); bars at ±1 and ±1.5 mm each have their own nearest site (x = ±1.19),
    where the two maxima lie, well below the criterion. The threshold lies between."""
    ratios = {}
    for d in (1.2, 2.0, 3.0):
        x, rate = population_profile(two_point_runs / f"d{d:g}", 1.0)
        assert len(x) == 11 and np.all(rate >= 0)
        ratios[d] = dip_ratio(rate)
        peaks = np.argsort(rate)[-2:]
        if d == 1.2:
            assert np.argmax(rate) == 5 and x[5] == 0.0
        else:
            np.testing.assert_allclose(np.sort(x[peaks]), [-1.195, 1.195], atol=0.01)
        np.testing.assert_allclose(rate, rate[::-1], rtol=0.05, atol=1e-3 * rate.max())
    assert ratios[1.2] == 1.0 and ratios[2.0] < RESOLVED and ratios[3.0] < RESOLVED
    got = population_threshold(list(ratios), list(ratios.values()))
    assert got["smallest_resolved_mm"] == 2.0 and 1.2 < got["threshold_mm"] < 2.0
