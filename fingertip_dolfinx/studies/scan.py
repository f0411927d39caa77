"""A grating scanned along the finger (the `scan` scene): where its ridges are, and its forces
in its own frame.

The grating's plane may be tilted by θ about x (a finger's contact angle); it then moves along
its own plane, t = (0, sin θ, cos θ), with normal n = (0, cos θ, −sin θ). These helpers turn a
run's records into what the ridges do: the phase of the ridges' passage over a receptor site
(for the vector strength of spikes, `studies.signals.vector_strength`), the forces along n and
t, and the friction's share of Coulomb's bound. Used by the scan's test and its benchmark figure.
"""

from __future__ import annotations

import numpy as np


def ridge_frequency(scene) -> tuple[float, float, float]:
    """(start of the scan (s), speed along the plane (mm/s), speed/period (Hz))."""
    path, grating = scene.history, scene.indenters[0]
    start, end = path.normal.ramp_time, path.end_time
    speed = (path.tangential_at(end) - path.tangential_at(start)) / (end - start)
    return start, speed, speed / grating.period


def pivot_height(scene) -> float:
    """y_tip of a tilted grating pressed home: its plane, through (y_tip, centre_z), tangent
    to the cap (a circle of radius b = tip_length in the (y, z) plane) at
    (−b cos θ, L + b sin θ), then pressed the protocol's depth along y. Taken from the
    undeformed cap's geometry, not the mesh (an error of the order of the mesh's chord)."""
    grating, section = scene.indenters[0], scene.section
    theta, b = np.radians(grating.tilt), section.outer.b
    touch = -b * np.cos(theta) - (section.cylinder_length + b * np.sin(theta)
                                  - grating.centre_z) * np.tan(theta)
    return touch + scene.history.deepest


def along_plane(scene, y, z) -> np.ndarray:
    """A point's distance along the grating's plane from the middle ridge's line (y_tip,
    centre_z) at the start: (z − centre_z) cos θ + (y − y_tip) sin θ (flat: z − centre_z)."""
    grating = scene.indenters[0]
    theta = np.radians(grating.tilt)
    return ((np.asarray(z, dtype=float) - grating.centre_z) * np.cos(theta)
            + (np.asarray(y, dtype=float) - pivot_height(scene)) * np.sin(theta))


def ridge_phases(scene, times, along) -> np.ndarray:
    """The phase (rad) of each event in the ridges' passage over its site (at `along` on the
    plane, `along_plane`): 0 when a ridge's centre line is over it, 2π a period later."""
    travel = np.array([scene.history.tangential_at(t) for t in times])
    return 2 * np.pi * (travel - np.asarray(along)) / scene.indenters[0].period


def in_plane_frame(h: dict, tilt: float) -> dict:
    """history.csv's forces in the grating's frame, rotated by the tilt θ about x: along its
    normal n and its direction of travel t, under the flat grating's names (force_N: F_n,
    tangential_z_force_N: F_t, and the pressure's parts): flat, the same."""
    c, s = np.cos(np.radians(tilt)), np.sin(np.radians(tilt))
    out = dict(h)
    for normal, along in (("force_N", "tangential_z_force_N"),
                          ("pressure_normal_force_N", "pressure_tangential_z_force_N")):
        out[normal] = h[normal] * c - h[along] * s
        out[along] = h[normal] * s + h[along] * c
    return out


def friction_share(h: dict, mu: float) -> np.ndarray:
    """(F_t − F_p,t)/(μ F_p,n) in the grating's frame (`in_plane_frame`): the friction's share
    of the force along the scan over μ times the pressure's normal force. The ridges run
    across the finger, so every normal n lies in the (y, z) plane (F_p,x = 0); in gross slip
    along the profile the friction traction is μp along the tangent R n, the same way
    everywhere, so F_f = μ R F_p: F_f,t = μ F_p,n and F_f,n = −μ F_p,t, whence
    F_p,n = F_n + μ F_p,t. The ratio is 1 in gross slip, below 1 where some of it sticks."""
    pz = h["pressure_tangential_z_force_N"]
    return (h["tangential_z_force_N"] - pz) / (mu * (h["force_N"] + mu * pz))
