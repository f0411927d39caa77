"""The `slide` scene: the round-tipped 1 mm bar pressed 0.5 mm into the pulp, then slid 2 mm
across it at 80 mm/s with Coulomb friction μ = 0.5, the receptor rows and afferents on.

Gross slip in 2D: at every contact point the friction traction is μp along the tangent
t = (n_y, −n_x), all pointing the same way (the skin slips backwards under the bar), so the
friction's force is F_f = μ (F_p,y, −F_p,x) with F_p = ∫ p n ds the pressure's: its x-share is
μ times the pressure's normal force exactly, at the quadrature points that integrate both.
The total tangential force Ft = F_p,x + F_f,x is not μ Fn: on the round tip the pressure has an
x-share F_p,x (ploughing). history.csv has Ft, Fn = F_p,y + F_f,y and F_p,x, so
F_p,y = Fn + μ F_p,x and the law reads Ft − F_p,x = μ (Fn + μ F_p,x).
"""

from functools import cache

import numpy as np
import pytest

MU = 0.5


@cache
def slide_run(tmp_root: str):
    import fingertip_dolfinx as ft

    return ft.run(ft.load_scene("slide"), f"{tmp_root}/slide", progress=False)


@pytest.fixture(scope="module")
def slid(tmp_path_factory):
    from fingertip_dolfinx.outputs import read_csv

    result = slide_run(str(tmp_path_factory.mktemp("slide")))
    return result, read_csv(result.out / "history.csv"), read_csv(result.out / "stick_slip.csv")


def gross_slip(history, states) -> np.ndarray:
    """Steps of the slide where no surface node sticks and some are in contact."""
    rows = []
    for t in history["time_s"]:
        s = states["contact_state"][np.isclose(states["time_s"], t, rtol=0, atol=1e-12)]
        rows.append(np.any(s == 1) and not np.any(s == 2))
    return np.array(rows) & (history["tangential_displacement_mm"] > 0)


def friction_share(h) -> tuple[np.ndarray, np.ndarray]:
    """The friction's x-force Ft − F_p,x and the pressure's normal force F_p,y (gross slip)."""
    ft, fn = h["tangential_force_N_per_mm"], h["force_N_per_mm"]
    px = h["pressure_tangential_force_N_per_mm"]
    return ft - px, fn + MU * px


@pytest.mark.slow
def test_sliding_friction_is_mu_times_the_pressure_normal_force(slid):
    _, h, states = slid
    sliding = gross_slip(h, states)
    # gross slip is reached within the first half of the 2 mm slide (measured: no node
    # sticks from 0.58 mm on; the friction share is μ F_p,y from 0.44 mm)
    assert sliding[-1] and h["tangential_displacement_mm"][np.argmax(sliding)] < 1.0
    friction, normal = friction_share(h)
    # an identity of the projection at the forces' own quadrature points: rounding and the
    # solver's residual (rtol 1e-9) only (measured 2e-12)
    np.testing.assert_allclose(friction[sliding], MU * normal[sliding], rtol=1e-8)
    # the total is not μ Fn: the round tip ploughs (F_p,x > 0 pushes the bar back)
    ratio = h["tangential_force_N_per_mm"][sliding] / h["force_N_per_mm"][sliding]
    assert np.all(ratio > MU * 1.2) and np.all(h["pressure_tangential_force_N_per_mm"] >= 0)


@pytest.mark.slow
def test_sliding_dissipates_mu_times_the_load_times_the_slip(slid):
    """Per step in gross slip D = μ ∫ p |Δs| ds with |Δs| the slip relative to the bar, the
    bar's travel Δc less the skin's own travel under it: D/(μ F_p,y Δc) = 1 − (the skin's
    pressure-weighted speed)/(the bar's), in (0, 1] while the skin is carried along. On this
    curved pulp at constant depth the normal force grows ~40 % along the slide, so the skin
    is carried the whole way (a steady slide, D = μ F_p,y Δc, is the block's check:
    test_friction); the ratio rises as the tangential force levels off (measured 0.24 where
    no node sticks any more, 0.49 at 1 mm, 0.94 at the end)."""
    _, h, states = slid
    sliding = gross_slip(h, states)
    travel = np.diff(np.concatenate([[0.0], h["tangential_displacement_mm"]]))
    _, normal = friction_share(h)
    ratio = h["dissipated_N_mm_per_mm"][sliding] / (MU * normal[sliding] * travel[sliding])
    assert np.all(ratio > 0) and np.all(ratio <= 1 + 1e-8), ratio
    assert ratio[-1] > 0.9 and ratio[-1] > 3 * ratio[0], ratio
    # Pressed, the contact sticks: its elastic slip f/γ_t stores and gives back energy of
    # order (μp)² w/(2γ_t) ~ 1e-7 N mm/mm (p ~ 3 kPa, w ~ 1 mm, γ_t ~ 10 MPa/mm), of either
    # sign (measured −6e-7), against ~4e-4 dissipated by the slide
    pressing = h["tangential_displacement_mm"] == 0
    dissipated = h["dissipated_N_mm_per_mm"]
    assert abs(dissipated[pressing].sum()) < 1e-2 * dissipated[~pressing].sum()


@pytest.mark.slow
def test_the_slide_writes_receptor_histories_and_spikes(slid):
    result, h, _ = slid
    receptors = result.receptors()
    times = np.unique(receptors["time_s"])
    assert np.array_equal(times, h["time_s"])  # every site at every step
    assert set(np.unique(receptors["class"])) == {"SA1", "RA", "PC"}
    assert len(result.afferents["afferent"]) > 0 and "time_s" in result.spikes
    assert (result.out / "friction.png").exists() and (result.out / "population.png").exists()



def test_the_slide_scene_presses_then_slides_at_its_stated_speed():
    import fingertip_dolfinx as ft

    scene = ft.load_scene("slide")
    (bar,) = scene.indenters
    assert bar.shape == "bar" and bar.width == 1.0 and bar.friction == MU
    path = scene.history
    press_end = path.normal.ramp_time
    assert path(press_end) == 0.5 and path.tangential_at(press_end) == 0.0
    speed = (path.tangential_at(path.end_time) - path.tangential_at(press_end)) / (
        path.end_time - press_end)
    assert speed == pytest.approx(80.0)  # mm/s, the scene's stated scanning speed
    assert path.tangential_at(path.end_time) == pytest.approx(2.0)
    assert scene.outputs.receptors == "calibrated"
    assert any("check passed" in line for line in ft.check("slide"))
