"""Pictures of the fields at an output time, from the arrays a run gathers (rank 0 only).

u2 and the pore pressure on the deformed section near the load (cf. the paper's Fig. 4).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import plot_field


def field_pictures(arrays: dict, out: Path, t: float, scene, problem) -> None:
    """field_u2_t<t>s.png and, with a pore pressure, field_p_t<t>s.png in `out`."""
    half = scene.profile_half_width
    window = ((-half, half), (-float(np.max(arrays["X"][..., 1])) - 0.5, 0.0))
    pictures = [("u2", arrays["X"] + arrays["u"], arrays["u"][..., 1],
                 "vertical displacement u2 (mm)")]
    if "p" in arrays:
        pictures.append(("p", arrays["X_p"] + arrays["u_p"], arrays["p"], "pore pressure (MPa)"))
    for name, corners, values, label in pictures:
        corners, values = _triangles(corners, values)
        plot_field(corners, values, out / f"field_{name}_t{t:g}s.png", label,
                   title=f"{scene.name}: {name} at t = {t:g} s", window=window)


def _triangles(corners: np.ndarray, values: np.ndarray):
    """Quadrilaterals as two triangles each (DOLFINx's vertex order); triangles unchanged."""
    if corners.shape[1] == 4:
        corners = np.concatenate([corners[:, [0, 1, 3]], corners[:, [0, 3, 2]]])
        values = np.concatenate([values[:, [0, 1, 3]], values[:, [0, 3, 2]]])
    return corners, values
