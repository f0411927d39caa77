"""Ask for an accuracy, get it: refine the mesh where the key outputs need it and control the
time steps until the estimated error of every key output (`keys.KEYS`) is below a
tolerance.

The tolerance is split (`AdaptOptions.time_share`, 25 %): the mesh must reach tol_space =
tol (1 − time_share), the time stepping tol_time = tol time_share; the two estimates add.
Every level runs with the steps of `stepping.tolerance_steps(tol_time)` (error-controlled BDF2,
rtol and atol scaled with it); after the mesh loop, step 5 checks the time error.

The loop (`adapt`), level k = 0, 1, ...:

1. **Run** the scene on level k's mesh into `out/level-<k>/` (`runner.run_scene`). Level 0 is
   the scene's mesh with `min_size` multiplied by `AdaptOptions.coarsen` (2 by default: the
   loop places the fine cells itself); level k > 0 adds a size map (`mesh.SizeMap`, the file
   `section.mesh.size_map`) that can only refine the level-0 fields.
2. **Estimate** the error of every key output from the levels so far (`estimate`): Roache's
   grid convergence index E = Fs |f_k - f_(k-1)| / (r^p - 1) / |f_k| (P. J. Roache,
   *Verification and Validation in Computational Science and Engineering*, Hermosa 1998,
   ch. 5; I. B. Celik et al., "Procedure for estimation and reporting of uncertainty due to
   discretization in CFD applications", J. Fluids Eng. 130 (2008) 078001, for unequal ratios
   and the size of a region). With three levels that refined the output's region, p is the
   order observed from the three values and the two ratios, capped at the assumed order 2,
   and Fs = 1.25; an oscillating sequence, or an observed order below 0.5, falls back to
   p = 2 and Fs = 3. With two levels, p = 2 and Fs = 1.25: Roache's Fs = 3 is for an order
   nobody observed, but the accuracy study observed 2.0-2.2 on every key output of these
   scenes (3.1 for the line load's SED), and its check of this loop (`studies.accuracy`,
   the estimates against its Richardson values) keeps that honest. The ratio r is measured,
   not requested: the area-weighted geometric mean of h_(k-1)/h_k over the output's region
   (`zones`: the pulp band out to the 3 mm deflections for forces and deflections, discs of
   0.3 mm around the depth-curve peak for e_max and for SED) on the two meshes themselves. A
   region left alone (its outputs already within safety * tol) keeps its estimate plus the
   change its outputs saw.
3. **Stop** when every estimate is <= tol_space (converged), or after `max_levels` runs, or when the
   next mesh would exceed `max_dofs` or the floor stops a region's refinement, saying which
   outputs missed and by how much.
4. **Indicate and size** the next mesh (`next_sizes`): the Zienkiewicz–Zhu indicator
   (O. C. Zienkiewicz, J. Z. Zhu, "A simple error estimator and adaptive procedure for
   practical engineering analysis", IJNME 24 (1987) 337–357): the L2 distance on each cell
   between the discontinuous log strain (DG1, what the run writes) and its continuous recovery
   (area-weighted nodal averaging within each region: strains jump across material interfaces,
   so averaging across them would flag the interfaces, not errors), the largest over the output
   times. Its density e_K = eta_K / sqrt(|K|) falls as h^2 for P2 displacements; averaged P1
   recovery of a P2 strain is not superconvergent, so it underestimates the error by a constant
   factor (0.29 on a smooth field, tests/test_adaptivity.py): it says where, the levels say how
   much. Each region whose outputs are not yet within safety * tol gets a ratio
   r = clip((E / (safety tol))^(1/p), 1.25, 2) from its largest estimate (level 0:
   `first_ratio`), and every cell in it is refined by r at least. Beyond that, ZZ's
   equidistribution (1987, Eq. 23, with the local order p): a cell whose density exceeds a
   target theta gets h_K (theta / e_K)^(1/p). For the pulp band (forces and deflections,
   functionals of the whole solution) theta = e_rms / r^p over the whole section, so that no
   density is left above what the total must reach; for a peak, theta = median(w e_K over its
   discs) / r^p with w = 1 in the discs and exp(-d / weight_length) at distance d. Sizes fall
   by at most 4 per level, never below `floor` (`default_floor`); a grading pass (Dijkstra
   over the cells: h_i <= h_j + g |x_i - x_j|, g = mesh.SIZE_GROWTH) keeps neighbours within
   30 % per mm, as the scene's own fields do. The map is handed to gmsh as a size callback
   that combines with the scene's fields by min (`mesh.build_mesh(..., size=)`).

5. **Check the time error** (`check_time`, `stepping.verify_time`): the finest mesh again with
   rtol and atol 4 times tighter (and more, up to `max_time_runs` runs), the time error of
   every key output estimated from the difference, E = 1.25 |f_k - f_(k-1)| / (r^a - 1) / |f|
   with a = 1/2 (the error's exponent in the tolerance, measured); the tightest run is the
   answer published.

Files: `out/level-<k>/` (a normal run each, plus `size_map.npz` for k > 0),
`out/level-<k>-time-<i>/` (the time check's runs), the answer's files copied to `out/`,
`out/adapt.json` (per level: cells, dofs, wall time, key outputs and the times they were read
at, estimates, ratios, the next level's plan; the time check's runs; the space, time and total
estimates; the mesh settled on;
the total cost) and an `adaptivity` table in `out/summary.json`. Under MPI the runs use every
rank; the indicator and the sizes are computed on rank 0 (2 ranks reproduce 1 rank's meshes
and values).
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import ConvergenceError, InputError, on_root
from ..geometry.mesh import SIZE_GROWTH, SizeMap
from ..keys import DEFLECTION_POINTS, KEY_OUTPUTS, KEYS, check_scene, key_outputs, read_key
from ..post import depth_curve
from ..stepping.tolerance import TIME_SHARE, tolerance_steps, verify_time

#: |x| (mm) of the farthest surface deflection among the key outputs.
DEFLECTION_REACH = max(DEFLECTION_POINTS)
#: Which region each key output's error comes from: the pulp under the indenters (forces and
#: surface deflections, energy-like outputs of the whole loaded zone) or the disc around the
#: depth-curve peak of its own field (point values: "e_max", "sed_MPa").
REGION_OF = {k.column: "load" if k.depth_mm is None else k.name for k in KEY_OUTPUTS}
FLOOR_DIVISOR = 16.0  # the default smallest size: level 0's min_size / this
#: A region refined by less than this (its cells at the floor) gives no estimate.
UNREFINED = 1.05
SAFETY_THREE_LEVELS = 1.25  # Roache's factor of safety with an observed order
SAFETY_TWO_LEVELS = 1.25  # two levels: the order the accuracy study observed (2.0-2.2)
SAFETY_OUT_OF_RANGE = 3.0  # three levels that oscillate or converge slower than h^0.5


@dataclass(frozen=True)
class AdaptOptions:
    """Settings of the adaptive loop (see the module docstring).

    Attributes
    ----------
    tol : float
        The relative error every key output must reach (estimated).
    max_levels : int
        Runs at most.
    coarsen : float
        Level 0's min_size is the scene's times this (1: the scene's own mesh).
    order : float
        The convergence order p assumed (P2: 2.0-2.2 measured by the accuracy study, the
        smaller taken) and the cap on an observed one.
    safety : float
        Aim at safety * tol, and leave a region alone once its outputs are within that.
    first_ratio : float
        The refinement of the output regions after level 0.
    min_ratio, max_ratio : float
        Bounds of a level's ratio there.
    peak_radius : float
        The disc (mm) around each depth-curve peak.
    load_margin : float
        The pulp band reaches this far (mm) beyond the 3 mm deflections (or each indenter's
        footprint), and this deep.
    weight_length : float
        Decay length (mm) of the indicator's weight outside the regions.
    floor : float
        The smallest size (mm; default `default_floor`).
    max_dofs : int
        Stop before a level would exceed this many unknowns (estimated).
    time_share : float
        The share of tol that goes to the time error (`stepping.TIME_SHARE`; the mesh gets
        tol (1 - time_share)); 0 leaves the scene's step control alone and refines the mesh
        to the whole tol (the time error then neither controlled nor estimated).
    max_time_runs : int
        Runs of the finest mesh at most in the time check (the first is its level).
    """

    tol: float = 0.01
    max_levels: int = 4
    coarsen: float = 2.0
    order: float = 2.0
    safety: float = 0.5
    first_ratio: float = 2.0
    min_ratio: float = 1.25
    max_ratio: float = 2.0
    peak_radius: float = 0.3
    load_margin: float = 1.0
    weight_length: float = 1.0
    floor: float | None = None
    max_dofs: int | None = None
    time_share: float = TIME_SHARE
    max_time_runs: int = 4

    def __post_init__(self):
        for key in ("tol", "coarsen", "order", "safety", "first_ratio", "min_ratio",
                    "max_ratio", "peak_radius", "load_margin", "weight_length"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                    math.isfinite(value) and value > 0):
                raise InputError(f"adaptivity: {key}", f"must be a positive number, got "
                                 f"{value!r}.", "give a number > 0.")
        if not self.tol < 1:
            raise InputError("adaptivity: tol", f"{self.tol} is a relative error of "
                             f"{self.tol:.0%}.", "give a fraction, e.g. 0.01 for 1 %.")
        if not (isinstance(self.max_levels, int) and self.max_levels >= 2):
            raise InputError("adaptivity: max_levels", f"got {self.max_levels!r}: an estimate "
                             "needs two levels.", "give an integer >= 2.")
        if self.coarsen < 1:
            raise InputError("adaptivity: coarsen", f"got {self.coarsen}.",
                             "give 1 (the scene's mesh) or more (a coarser start).")
        if not 1 < self.min_ratio <= self.max_ratio <= 4 or self.first_ratio <= 1:
            raise InputError("adaptivity: min_ratio, max_ratio, first_ratio",
                             f"got {self.min_ratio}, {self.max_ratio}, {self.first_ratio}.",
                             "use 1 < min_ratio <= max_ratio <= 4 and first_ratio > 1.")
        if self.safety > 1:
            raise InputError("adaptivity: safety", f"got {self.safety}.", "give (0, 1].")
        if isinstance(self.time_share, bool) or not (
                isinstance(self.time_share, int | float) and 0 <= self.time_share < 1):
            raise InputError("adaptivity: time_share", f"got {self.time_share!r}.",
                             "give a fraction in [0, 1), e.g. 0.25 (0: the mesh only).")
        if not (isinstance(self.max_time_runs, int) and self.max_time_runs >= 2):
            raise InputError("adaptivity: max_time_runs", f"got {self.max_time_runs!r}: a "
                             "time-error estimate needs two runs.", "give an integer >= 2.")

    @property
    def space_tol(self) -> float:
        """The mesh's share of tol."""
        return self.tol * (1.0 - self.time_share)

    @property
    def time_tol(self) -> float:
        """The time error's share of tol."""
        return self.tol * self.time_share


# --- the indicator ------------------------------------------------------------------------------

def vertex_ids(X: np.ndarray) -> np.ndarray:
    """Integer ids of the corners (cells, corners, 2): equal coordinates, equal id."""
    flat = np.asarray(X, dtype=float).reshape(-1, X.shape[-1])
    scale = max(float(np.abs(flat).max()), 1.0) * 1e-10
    _, ids = np.unique(np.round(flat / scale).astype(np.int64), axis=0, return_inverse=True)
    return ids.reshape(X.shape[:2])


def cell_areas(X: np.ndarray) -> np.ndarray:
    """Areas of triangles given by their corners (cells, 3, 2)."""
    a, b = X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]
    return 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def cell_sizes(X: np.ndarray) -> np.ndarray:
    """Each triangle's size: the edge of the equilateral triangle of its area (mm), gmsh's
    meaning of a target size."""
    return np.sqrt(4.0 * cell_areas(X) / math.sqrt(3.0))


def zz_indicator(X: np.ndarray, values: np.ndarray, region: np.ndarray | None = None,
                 ids: np.ndarray | None = None) -> np.ndarray:
    """The Zienkiewicz–Zhu indicator eta_K = || v_h - R v_h ||_L2(K) of a discontinuous P1 field.

    X (cells, 3, 2): the corners; values (cells, 3, m): the field's corner values (its DG1
    dofs, e.g. `FieldArrays`' log_strain); region (cells): cells of different regions do not
    share a recovered value. R v_h is the continuous P1 field whose vertex value is the
    area-weighted mean of the corner values of the cells (of that region) around the vertex.
    Both fields are linear on a cell, so the norm is exact:
    int_K |d|^2 = |K| / 12 (sum_i |d_i|^2 + |sum_i d_i|^2).
    """
    X = np.asarray(X, dtype=float)
    if X.ndim != 3 or X.shape[1] != 3:
        raise InputError("adaptivity", f"cells with {X.shape[1]} corners: the indicator is "
                         "written for triangles.", "mesh with triangles (quadrilateral = false).")
    values = np.asarray(values, dtype=float)
    values = values.reshape(*values.shape[:2], -1)
    ids = vertex_ids(X) if ids is None else ids
    if region is not None:  # a vertex on an interface is one vertex per region
        _, ids = np.unique(np.stack([ids, np.broadcast_to(np.asarray(region)[:, None],
                                                          ids.shape)], axis=-1).reshape(-1, 2),
                           axis=0, return_inverse=True)
        ids = ids.reshape(X.shape[:2])
    area = cell_areas(X)
    n = int(ids.max()) + 1
    weight = np.bincount(ids.ravel(), np.repeat(area, 3), minlength=n)
    recovered = np.stack([np.bincount(ids.ravel(), (area[:, None] * values[..., c]).ravel(),
                                      minlength=n) for c in range(values.shape[-1])], axis=-1)
    recovered /= weight[:, None]
    d = values - recovered[ids]
    square = np.sum(d**2, axis=(1, 2)) + np.sum(np.sum(d, axis=1) ** 2, axis=-1)
    return np.sqrt(np.maximum(area / 12.0 * square, 0.0))


# --- sizes --------------------------------------------------------------------------------------

def cell_neighbours(ids: np.ndarray) -> np.ndarray:
    """Pairs (i, j) of cells that share an edge (each pair once)."""
    n, corners = ids.shape
    edges = np.sort(np.stack([ids, np.roll(ids, -1, axis=1)], axis=-1), axis=-1).reshape(-1, 2)
    owner = np.repeat(np.arange(n), corners)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    same = np.all(edges[1:] == edges[:-1], axis=1)
    return np.column_stack([owner[:-1][same], owner[1:][same]])


def graded(sizes: np.ndarray, centroids: np.ndarray, pairs: np.ndarray,
           growth: float = SIZE_GROWTH) -> np.ndarray:
    """The largest sizes h' <= sizes with h'_i <= h'_j + growth * |x_i - x_j| along the cells'
    adjacency (the shortest path from a virtual source joined to cell j at h_j / growth)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    n = len(sizes)
    length = np.linalg.norm(centroids[pairs[:, 0]] - centroids[pairs[:, 1]], axis=1)
    rows = np.concatenate([pairs[:, 0], np.full(n, n)])
    cols = np.concatenate([pairs[:, 1], np.arange(n)])
    data = np.concatenate([np.maximum(length, 1e-12), sizes / growth])
    graph = coo_matrix((data, (rows, cols)), shape=(n + 1, n + 1)).tocsr()
    return growth * dijkstra(graph, directed=False, indices=n)[:n]


@dataclass(frozen=True)
class Zone:
    """Discs (centres (n, 2), radii (n,)) where some key outputs are read or caused."""

    centres: np.ndarray
    radii: np.ndarray

    def distance(self, x: np.ndarray) -> np.ndarray:
        """Distance from points (m, 2) to the union of the discs (0 inside)."""
        if not len(self.radii):
            return np.full(len(x), np.inf)
        d = np.linalg.norm(x[:, None, :] - self.centres[None, :, :], axis=-1) - self.radii
        return np.maximum(d.min(axis=1), 0.0)

    def cells(self, centroids: np.ndarray) -> np.ndarray:
        """The cells (a mask over their centroids) that stand for the zone: those whose
        centroid lies in its discs; a zone smaller than the cells around it, whose discs hold
        no centroid (0.3 mm peak discs in 1.5 mm cells), by the cells nearest to the discs'
        centres. Without that, such a zone was neither refined nor measured, and the loop
        stopped on an empty average (ZeroDivisionError)."""
        inside = self.distance(centroids) == 0.0
        if not inside.any() and len(self.radii) and len(centroids):
            gaps = np.linalg.norm(centroids[:, None, :] - self.centres[None, :, :], axis=-1)
            inside[np.unique(gaps.argmin(axis=0))] = True
        return inside


def next_sizes(h: np.ndarray, density: np.ndarray, area: np.ndarray, centroids: np.ndarray,
               pairs: np.ndarray, zones: dict[str, Zone], ratios: dict[str, float], *,
               order: float, weight_length: float, floor: float,
               growth: float = SIZE_GROWTH) -> np.ndarray:
    """Target sizes at the old cells (module docstring, step 4).

    "load" (forces, deflections: functionals of the whole solution): ZZ's equidistribution
    over the whole section, every cell's density brought down to theta = e_rms / r^p (so the
    indicator's total falls by r^p at least: every density ends <= theta), and the pulp band
    refined by r at least. A peak region: the same towards theta = median(w e_K over its
    discs) / r^p with the weight w decaying away from the discs, and the discs refined by r.
    """
    p = order
    targets = []
    for name, zone in zones.items():
        r = ratios[name]
        distance = zone.distance(centroids)
        if name == "load":
            weighted = density
            theta = math.sqrt(np.sum(density**2 * area) / np.sum(area)) / r**p
        else:
            weighted = np.exp(-distance / weight_length) * density
            inside = zone.cells(centroids)
            reference = np.median(weighted[inside]) if inside.any() else np.max(weighted)
            theta = reference / r**p
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(weighted > theta, (theta / weighted) ** (1.0 / p), 1.0)
        target = h * np.clip(factor, 0.25, 1.0)
        there = zone.cells(centroids)
        target[there] = np.minimum(target[there], h[there] / r)
        targets.append(target)
    target = np.min(targets, axis=0)
    # Never below the floor, even where gmsh made a cell smaller than asked (at a tip): a
    # size taken over from such a cell would shrink the tip disc level after level.
    target = np.maximum(target, floor)
    return graded(target, centroids, pairs, growth)


# --- estimates ----------------------------------------------------------------------------------

def observed_order(f: tuple[float, float, float], r21: float, r32: float) -> float:
    """The order p with f = f_inf + C h^p through three values f = (coarse, middle, fine) on
    sizes h3 = r32 h2, h2 = r21 h1: the root of r21^p (r32^p - 1) / (r21^p - 1) = e32 / e21
    (Celik et al. 2008, Eqs 3-5, for a monotone sequence): NaN for an oscillating one, 0 below
    0.05, inf above 10 (a change far smaller than the one before)."""
    from scipy.optimize import brentq

    e32, e21 = f[1] - f[0], f[2] - f[1]
    if e32 == 0 or e21 == 0 or e32 * e21 < 0:
        return math.nan
    target = e32 / e21

    def g(p):
        return r21**p * (r32**p - 1.0) / (r21**p - 1.0) - target

    lo, hi = 0.05, 10.0
    if g(lo) > 0:
        return 0.0
    if g(hi) < 0:
        return math.inf
    return brentq(g, lo, hi, xtol=1e-10)


def estimate(values: list[float], ratios: list[float], order: float) -> dict:
    """Estimated relative error of the finest of `values` (one output, coarse to fine;
    ratios[i]: h_i / h_{i+1}), after Roache's grid convergence index:
    E = Fs |f_k - f_{k-1}| / (r^p - 1) / |f_k|. With three values and an observed order p_obs
    in [0.5, inf): p = min(p_obs, order), Fs = 1.25; an oscillating sequence or p_obs < 0.5:
    p = order, Fs = 3; two values: p = order, Fs = 1.25 (module docstring)."""
    f1, f0, r = values[-1], values[-2], ratios[-1]
    scale = max(abs(f1), 1e-300)
    out = {"value": f1, "ratio": r, "observed_order": math.nan}
    if not (math.isfinite(r) and r >= UNREFINED):
        return out | {"error": math.inf, "order": order, "safety": math.nan,
                      "method": f"its region was not refined (ratio {r:.3g}): no estimate"}
    if abs(f1 - f0) <= 1e-12 * scale:
        return out | {"error": abs(f1 - f0) / scale, "order": order, "safety": 1.0,
                      "method": "unchanged to round-off"}
    p, fs, method = order, SAFETY_TWO_LEVELS, "two levels, assumed order"
    if len(values) >= 3:
        p_obs = observed_order(tuple(values[-3:]), ratios[-1], ratios[-2])
        out["observed_order"] = p_obs
        if math.isfinite(p_obs) and p_obs >= 0.5:
            p, fs = min(p_obs, order), SAFETY_THREE_LEVELS
            method = "three levels, observed order" + (" (capped)" if p_obs > order else "")
        else:
            fs = SAFETY_OUT_OF_RANGE
            method = ("three levels, oscillating or out of the asymptotic range: assumed order"
                      if not math.isfinite(p_obs) else "three levels, observed order < 0.5: "
                      "assumed order")
    error = fs * abs(f1 - f0) / (r**p - 1.0) / scale
    return out | {"error": error, "order": p, "safety": fs, "method": method,
                  "extrapolated": f1 + (f1 - f0) / (r**p - 1.0)}


def measured_ratio(old: dict, new: dict, zone: Zone) -> float:
    """The refinement ratio between two meshes in `zone`, measured: the area-weighted
    geometric mean of h_old / h_new over the new cells inside it (h_old: the size of the old
    cell nearest to each new centroid). Celik et al. (2008) take the representative size
    (area / cells)^(1/2) of a region; the geometric mean is the same for a uniform refinement
    and is not dominated by a few small cells (the tip disc of a wedge)."""
    from scipy.spatial import cKDTree

    inside = zone.cells(new["centroids"])
    if not inside.any():
        return math.nan
    _, nearest = cKDTree(old["centroids"]).query(new["centroids"][inside])
    logs = np.log(old["h"][nearest] / new["h"][inside])
    return float(np.exp(np.average(logs, weights=new["area"][inside])))


# --- one level's mesh, fields and zones ---------------------------------------------------------

def level_data(run_dir: Path, scene, options: AdaptOptions) -> dict:
    """What the loop needs from a finished run (rank 0): the cells (corners, areas, sizes,
    centroids, neighbours), the ZZ density (the largest over the output times) and the zones."""
    from ..result import Result

    result = Result(run_dir)
    times = sorted(result.output_times) or list(scene.output_times)
    density = None
    for t in times:
        fields = result.fields(t)
        X = fields["X"]
        if density is None:
            ids = vertex_ids(X)
            area = cell_areas(X)
        eta = zz_indicator(X, fields["log_strain"], fields["region"], ids=ids)
        d = eta / np.sqrt(area)
        density = d if density is None else np.maximum(density, d)
    return {"X": X, "area": area, "h": cell_sizes(X), "centroids": X.mean(axis=1),
            "pairs": cell_neighbours(ids), "density": density,
            "zones": zones(result, scene, options)}


def zones(result, scene, options: AdaptOptions) -> dict[str, Zone]:
    """The output regions of a run: "load", the band of depth load_margin under the pulp
    from the load to the deflections read farthest out (|x| <= 3 mm, or each indenter's
    half-width beyond its centre, + load_margin); "e_max" and "sed_MPa", discs of
    peak_radius around the depth-curve points (key depth, at the output time of the key
    output's largest value) within 10 % of the curve's peak (symmetric twins and flat peaks
    included)."""
    outer, o = scene.section.outer, scene.outputs
    reach = [abs(ind.centre_x) + _half_width(ind, outer) for ind in scene.indenters]
    half = min(max(DEFLECTION_REACH, *reach) + options.load_margin, 0.95 * outer.a)
    xs = np.linspace(-half, half, max(3, math.ceil(4 * half / options.load_margin) + 1))
    ys = outer.cy - outer.b * np.sqrt(np.clip(1 - (xs / outer.a) ** 2, 0.0, None))
    out = {"load": Zone(np.column_stack([xs, ys]), np.full(len(xs), options.load_margin))}
    d = result.depth
    for key in (k for k in KEY_OUTPUTS if k.depth_mm is not None):
        # the curve at the time the key output was read (its largest value over the run)
        _, t = read_key(key, d, float(np.max(d["time_s"])), f"{result.out}/depth_profiles.csv")
        rows = np.isclose(d["time_s"], t) & np.isclose(d["depth_mm"], key.depth_mm)
        xs, points = depth_curve(outer, key.depth_mm, o.profile_half_width, o.profile_points)
        q = d[key.name][rows]
        peak = np.nanmax(q)
        near = d["x_mm"][rows][q >= peak - 0.1 * abs(peak)]
        index = np.abs(xs[None, :] - near[:, None]).argmin(axis=1)
        out[key.name] = Zone(points[index], np.full(len(index), options.peak_radius))
    return out


def _half_width(indenter, outer) -> float:
    """Half the footprint of an indenter (mm): a bar's or wedge's base, a cylinder's radius;
    a plate presses the whole pulp."""
    if indenter.shape == "plate":
        return outer.a
    for attr, factor in (("width", 0.5), ("base", 0.5), ("radius", 1.0)):
        if hasattr(indenter, attr):
            return factor * float(getattr(indenter, attr))
    return 1.0


# --- the loop -----------------------------------------------------------------------------------

def default_floor(scene) -> float:
    """The smallest size the loop asks for: the scene's tip_size if it has tips, else level 0's
    min_size / 16 (a guard against refining a singular point, the edge of a contact zone,
    without end). At a sharp tip the contact is a penalty whose stiffness grows as 1/h
    (`contact.py`): refining the tip disc changes the contact law itself (with tip cells of
    ~9 µm instead of 20 µm the line load's wedge sank 1.4 µm less and every force and
    deflection rose by ~0.1 %), so the loop keeps the scene's tip_size, as the accuracy study
    does."""
    mesh = scene.section.mesh
    return mesh.tip_size if mesh.tips else mesh.min_size / FLOOR_DIVISOR


def start_scene(scene, options: AdaptOptions):
    """Level 0: the scene with min_size times `coarsen` (at most max_size) and no size map."""
    mesh = scene.section.mesh
    if mesh.quadrilateral:
        raise InputError("adaptivity: section.mesh.quadrilateral", "the loop refines "
                         "triangles only.", "mesh with triangles (quadrilateral = false).")
    coarse = dataclasses.replace(mesh, min_size=min(mesh.min_size * options.coarsen,
                                                    mesh.max_size), size_map="")
    return dataclasses.replace(scene, section=dataclasses.replace(scene.section, mesh=coarse))


def _with_size_map(scene, path: Path):
    mesh = dataclasses.replace(scene.section.mesh, size_map=str(path))
    return dataclasses.replace(scene, section=dataclasses.replace(scene.section, mesh=mesh))


def timed_scene(scene, options: AdaptOptions):
    """The scene with the steps of the time budget (`stepping.tolerance_steps`), or as it is
    (time_share 0). A dynamic scene has no error estimate for its scheme: refused."""
    if options.time_share == 0:
        return scene
    if scene.steps.scheme == "generalized-alpha":
        raise InputError(f"{scene.name}: steps.scheme", "a tolerance controls the time error "
                         "by error-controlled BDF2 steps, which have no error estimate for the "
                         "generalized-alpha scheme of a dynamic run.",
                         "set the accuracy in time by steps.steps_per_period and adapt the mesh "
                         "alone: ft.adapt(scene, out, ft.AdaptOptions(tol=..., time_share=0)).")
    steps = tolerance_steps(options.time_tol, scene.steps)
    return dataclasses.replace(scene, steps=steps)


def check_time(scene, final: dict, out: Path, options: AdaptOptions, say, comm) -> dict:
    """The time check of the finest mesh (`stepping.verify_time`): its level's run against runs
    with tolerances 4 (and more) times tighter, until every key output's estimated time error
    is within options.time_tol. Run i > 0 goes to `out/<level>-time-<i>/`; the last is the
    answer published. Returns adapt.json's `time` table."""
    from ..runner import run_scene

    dirs, summaries = [Path(final["run"])], []

    def run(steps, i: int) -> dict[str, float]:
        if i == 0:
            return final["values"]
        run_dir = out / f"{Path(final['run']).name}-time-{i}"
        say(f"time check {i}: the finest mesh at steps.rtol = {steps.rtol:.3g}")
        summaries.append(run_scene(dataclasses.replace(scene, steps=steps), run_dir,
                                   progress=False, comm=comm))
        dirs.append(run_dir)
        values = on_root(comm, lambda: key_outputs(run_dir))
        return {key: values[key] for key in KEYS} if values else None

    check = verify_time(run, scene.steps, options.time_tol, max_runs=options.max_time_runs)
    for entry, run_dir, summary in zip(check["runs"], dirs, [None, *summaries]):
        entry["run"] = str(run_dir)
        if summary is not None:
            entry.update(time_steps=summary["time_steps"], wall_time_s=summary["wall_time_s"])
    failed = check["runs"][-1].get("failed")
    say(f"time check: largest estimated time error {max(check['estimates'].values()):.3%} "
        f"after {len(check['runs'])} runs" + (f"; the last failed: {failed}" if failed else ""))
    return {"budget": options.time_tol, "converged": check["converged"],
            "estimated_time_errors": check["estimates"], "values": check["values"],
            "runs": check["runs"], "published": str(dirs[-1]),
            "method": ("key outputs of the finest mesh at steps.rtol and steps.atol divided by "
                       "4 (and more): E = 1.25 |f_fine - f_coarse| / (r^a - 1) / |f_fine|, "
                       "a = 1/2 (stepping.verify_time)")}


def adapt(scene, out: str | Path, options: AdaptOptions | None = None, *,
          progress: bool = True, comm: MPI.Comm | None = None) -> dict:
    """Run `scene` on adapted meshes into `out` until every key output's estimated relative
    error, the mesh's plus the time stepping's, is <= options.tol (module docstring). Returns
    adapt.json's content; `out` holds the answer's files as a normal run (summary.json with an
    `adaptivity` table): the finest mesh at the tightest step tolerances of the time check.

    Without `options`: tol and max_levels from the scene's `[accuracy]` table (tol 0.01 if it
    has none). A level whose run fails raises `ConvergenceError` after the files are written.

        report = ft.adapt(ft.load_scene("line-load"), "results/ll", ft.AdaptOptions(tol=0.01))
        report["estimated_errors"], report["mesh"], report["cost"]
        ft.load_result("results/ll").depth_profile("sed_MPa", depth=0.75, t=1.0)
    """
    if options is None:
        options = AdaptOptions(tol=scene.accuracy.tol or 0.01,
                               max_levels=scene.accuracy.max_levels)
    comm = comm or MPI.COMM_WORLD
    check_scene(scene, f"{scene.name}: the adaptive loop (--tol)")
    out = Path(out)
    started, cpu = time.perf_counter(), time.process_time()
    base = timed_scene(start_scene(scene, options), options)
    say = _say(progress and comm.rank == 0)
    levels, level_scene, failure, stop = _mesh_levels(
        scene, base, out, dataclasses.replace(options, tol=options.space_tol), say, progress,
        comm)
    timing = None
    if levels and failure is None and options.time_share > 0:
        try:
            timing = check_time(level_scene, levels[-1], out, options, say, comm)
        except ConvergenceError as error:
            failure, stop = str(error), f"the time check failed: {error}"
    report = _report(levels, options, stop, failure, started, cpu, comm, scene, timing)
    if levels:
        _publish(out, timing["published"] if timing else levels[-1]["run"], report, comm)
    say(report["message"])
    if failure is not None:
        raise ConvergenceError(f"adaptive loop: {failure}")
    return report


def _mesh_levels(scene, base, out: Path, options: AdaptOptions, say, progress: bool,
                 comm: MPI.Comm) -> tuple[list[dict], object, str | None, str]:
    """The mesh loop, steps 1-4 of the module docstring, from level 0's scene `base`; options
    with tol = the mesh's share. Returns (the levels' records, the last level's scene, the
    failure or None, why the loop stopped)."""
    from ..runner import run_scene

    floor = options.floor or default_floor(base)
    levels, data = [], []
    level_scene = base
    for k in range(options.max_levels):
        run_dir = out / f"level-{k}"
        say(f"level {k}: running ({'the start mesh' if k == 0 else 'adapted mesh'})")
        t0 = time.perf_counter()
        try:
            summary = run_scene(level_scene, run_dir, progress=progress, comm=comm)
        except ConvergenceError as error:
            return levels, level_scene, str(error), f"level {k} failed: {error}"
        levels.append(_record_level(k, run_dir, summary, t0, scene, options, levels, data,
                                    comm))
        _say_level(say, levels[-1])
        stop = _converged_or_last(k, levels[-1], options)
        if stop:
            return levels, level_scene, None, stop
        plan = _plan_level(k, levels, data, options, floor, out, comm)
        levels[-1]["next"] = plan
        stop = _refinement_stopped(plan, options)
        if stop:
            return levels, level_scene, None, stop
        level_scene = _with_size_map(base, (out / f"level-{k + 1}" / "size_map.npz").resolve())
    return levels, level_scene, None, ""


def _record_level(k: int, run_dir: Path, summary: dict, t0: float, scene, options: AdaptOptions,
                  levels: list, data: list, comm: MPI.Comm) -> dict:
    """Level k's record (`_level_record`, with its estimates for k > 0), made on rank 0 (which
    appends the level's `level_data` to `data`) and sent to every rank."""

    def record() -> dict:
        data.append(level_data(run_dir, scene, options))
        made = _level_record(k, run_dir, summary, time.perf_counter() - t0, data)
        if k > 0:
            made["estimates"] = _estimates(levels, made, options)
        return made

    return on_root(comm, record)


def _say_level(say, record: dict) -> None:
    """The progress line of a finished level: its size, cost and largest estimate."""
    if record["level"] == 0:
        say(f"level 0: {record['cells']} cells, {record['dofs']} dofs, "
            f"{record['wall_time_s']:.1f} s; no estimate from one level")
        return
    worst = max(KEYS, key=lambda key: record["estimates"][key]["error"])
    say(f"level {record['level']}: {record['cells']} cells, {record['dofs']} dofs, "
        f"{record['wall_time_s']:.1f} s; largest estimated error "
        f"{record['estimates'][worst]['error']:.3%} ({worst})")


def _converged_or_last(k: int, record: dict, options: AdaptOptions) -> str:
    """Why the loop stops after level k: every estimate within tol, or the last level; "" to
    go on."""
    if k > 0 and all(record["estimates"][key]["error"] <= options.tol for key in KEYS):
        return f"every key output within {options.tol:.3g} (estimated)"
    if k + 1 == options.max_levels:
        return f"max_levels = {options.max_levels} reached"
    return ""


def _plan_level(k: int, levels: list, data: list, options: AdaptOptions, floor: float,
                out: Path, comm: MPI.Comm) -> dict:
    """Level k + 1's plan (`_plan_next`), made on rank 0, which writes its size map to
    out/level-<k+1>/size_map.npz; every rank gets the plan (without the sizes)."""

    def plan() -> dict:
        made = _plan_next(k, levels, data, options, floor)
        (out / f"level-{k + 1}").mkdir(parents=True, exist_ok=True)
        SizeMap(data[-1]["centroids"], made.pop("sizes")).save(
            out / f"level-{k + 1}" / "size_map.npz")
        return made

    return on_root(comm, plan)


def _refinement_stopped(plan: dict, options: AdaptOptions) -> str:
    """Why the planned level is not run: the floor blocks a region, or it would exceed
    max_dofs; "" to run it."""
    if plan["blocked"]:
        return (f"the floor ({plan['floor_mm']:.3g} mm) stops the refinement of the "
                f"{', '.join(plan['blocked'])} region(s): lower AdaptOptions.floor")
    if options.max_dofs and plan["predicted_dofs"] > options.max_dofs:
        return (f"the next level would have ~{plan['predicted_dofs']} dofs > max_dofs = "
                f"{options.max_dofs}")
    return ""


def _say(active: bool):
    def say(text: str) -> None:
        if active:
            print(f"[adapt] {text}", flush=True)
    return say


def _estimates(levels: list, record: dict, options: AdaptOptions) -> dict:
    """Every key output's estimate at the level of `record`, the earlier levels in `levels`.

    An output whose region was kept (not refined: its outputs were already well within tol)
    keeps its previous estimate plus the change since: E_k = E_(k-1) + |f_k - f_(k-1)| / |f_k|.
    Otherwise the grid convergence index over the last levels that refined its region."""
    out = {}
    kept = levels[-1].get("next", {}).get("kept", [])
    for key in KEYS:
        f1, f0 = record["values"][key], levels[-1]["values"][key]
        if REGION_OF[key] in kept:
            before = levels[-1]["estimates"][key]["error"]
            out[key] = {"value": f1, "ratio": record["ratios"][key], "observed_order": math.nan,
                        "error": before + abs(f1 - f0) / max(abs(f1), 1e-300),
                        "order": math.nan, "safety": math.nan,
                        "method": "region kept: the previous estimate plus the change"}
            continue
        values, ratios = [f0, f1], [record["ratios"][key]]
        if len(levels) >= 2 and REGION_OF[key] not in levels[-2].get("next", {}).get("kept", []):
            values.insert(0, levels[-2]["values"][key])
            ratios.insert(0, levels[-1]["ratios"][key])
        out[key] = estimate(values, ratios, options.order)
    return out


def _level_record(k: int, run_dir: Path, summary: dict, elapsed: float, data: list) -> dict:
    new = data[-1]
    values = key_outputs(run_dir)
    ratios = {}
    if k > 0:
        for key in KEYS:
            ratios[key] = measured_ratio(data[-2], new, new["zones"][REGION_OF[key]])
    return {"level": k, "run": str(run_dir), "cells": summary["mesh"]["cells"],
            "dofs": summary["dofs"], "min_edge_mm": summary["mesh"]["min_edge_mm"],
            "max_edge_mm": summary["mesh"]["max_edge_mm"],
            "time_steps": summary["time_steps"], "newton_iterations":
            summary["newton_iterations"], "wall_time_s": summary["wall_time_s"],
            "elapsed_s": elapsed, "values": {key: values[key] for key in KEYS},
            "read_at_s": {key: values[f"{key}_t_s"] for key in KEYS},
            "ratios": ratios,
            "zones": {name: {"centres": z.centres.tolist(), "radii": z.radii.tolist()}
                      for name, z in new["zones"].items()}}


def _plan_next(k: int, levels: list, data: list, options: AdaptOptions, floor: float) -> dict:
    """The refinement ratio of every region and the target sizes of the next level."""
    now = levels[-1]
    ratios, why, kept = {}, {}, []
    for name in ("load", "e_max", "sed_MPa"):
        keys = [key for key in KEYS if REGION_OF[key] == name]
        if k == 0:
            ratios[name], why[name] = options.first_ratio, "first refinement"
            continue
        worst = max(now["estimates"][key]["error"] for key in keys)
        if worst <= options.safety * options.tol:
            kept.append(name)
            why[name] = (f"kept: largest estimate {worst:.3%} of {', '.join(keys)} is within "
                         f"safety * tol = {options.safety * options.tol:.3%}")
            continue
        want = (worst / (options.safety * options.tol)) ** (1.0 / options.order)
        ratios[name] = float(np.clip(want, options.min_ratio, options.max_ratio))
        why[name] = f"largest estimate {worst:.3%} of {', '.join(keys)}"
    d = data[-1]
    refine = {name: zone for name, zone in d["zones"].items() if name not in kept}
    sizes = next_sizes(d["h"], d["density"], d["area"], d["centroids"], d["pairs"], refine,
                       ratios,
                       order=options.order, weight_length=options.weight_length, floor=floor)
    growth = float(np.sum(d["area"] / sizes**2) / np.sum(d["area"] / d["h"] ** 2))
    planned, blocked = {}, []
    for name, zone in d["zones"].items():
        there = zone.cells(d["centroids"])
        planned[name] = float(np.exp(np.average(np.log(d["h"][there] / sizes[there]),
                                                weights=d["area"][there])))
        if name not in kept and planned[name] < 1.1:
            blocked.append(name)
    return {"ratios": ratios, "why": why, "kept": kept, "planned_ratios": planned,
            "blocked": blocked,
            "floor_mm": floor, "sizes": sizes,
            "predicted_cells": int(now["cells"] * growth),
            "predicted_dofs": int(now["dofs"] * growth),
            "smallest_size_mm": float(sizes.min())}


def _report(levels, options, stop, failure, started, cpu, comm, scene, timing=None) -> dict:
    """adapt.json's content. Per key output the estimated errors of the mesh (`space`), of the
    time stepping (`time`, None if not controlled) and their sum (`estimated_errors`, what is
    held against tol)."""
    final = levels[-1] if levels else None
    estimates = final.get("estimates") if final else None
    space = {key: estimates[key]["error"] for key in KEYS} if estimates else None
    times = timing["estimated_time_errors"] if timing else None
    total = ({key: space[key] + (times[key] if times else 0.0) for key in KEYS}
             if space else None)
    converged = bool(space) and failure is None and all(
        total[key] <= options.tol for key in KEYS) and (timing is None or timing["converged"])
    what = "space and time" if timing else "the mesh alone; time not controlled"
    if converged:
        message = (f"{scene.name}: every key output within {options.tol:.3g} (estimated; "
                   f"{what}) after {len(levels)} levels; the finest has {final['cells']} "
                   f"cells, {final['dofs']} dofs.")
    elif space:
        missed = [f"{key} {total[key]:.3%}" + (f" (space {space[key]:.3%}, time "
                                                f"{times[key]:.3%})" if times else "")
                  for key in KEYS if total[key] > options.tol]
        message = (f"{scene.name}: not converged to tol = {options.tol:.3g} ({stop}): "
                   f"estimated {', '.join(missed) or 'within tol, but the time check did not'}"
                   f"; the last level has {final['cells']} cells, {final['dofs']} dofs.")
    else:
        message = f"{scene.name}: no estimate ({stop})."
    walls = [lv["wall_time_s"] for lv in levels]
    checks = [r["wall_time_s"] for r in timing["runs"] if "wall_time_s" in r] if timing else []
    return {
        "scene": scene.name, "tol": options.tol, "tol_space": options.space_tol,
        "tol_time": options.time_tol if timing else None, "converged": converged,
        "stop": stop, "message": message, "failure": failure,
        "options": dataclasses.asdict(options),
        "estimated_errors": total, "estimated_space_errors": space,
        "estimated_time_errors": times,
        "values": timing["values"] if timing else (final["values"] if final else None),
        "time": ({k: v for k, v in timing.items() if k not in ("values",)} if timing else
                 {"controlled": False, "steps": "the scene's own (time_share = 0)"}),
        "mesh": ({"level": final["level"], "cells": final["cells"], "dofs": final["dofs"],
                  "min_edge_mm": final["min_edge_mm"], "max_edge_mm": final["max_edge_mm"],
                  "size_map": (str(Path(final["run"]) / "size_map.npz")
                               if final["level"] > 0 else None)} if final else None),
        "cost": {"levels": len(levels), "wall_time_s": float(sum(walls) + sum(checks)),
                 "final_level_wall_time_s": walls[-1] if walls else 0.0,
                 "time_check_wall_time_s": float(sum(checks)), "time_check_runs": len(checks),
                 "elapsed_s": time.perf_counter() - started,
                 "cpu_time_s": comm.allreduce(time.process_time() - cpu, op=MPI.SUM),
                 "mpi_ranks": comm.size},
        "levels": levels,
    }


def _publish(out: Path, run: str, report: dict, comm: MPI.Comm) -> None:
    """Copy the files of the answer's run (the finest level's, or its time check's last) to
    `out`; write adapt.json and summary.json's table."""
    if comm.rank == 0:
        source = Path(run)
        for item in source.iterdir():
            if item.name == "checkpoint":
                continue
            target = out / item.name
            if item.is_dir():
                shutil.copytree(item, target, dirs_exist_ok=True)
            else:
                shutil.copy2(item, target)
        (out / "adapt.json").write_text(json.dumps(report, indent=1, default=_plain) + "\n")
        summary = json.loads((source / "summary.json").read_text())
        summary["adaptivity"] = {k: report[k] for k in (
            "tol", "tol_space", "tol_time", "converged", "stop", "message", "estimated_errors",
            "estimated_space_errors", "estimated_time_errors", "mesh", "cost")}
        summary["adaptivity"]["levels"] = [
            {k: lv[k] for k in ("level", "cells", "dofs", "wall_time_s")} for lv in
            report["levels"]]
        (out / "summary.json").write_text(json.dumps(summary, indent=1, default=_plain) + "\n")
    comm.barrier()


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def read_adapt(out: str | Path) -> dict:
    """adapt.json of an adaptive run in `out`."""
    path = Path(out) / "adapt.json"
    if not path.is_file():
        raise InputError(str(out), "holds no adaptive run (no adapt.json).",
                         "give the --out directory of `fingertip run SCENE --tol TOL`.")
    return json.loads(path.read_text())
