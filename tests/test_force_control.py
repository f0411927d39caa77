"""Force control: the indenters' normal force held at a target while they slide, their depth
found per step (force_control.py): the depth search on closed-form force laws, the bad inputs,
the scene record, and the coarse `shear` scene dragged under a held force."""

import math
import re

import numpy as np
import pytest

from fingertip_dolfinx.errors import ConvergenceError, InputError
from fingertip_dolfinx.force_control import MAX_SOLVES, DepthControl, NormalForce
from fingertip_dolfinx.loading import (
    PiecewiseLinear,
    RampHold,
    TangentialPath,
    check_tangential_path,
    history_from_dict,
)


def drive(target: NormalForce, force_of, times, depth=lambda t: 0.0):
    """Step a `DepthControl` through `times` as the stepper does (begin, solve and record until
    reached or out of solves, then advance), with the "solve" Fn = force_of(t, d); per step the
    (depth, force, solves, reached)."""
    clock = [0.0]
    control = DepthControl(target, depth, lambda: force_of(clock[0], depth(clock[0])),
                           lambda: clock[0])
    rows = []
    for t in times:
        clock[0] = t
        if control.active(t):
            control.begin(t)
            for _ in range(control.max_solves):
                if control.record(force_of(t, control.d_trial)):
                    break
            rows.append((control.d_trial, control.samples[-1][1], len(control.samples),
                         control.reached))
            if not control.reached:
                return control, rows
        control.advance()
    return control, rows


def pulp(t, d):
    """A Hertz-like pad, Fn = c(t) d^1.5 (N/mm, d in mm), stiffening by 50 % as the indenter
    slides (the slide scene's force grew ~30 % at constant depth)."""
    return 2e-3 * (1.0 + 5.0 * t) * max(d, 0.0) ** 1.5


def test_the_depth_search_holds_the_force_to_its_tolerance_in_few_solves():
    """Pressed to 1 mN/mm over 0.1 s in 10 steps from untouched, then held for 10 more while
    the pad stiffens: every step reaches |Fn − F*| <= rtol F* (and so the depth the exact
    root's to rtol/1.5, the law's d ∝ F^(2/3)); the predictor (the accepted depths
    extrapolated) makes the held steps cheap."""
    target = NormalForce((0.0, 0.1), (0.0, 1e-3), rtol=1e-4)
    times = np.round(np.arange(1, 21) * 0.01, 12)
    _, rows = drive(target, pulp, times, depth=lambda t: 0.5 * min(t / 0.1, 1.0))
    depth, force, solves, reached = map(np.array, zip(*rows))
    assert np.all(reached) and len(rows) == 20
    goal = np.array([target(t) for t in times])
    assert np.all(np.abs(force - goal) <= 1e-4 * goal)
    exact = (goal / (2e-3 * (1 + 5 * times))) ** (2 / 3)
    np.testing.assert_allclose(depth, exact, rtol=1e-4 / 1.5 * 1.01)
    # measured: 3-5 solves a step on the ramp, 2-3 in the hold (the pad stiffening 50 % over it)
    assert solves.max() <= 5 and solves[10:].max() <= 3


def test_a_kinked_force_law_is_bracketed_and_a_missed_tolerance_is_said():
    """A force law with a kink (the contact reaching a layer 100 times stiffer at d = 0.3 mm:
    the stiffness learnt below it overshoots) is solved inside the bracket in a few solves
    (measured 4); a force noisier than the tolerance is not reached, and the message says what
    was asked."""
    def layered(t, d):
        return 1e-3 * max(d, 0.0) + 0.1 * max(d - 0.3, 0.0)

    target = NormalForce((0.05,), (1.3e-3,), rtol=1e-6)  # d = 0.0313/0.101, past the kink
    _, rows = drive(target, layered, [0.05, 0.1], depth=lambda t: 0.5 * t)
    (depth, force, solves, reached), = rows
    assert reached and solves <= 5 and force == pytest.approx(1.3e-3, rel=1e-6)
    assert depth == pytest.approx(0.0313 / 0.101, rel=1e-6 * 1.3e-3 / 0.0313)

    def noisy(t, d):  # ±1e-4 relative noise on a smooth law
        return 1e-3 * d * (1 + 1e-4 * math.sin(1e7 * d))

    control, rows = drive(NormalForce((0.0, 0.1), (0.0, 5e-4), rtol=1e-7), noisy, [0.05])
    assert rows[-1][2] == MAX_SOLVES and not rows[-1][3]
    message = control.shortfall()
    assert "protocol.normal_force.rtol = 1e-07" in message and f"{MAX_SOLVES} solves" in message


@pytest.mark.parametrize("table, match", [
    ({"times": [0.0, 0.1], "values": [0.0, 0.0]}, "normal force <= 0"),
    ({"times": [0.1], "values": [-1e-3]}, "normal force <= 0"),
    ({"times": [0.1, 0.2], "values": [1e-3, 0.0]}, "normal force <= 0"),
    ({"times": [0.2, 0.1], "values": [1e-3, 1e-3]}, "increase strictly"),
    ({"times": [0.1], "values": [1e-3], "rtol": 0.0}, "relative tolerance"),
    ({"times": [0.1], "values": [1e-3], "rtol": 2.0}, "relative tolerance"),
    ({"times": [0.1], "values": [1e-3], "tol": 1e-3}, "tol"),
    ({"times": [0.1], "values": [1e-3, 2e-3]}, "one force"),
    ({"times": [1.5], "values": [1e-3]}, "not before the protocol's end"),
    ("1e-3", "times = "),
])
def test_bad_force_targets_are_refused(table, match):
    data = {"kind": "ramp-hold", "depth": 0.5, "ramp_time": 0.5, "end_time": 1.0,
            "tangential": {"times": [0.0, 0.5, 1.0], "values": [0.0, 0.0, 1.0]},
            "normal_force": table}
    with pytest.raises(InputError, match=match) as error:
        history_from_dict(data)
    assert "normal_force" in error.value.where


def test_force_control_needs_a_tangential_path_and_step_control_by_iterations():
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match="comes with a tangential path"):
        history_from_dict({"kind": "ramp-hold", "depth": 0.5, "ramp_time": 0.5,
                           "end_time": 1.0, "normal_force": {"times": [0.0], "values": [0.0]}})
    along_z = TangentialPath(RampHold(0.5, 0.5, 1.0), PiecewiseLinear((0.0, 1.0), (0.0, 1.0)),
                             (0.0, 1.0), NormalForce((0.5,), (1e-3,)))
    check_tangential_path(along_z, 3, True)  # 3D, a half model too (the target: the whole's)
    with pytest.raises(InputError, match='control = "iterations"'):
        load_scene("slide-force", ["steps.control=error"])


def test_the_slide_force_scene_records_its_target_and_other_scenes_their_old_record(tmp_path):
    from fingertip_dolfinx.outputs import check_resume
    from fingertip_dolfinx.scene import load_scene, scene_record

    scene = load_scene("slide-force")
    record = scene_record(scene)["protocol"]
    assert record["normal_force"] == {"times": [0.0, 0.1], "values": [0.0, 6.5e-4], "rtol": 1e-3}
    back = history_from_dict(record)
    assert back.normal_force == scene.history.normal_force
    # the force path's times are steps' landing points; a path without it is as it was
    assert 0.1 in scene.history.breakpoints
    assert "normal_force" not in scene_record(load_scene("slide"))["protocol"]
    # a resume with another target is another experiment
    other = scene_record(load_scene("slide-force", ["protocol.normal_force.rtol=1e-4"]))
    with pytest.raises(InputError, match="normal_force"):
        check_resume(scene_record(scene), other, 0.05, tmp_path)
    harder = scene_record(load_scene("slide-force", ["protocol.normal_force.values=[0.0, 7e-4]"]))
    with pytest.raises(InputError, match="normal_force"):
        check_resume(scene_record(scene), harder, 0.05, tmp_path)
    check_resume(scene_record(scene), scene_record(scene), 0.05, tmp_path)  # the same: allowed


#: The coarse shear scene pressed 0.5 mm in two steps, then dragged 0.2 mm in two with its
#: normal force held at 1 mN/mm (pressed: 0.966 mN/mm), no pictures.
HELD_SHEAR = ["protocol.end_time=0.7", "output.times=[0.5, 0.6, 0.7]", "output.pictures=false",
              "protocol.tangential={times = [0.0, 0.5, 0.7], values = [0.0, 0.0, 0.2]}",
              "steps.dt_initial=0.25", "steps.dt_max=0.25"]


@pytest.mark.parametrize("mu", [0.5, 0.0])
def test_the_shear_scene_dragged_under_a_held_force_keeps_it_to_the_tolerance(tmp_path, mu):
    """From 0.5 s on the depth is found per step: |Fn − F*| <= rtol F* at every step (the
    support's reaction agrees: equilibrium), history.csv's depth is the one found (deeper than
    the protocol's 0.5 mm: 1 mN/mm needs more), and the plate drags with friction. Without
    friction the force is held alike (the contact's force alone)."""
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    held = "protocol.normal_force={times = [0.5], values = [1.0e-3], rtol = 1e-4}"
    scene = load_scene("shear", [*HELD_SHEAR, held, f"indenters.0.friction={mu}"])
    run_scene(scene, tmp_path, progress=False)
    h = read_csv(tmp_path / "history.csv")
    on = h["time_s"] > 0.5 + 1e-9
    assert on.sum() >= 2 and np.all(h["normal_force_target_N_per_mm"][on] == 1e-3)
    force = h["force_N_per_mm"][on]
    assert np.all(np.abs(force - 1e-3) <= 1e-4 * 1e-3)
    np.testing.assert_allclose(h["reaction_N_per_mm"][on], force, rtol=1e-6)
    assert np.all(h["indenter_displacement_mm"][on] > 0.5 + 5e-3)
    assert np.all(np.isnan(h["normal_force_target_N_per_mm"][~on]))
    assert np.all(h["force_solves"][on] >= 1)
    assert h["tangential_force_N_per_mm"][-1] > 1e-5 if mu else "tangential_force_N_per_mm" not in h


def test_a_force_tolerance_that_cannot_be_met_stops_the_run_with_its_reason(tmp_path):
    """rtol = 1e-12 is below the force's own accuracy (Newton's residual tolerance): the step
    fails after its solves, and (no cuts allowed) the run stops saying so."""
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    held = "protocol.normal_force={times = [0.5], values = [1.0e-3], rtol = 1e-12}"
    scene = load_scene("shear", [*HELD_SHEAR, held, "steps.max_cuts=0"])
    with pytest.raises(ConvergenceError, match=r"normal_force.rtol = 1e-12 \(loosen it") as stop:
        run_scene(scene, tmp_path, progress=False)
    # the stop names the depths force control found (the protocol's stays at 0.5 mm): the
    # accepted one at 0.5 s, then the last one tried, the depth its reason reports
    message = str(stop.value)
    accepted, tried = (float(x) for x in re.search(
        r"\(depth (\S+) -> (\S+) mm, as found by force control\)", message).groups())
    reported = float(re.search(r"at depth (\S+) mm after", message).group(1))
    assert accepted == 0.5 and tried == pytest.approx(reported, rel=1e-5)
    assert tried > 0.5 + 5e-3  # 1 mN/mm needs 0.513 mm (the held-shear test above)
