r"""Receptor sites and afferent models, for the quasi-static runs (groundwork for vibrotactile
touch: the dynamics and the frequency response of the mechanics come later).

**Sites.** A receptor set (`data/receptors/*.toml`, built in: `default`) gives per class (SA1:
Merkel, RA: Meissner, PC: Pacinian) its depth below the undeformed outer surface, its
innervation density on the fingertip (per cm²) and the stimulus quantity its model reads. The
plane-strain section holds one row of each class along the pulp: sites spaced 1/sqrt(density)
apart in arc length along the undeformed outer surface (10/sqrt(ρ) mm for ρ per cm²; the
spacing of TouchSim's square grid), centred under x = 0, over |x| <= `sites.half_width`, each at
the class depth along the surface's inward normal (`post.depth_curve`). A row is a slice of the
areal population: it has the areal spacing, not the areal count.

**Sites in 3D** (`surface_sites`): over the pulp surface of the 3D fingertip, round(density ×
area) per class, uniformly at random (fixed seed) on the meshed facets, each at the class depth
below its facet along the facet's inward normal; a half model's afferents cover both halves,
those on the mirrored half read their mirror image.

**Spike files** (`write_spike_files`, at the end of a run): spikes.csv, afferents.csv and the
rate histories rates.npz from the run's receptors.csv.

**Stimulus quantities** (sampled at the sites at every accepted step, `receptors.csv`): strain
energy density (SED, MPa, the region's own elastic energy), the minimum principal log strain
(e_min: the largest compression), and the vertical Cauchy stress σ22 (MPa; total stress: the
law's σ22 minus the pore pressure where the tissue has one). A class reads one of

    sed                  SED                        MPa
    compressive_strain   −e_min                     1
    compressive_stress   −σ22                       MPa

(compression positive). Their rates are finite differences over the steps: for samples s_k at
t_k, ṡ = (s_k − s_{k−1}) / (t_k − t_{k−1}) on the step (t_{k−1}, t_k] (the exact derivative of the
piecewise-linear interpolant) and s̈ the same difference of ṡ (ṡ = 0 before the first step:
the run starts at rest). On a quasi-static run the rates are those of the load's ramp; they
carry no inertia or wave propagation.

**Transduction, two models.**

(a) SA1 rate proportional to SED, r = k · SED (spikes/s): the SED at the receptor site is the
candidate relevant stimulus of SA1 afferents of Srinivasan & Dandekar (1996, J Biomech Eng
118:48) and Dandekar, Raju & Srinivasan (2003, J Biomech Eng 125:682), whose 3-D model
predicted SA1 responses to shaped indenters. The linear form is this package's reading (only
the abstracts were checked); the gain k is an assumption (see the data file).

(b) A rectified-input leaky integrate-and-fire neuron, the form of Kim, Sripati & Bensmaia
(2010, J Neurophysiol 104:1484), Dong et al. (2013, J Neurophysiol 109:1350: the saturation)
and TouchSim (Saal et al. 2017, PNAS 114:E5693; read in its code, github.com/hsaal/touchsim,
`touchsim/transduction.py`):

    I = p1 [s]+ + p2 [s]− + p3 [ṡ]+ + p4 [ṡ]− + p5 [s̈]+ + p6 [s̈]−      ([x]− = max(−x, 0))
    J = p7 I / (p7 + |I|)          (saturation; p7 = 0: none, J = I)
    τ dv/dt = −v + J,   a spike when v reaches 1, then v = 0 held for the refractory period.

The current is formed at both ends of each step (the static terms from s at the step's start
and end, the rate terms from the step's own differences) and is linear in between ("linear"
hold), or held at its end value ("constant"). Over each piece the ODE is solved in closed form,
v(t) = J(t) − mτ + (v0 − J0 + mτ) e^{−(t−t0)/τ} for J = J0 + m (t − t0), and the threshold
crossing is the root of that expression (bracketed, to round-off): no time stepping. For a
constant J > 1 the rate is r = 1 / (t_ref + τ ln(J/(J − 1))), 0 for J <= 1.

TouchSim's neuron (membrane update per 0.2 ms sample, V ← V − V/τ_n + I_n) is the Euler form
of this one with τ = τ_n / 5 kHz and J = τ_n I_n; it adds a post-spike current and noise, left
out here, and lets V integrate (from 0) during its 1.2 ms without spikes, where v is held at 0
here. Its fitted parameter sets (17 afferents) were fitted to recordings *with its own
mechanics* (vertical stress of a Sneddon half-space, E = 50 kPa, plus a surface wave): they do
not carry over to this model's stresses without refitting against afferent recordings, which
this package does not have. The `default` set's parameters take TouchSim's time scales and the
form of its weights (which terms each class uses) and set every weight's scale by a stated
criterion, marked as an assumption in the data file.

(c) TouchSim's fitted afferents themselves, `model = "saal2017"` in a class (`SaalModel`; the
model is `afferents.transduction`): the site quantity is mapped to their input with one
calibrated scale per class (the `calibrated` set; scripts/calibrate_afferents.py), the rate
input with TouchSim's own factor κ. On a run, `afferent_responses` interpolates the steps'
samples onto the model's 5 kHz grid (`saal_spikes`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..datafiles import find, read_toml
from ..errors import InputError
from ..validation import check_keys, number, positive
from .transduction import (
    Afferents,
    load_afferents,
    model_depths,
    rate_factor,
    site_inputs,
    spike_times,
)

#: The stimulus quantities a class may read: column of receptors.csv, sign (compression > 0),
#: unit.
QUANTITIES = {
    "sed": ("sed_MPa", 1.0, "MPa"),
    "compressive_strain": ("e_min", -1.0, "1"),
    "compressive_stress": ("sigma22_MPa", -1.0, "MPa"),
}
CLASSES = ("SA1", "RA", "PC")
#: The columns of receptors.csv (one row per receptor per accepted step).
RECEPTOR_COLUMNS = ("time_s", "class", "index", "x_mm", "depth_mm", "sed_MPa", "e_min",
                    "sigma22_MPa", "p_MPa")
#: A 3D run's: the site's own reference position (x_mm, y_mm, z_mm; x < 0 on the mirrored half
#: of a half model) instead of the surface point's x.
RECEPTOR_COLUMNS_3D = (*RECEPTOR_COLUMNS[:4], "y_mm", "z_mm", *RECEPTOR_COLUMNS[4:])
WEIGHTS = ("s_pos", "s_neg", "ds_pos", "ds_neg", "dds_pos", "dds_neg")
HOLDS = ("linear", "constant")
DEFAULT_SET = "default"
#: Transduction models a class may use: this module's LIF (`[X.lif]`) or the fitted afferents
#: of Saal, Delhaye et al. 2017 (`[X.saal2017]`, afferents.transduction).
MODELS = ("lif", "saal2017")
#: TouchSim's default pin radius (mm; generators.stim_sine/stim_ramp), for κ (see SaalModel).
TOUCHSIM_PIN = 0.5


# --- the data --------------------------------------------------------------------------------


@dataclass(frozen=True)
class LIF:
    """A rectified-input leaky integrate-and-fire neuron (see the module's docstring).

    `tau` membrane time constant (s), `refractory` (s), `saturation` p7 (0: none), `weights`
    p1..p6 on [s]+, [s]−, [ṡ]+, [ṡ]−, [s̈]+, [s̈]− (units 1/[s], s/[s], s²/[s]).
    """

    tau: float
    refractory: float
    saturation: float = 0.0
    weights: tuple[float, ...] = (0.0,) * 6
    where: str = field(default="lif", compare=False, repr=False)

    def __post_init__(self):
        w = self.where
        object.__setattr__(self, "tau", positive(f"{w}.tau", self.tau, "s"))
        refractory = number(f"{w}.refractory", self.refractory)
        if refractory < 0:
            raise InputError(f"{w}.refractory", f"must be >= 0 s, got {refractory}.")
        object.__setattr__(self, "refractory", refractory)
        saturation = number(f"{w}.saturation", self.saturation)
        if saturation < 0:
            raise InputError(f"{w}.saturation", f"must be >= 0 (0: no saturation), got "
                             f"{saturation}.")
        object.__setattr__(self, "saturation", saturation)
        if len(self.weights) != 6:
            raise InputError(f"{w}.weights", f"needs 6 weights ({', '.join(WEIGHTS)}).")
        object.__setattr__(self, "weights", tuple(
            number(f"{w}.{k}", v) for k, v in zip(WEIGHTS, self.weights)))

    @classmethod
    def from_dict(cls, data: Mapping, where: str) -> LIF:
        check_keys(where, data, ("tau", "refractory", "saturation", *WEIGHTS),
                   required=("tau", "refractory"))
        return cls(tau=data["tau"], refractory=data["refractory"],
                   saturation=data.get("saturation", 0.0),
                   weights=tuple(data.get(k, 0.0) for k in WEIGHTS), where=where)

    def current(self, t, s, hold: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """The current J at the start and end of every step for samples s at times t."""
        return lif_current(t, s, self, hold)

    def spikes(self, t, s, hold: str = "linear") -> np.ndarray:
        """Spike times (s) for the stimulus samples s at times t (t[0]: at rest, v = 0)."""
        j0, j1 = self.current(t, s, hold)
        return lif_spikes(t, j0, j1, self.tau, self.refractory)

    def rate(self, current) -> np.ndarray:
        """Firing rate (spikes/s) for a constant current J, in closed form."""
        return constant_current_rate(current, self.tau, self.refractory)


@dataclass(frozen=True)
class SaalModel:
    """A class's use of the Saal et al. 2017 fits (afferents.transduction): which `fits` (rows
    of its class in the parameter file `source`), and the map from the site quantity s to the
    fits' inputs: static = α s, dynamic = α κ ṡ. α (`input_scale`) is the calibration (TouchSim's
    half-space stress per unit of s); κ is TouchSim's own ratio of dynamic input to stress rate
    under a pin of `pin_radius` at its depth for the class (`transduction.rate_factor`)."""

    fits: tuple[int, ...]
    input_scale: float
    pin_radius: float = TOUCHSIM_PIN
    source: str = "saal2017"

    def afferents(self, name: str) -> Afferents:
        return load_afferents(self.source, (name,), {name: list(self.fits)})

    def kappa(self, name: str) -> float:
        return rate_factor(model_depths(self.source)[name], self.pin_radius)

    def record(self) -> dict:
        return {"fits": list(self.fits), "input_scale": self.input_scale,
                "pin_radius": self.pin_radius, "source": self.source}

    @classmethod
    def from_dict(cls, name: str, data: Mapping, where: str) -> SaalModel:
        check_keys(where, data, ("fits", "input_scale", "pin_radius", "source"),
                   required=("input_scale",))
        source = str(data.get("source", "saal2017"))
        n = len(load_afferents(source, (name,)))
        fits = tuple(int(i) for i in data.get("fits", range(n)))
        if not fits or any(not 0 <= i < n for i in fits):
            raise InputError(f"{where}.fits", f"{list(fits)}: {source} has fits 0..{n - 1} of "
                             f"{name}.", "give a non-empty list of those indices.")
        return cls(fits, positive(f"{where}.input_scale", data["input_scale"], "per unit"),
                   positive(f"{where}.pin_radius", data.get("pin_radius", TOUCHSIM_PIN), "mm"),
                   source)


@dataclass(frozen=True)
class ReceptorClass:
    """One class: depth (mm), density (per cm²), the quantity its models read, its transduction
    `model` ("lif": `lif`; "saal2017": `saal`) and, optionally, the gain of the
    SED-proportional rate (spikes/s per MPa)."""

    name: str
    depth: float
    density: float
    quantity: str
    lif: LIF | None
    sed_gain: float | None = None
    description: str = ""
    model: str = "lif"
    saal: SaalModel | None = None

    @property
    def spacing(self) -> float:
        """Site spacing along the pulp (mm): 1/sqrt(density), density per cm² = per 100 mm²."""
        return 10.0 / math.sqrt(self.density)

    @property
    def unit(self) -> str:
        return QUANTITIES[self.quantity][2]


@dataclass(frozen=True)
class Sites:
    """The receptor sites of a population on one section: per site its class, index along
    the row (from −x to +x), the x of the surface point its normal starts from, depth (mm)
    and reference position (n, 2)."""

    cls: np.ndarray
    index: np.ndarray
    x: np.ndarray
    depth: np.ndarray
    points: np.ndarray
    #: Where the half model is sampled for each site (3D: a site on the mirrored half, x < 0,
    #: reads its mirror image (−x, y, z)); None: at `points`.
    sample_points: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.cls)


@dataclass(frozen=True)
class ReceptorPopulation:
    """Receptor classes and the half-width of the pulp their rows cover (a receptor set).

    Parameters
    ----------
    classes : tuple of ReceptorClass
        Each class (SA1, RA, PC): its depth, innervation density, stimulus quantity and models.
        ``population["RA"]`` gives one by name.
    half_width : float
        The rows of sites cover |x| <= this (mm) on the pulp.
    name, description : str, optional
        The set's name (its file name) and one line saying what it is.
    """

    classes: tuple[ReceptorClass, ...]
    half_width: float
    name: str = "custom"
    description: str = ""

    def __getitem__(self, name: str) -> ReceptorClass:
        for c in self.classes:
            if c.name == name:
                return c
        raise InputError(f"receptor class {name!r}", f"is not in the set {self.name!r}.",
                         f"use one of {', '.join(c.name for c in self.classes)}.")

    def sites(self, outer) -> Sites:
        """The sites on a section whose outer surface is the ellipse `outer`."""
        from ..post import depth_curve

        if not 0 < self.half_width < outer.a:
            raise InputError("receptors: sites.half_width", f"{self.half_width} mm must lie in "
                             f"(0, {outer.a}) (the section's half-width).")
        cls, index, xs, depth, points = [], [], [], [], []
        for c in self.classes:
            if c.depth >= outer.min_curvature_radius:
                raise InputError(f"receptors: {c.name}.depth", f"{c.depth} mm is not below the "
                                 f"outer surface's smallest radius of curvature "
                                 f"{outer.min_curvature_radius:.3f} mm: the normals would cross.")
            x = row_abscissae(outer, c.spacing, self.half_width)
            x0, p = depth_curve(outer, c.depth, self.half_width, len(x), x=x)
            cls += [c.name] * len(x)
            index.append(np.arange(len(x)))
            xs.append(x0)
            depth.append(np.full(len(x), c.depth))
            points.append(p)
        return Sites(np.array(cls), np.concatenate(index), np.concatenate(xs),
                     np.concatenate(depth), np.concatenate(points))

    def record(self) -> dict:
        """The set as plain data, in the data file's own tables (`receptors_from_dict` reads
        it back)."""
        def table(c: ReceptorClass) -> dict:
            models = {"model": c.model}
            if c.lif is not None:
                models["lif"] = {"tau": c.lif.tau, "refractory": c.lif.refractory,
                                 "saturation": c.lif.saturation,
                                 **dict(zip(WEIGHTS, c.lif.weights))}
            if c.saal is not None:
                models["saal2017"] = c.saal.record()
            gain = {} if c.sed_gain is None else {"sed_gain": c.sed_gain}
            return {"description": c.description, "depth": c.depth, "density": c.density,
                    "quantity": c.quantity, **gain, **models}

        return {"name": self.name, "description": self.description,
                "sites": {"half_width": self.half_width},
                **{c.name: table(c) for c in self.classes}}


#: The seed of the 3D populations' random site placement (TouchSim places afferents uniformly at
#: random over a region, `Surface.sample_uniform`): fixed, so a run's population is the same on
#: every run, rank count and resume.
SURFACE_SEED = 2017


def pulp_triangles(fm) -> tuple[np.ndarray, np.ndarray]:
    """(corners (n, 3, 3), unit outward normals (n, 3)) of every pulp-surface facet of a 3D
    mesh, gathered on every rank (each facet once: its owner's). The normal points away from
    the facet's cell. InputError if the mesh has no pulp surface."""
    from dolfinx.mesh import entities_to_geometry

    msh, fdim = fm.mesh, 2
    tag = fm.names.get("pulp_surface")
    facets = fm.facet_tags.find(tag) if tag is not None else np.zeros(0, dtype=np.int32)
    facets = facets[facets < msh.topology.index_map(fdim).size_local]
    msh.topology.create_connectivity(fdim, 3)
    x = msh.geometry.x
    corners = x[entities_to_geometry(msh, fdim, facets)][:, :3, :]
    f2c = msh.topology.connectivity(fdim, 3)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    centroid = x[entities_to_geometry(msh, 3, cells)].mean(axis=1) if len(cells) else corners[:, 0]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    outward = np.sign(np.einsum("ij,ij->i", normal, corners[:, 0] - centroid))
    corners = np.concatenate(msh.comm.allgather(corners)).reshape(-1, 3, 3)
    normal = np.concatenate(msh.comm.allgather(normal * outward[:, None])).reshape(-1, 3)
    # One order whatever the partition (the placement draws from it): corners sorted within
    # each facet, facets by their sorted corners.
    for k in range(len(corners)):
        corners[k] = corners[k][np.lexsort(corners[k].T[::-1])]
    order = np.lexsort(corners.reshape(-1, 9).T[::-1])
    corners, normal = corners[order], normal[order]
    if not len(corners):
        raise InputError("3D receptors: the mesh", "has no pulp surface (no facet tagged "
                         "pulp_surface): there is nowhere to place the afferents.",
                         "use a 3D section whose mesh tags its palmar skin (male-index-3d).")
    return corners, normal


def triangle_areas(corners: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1)


def surface_sites(population: ReceptorPopulation, fm, half: bool,
                  seed: int = SURFACE_SEED) -> Sites:
    """The sites of a 3D population over the pulp surface of the whole finger: per class
    round(density × pulp area) sites, uniformly at random over the (meshed) surface, each at
    the class depth below it along the facet's inward normal.

    A half model (`half`: its mesh holds x >= 0, the plane x = 0 a mirror) stands for the whole
    finger: the pulp area is twice the meshed one, each site lies on the meshed half or, with
    probability 1/2, on the mirrored half (x → −x); a site on the mirrored half is sampled at
    its mirror image (`Sites.sample_points`), exact for the scene the half model solves (one
    symmetric about x = 0)."""
    corners, normal = pulp_triangles(fm)
    area = triangle_areas(corners)
    total = (2.0 if half else 1.0) * area.sum() / 100.0  # cm²
    rng = np.random.default_rng(seed)
    cls, index, depth, points, sampled = [], [], [], [], []
    for c in population.classes:
        n = round(c.density * total)
        which = rng.choice(len(area), size=n, p=area / area.sum())
        r1, r2 = np.sqrt(rng.random(n)), rng.random(n)  # uniform on a triangle
        tri = corners[which]
        on = ((1 - r1)[:, None] * tri[:, 0] + (r1 * (1 - r2))[:, None] * tri[:, 1]
              + (r1 * r2)[:, None] * tri[:, 2])
        site = on - c.depth * normal[which]
        shown = site.copy()
        if half:
            shown[rng.random(n) < 0.5, 0] *= -1.0
            site[:, 0] = np.abs(site[:, 0])  # a normal at x = 0 may tip a site by round-off
        points.append(shown)
        sampled.append(site)
        cls += [c.name] * n
        index.append(np.arange(n))
        depth.append(np.full(n, c.depth))
    points = np.concatenate(points)
    return Sites(np.array(cls), np.concatenate(index), points[:, 0], np.concatenate(depth),
                 points, np.concatenate(sampled))


def row_abscissae(outer, spacing: float, half_width: float) -> np.ndarray:
    """x of the surface points spaced `spacing` apart in arc length along the palmar outer
    ellipse, one at x = 0, all within |x| <= half_width (ascending)."""
    a, b = outer.a, outer.b
    # Palmar arc: x = a cos u, y = cy + b sin u, u in (−π, 0); u = −π/2 at x = 0.
    u_edge = -math.acos(half_width / a)
    length = outer.arc_length(-math.pi / 2, u_edge)
    n = math.floor(length / spacing * (1 + 1e-12))
    u = []
    for k in range(1, n + 1):
        target, uk = k * spacing, -math.pi / 2 + k * spacing / a
        for _ in range(50):  # Newton on arc_length(−π/2, u) = target: ds/du = |P'(u)|
            step = (outer.arc_length(-math.pi / 2, uk) - target) / math.hypot(
                a * math.sin(uk), b * math.cos(uk))
            uk -= step
            if abs(step) < 1e-15:
                break
        u.append(uk)
    right = a * np.cos(np.array(u))
    return np.concatenate([-right[::-1], [0.0], right])


def load_receptors(source: str | Path = DEFAULT_SET,
                   overrides: Mapping | None = None) -> ReceptorPopulation:
    """Read a receptor set, with overrides merged over it.

    Parameters
    ----------
    source : str or Path, optional
        A built-in set's name (``"default"``) or a receptor TOML file.
    overrides : mapping or None, optional
        Tables of the same form, merged key by key.

    Returns
    -------
    ReceptorPopulation
        The validated receptor set.

    Raises
    ------
    InputError
        For a missing file, an unknown key or an impossible value.
    """
    from ..physics.tissues import merge

    path = find("receptors", source, "receptor set")
    data = merge(read_toml(path), overrides or {})
    data.setdefault("name", path.stem)
    return receptors_from_dict(data, where=str(path))


def receptors_from_dict(data: Mapping, where: str = "receptors") -> ReceptorPopulation:
    check_keys(where, data, ("name", "description", "sites", *CLASSES), required=("sites",),
               what="table")
    sites = data["sites"]
    check_keys(f"{where}: sites", sites, ("half_width",), required=("half_width",))
    half_width = positive(f"{where}: sites.half_width", sites["half_width"], "mm")
    classes = tuple(_receptor_class(name, data[name], f"{where}: {name}")
                    for name in CLASSES if name in data)
    if not classes:
        raise InputError(where, "has no receptor class.", f"add a table: {', '.join(CLASSES)}.")
    return ReceptorPopulation(classes, half_width, name=str(data.get("name", "custom")),
                              description=str(data.get("description", "")))


def _receptor_class(name: str, data: Mapping, where: str) -> ReceptorClass:
    check_keys(where, data, ("description", "depth", "density", "quantity", "sed_gain", "model",
                             "lif", "saal2017"), required=("depth", "density", "quantity"))
    quantity = data["quantity"]
    if quantity not in QUANTITIES:
        raise InputError(f"{where}.quantity", f"unknown quantity {quantity!r}.",
                         f"use one of {', '.join(QUANTITIES)}.")
    model = data.get("model", "lif")
    if model not in MODELS:
        raise InputError(f"{where}.model", f"unknown transduction model {model!r}.",
                         f"use one of {', '.join(MODELS)}.")
    if model not in data:
        raise InputError(where, f"uses model = {model!r} but has no [{name}.{model}] table.",
                         "add the table (see data/receptors/default.toml, calibrated.toml).")
    gain = data.get("sed_gain")
    if gain is not None:
        gain = positive(f"{where}.sed_gain", gain, "spikes/s per MPa")
    lif = LIF.from_dict(data["lif"], f"{where}.lif") if "lif" in data else None
    saal = (SaalModel.from_dict(name, data["saal2017"], f"{where}.saal2017")
            if "saal2017" in data else None)
    return ReceptorClass(
        name=name, depth=positive(f"{where}.depth", data["depth"], "mm"),
        density=positive(f"{where}.density", data["density"], "per cm²"), quantity=quantity,
        lif=lif, sed_gain=gain, description=str(data.get("description", "")), model=model,
        saal=saal)


# --- the stimulus and the transduction ------------------------------------------------------


def step_differences(t, s) -> tuple[np.ndarray, np.ndarray]:
    """(ṡ, s̈) on each step (t_{k−1}, t_k]: backward differences of the samples, at rest before
    the first (ṡ_0 = 0). Arrays of length len(t) − 1."""
    t, s = np.asarray(t, dtype=float), np.asarray(s, dtype=float)
    dt = np.diff(t)
    if len(t) < 2 or np.any(dt <= 0):
        raise InputError("stimulus times", "must increase, with at least two samples.")
    ds = np.diff(s) / dt
    dds = np.diff(np.concatenate([[0.0], ds])) / dt
    return ds, dds


def rectified_input(s, ds, dds, weights) -> np.ndarray:
    """I = p1 [s]+ + p2 [s]− + p3 [ṡ]+ + p4 [ṡ]− + p5 [s̈]+ + p6 [s̈]−."""
    p1, p2, p3, p4, p5, p6 = weights

    def pos_neg(x, wp, wn):
        x = np.asarray(x, dtype=float)
        return wp * np.maximum(x, 0.0) + wn * np.maximum(-x, 0.0)

    return pos_neg(s, p1, p2) + pos_neg(ds, p3, p4) + pos_neg(dds, p5, p6)


def saturate(current, saturation: float) -> np.ndarray:
    """p7 I / (p7 + |I|) (Dong et al. 2013; TouchSim), or I itself for p7 = 0."""
    current = np.asarray(current, dtype=float)
    if saturation == 0:
        return current
    return saturation * current / (saturation + np.abs(current))


def lif_current(t, s, lif: LIF, hold: str = "linear") -> tuple[np.ndarray, np.ndarray]:
    """The current at the start and at the end of every step (arrays of len(t) − 1)."""
    if hold not in HOLDS:
        raise InputError(f"hold {hold!r}", "is not a way to hold the current.",
                         f"use one of {HOLDS}.")
    s = np.asarray(s, dtype=float)
    ds, dds = step_differences(t, s)
    end = saturate(rectified_input(s[1:], ds, dds, lif.weights), lif.saturation)
    if hold == "constant":
        return end, end
    start = saturate(rectified_input(s[:-1], ds, dds, lif.weights), lif.saturation)
    return start, end


def constant_current_rate(current, tau: float, refractory: float) -> np.ndarray:
    """r = 1 / (t_ref + τ ln(J/(J − 1))) for J > 1, else 0 (spikes/s)."""
    j = np.asarray(current, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = 1.0 / (refractory + tau * np.log(j / (j - 1.0)))
    return np.where(j > 1.0, r, 0.0)


def lif_spikes(t, j_start, j_end, tau: float, refractory: float, v0: float = 0.0,
               threshold: float = 1.0) -> np.ndarray:
    """Spike times of τ dv/dt = −v + J(t), J linear on each step from j_start to j_end.

    Exact: the ODE is solved in closed form on every piece, the crossing of the threshold is
    found as the root of that closed form (to round-off), v = 0 is held for `refractory`
    after each spike. v0: the membrane at t[0] (below the threshold).
    """
    t = np.asarray(t, dtype=float)
    j_start, j_end = np.asarray(j_start, dtype=float), np.asarray(j_end, dtype=float)
    if not (len(j_start) == len(j_end) == len(t) - 1):
        raise InputError("lif_spikes", f"{len(t)} times need {len(t) - 1} currents per end.")
    if not v0 < threshold:
        raise InputError("lif_spikes: v0", f"{v0} must lie below the threshold {threshold}.")
    spikes, v, free = [], float(v0), t[0]  # free: the end of the refractory period
    for k in range(len(t) - 1):
        t0, t1 = t[k], t[k + 1]
        slope = (j_end[k] - j_start[k]) / (t1 - t0)
        now = t0
        while now < t1:
            if free > now:  # refractory: v held at 0
                if free >= t1:
                    v = 0.0
                    break
                now, v = free, 0.0
            j_now = j_start[k] + slope * (now - t0)
            s = _first_crossing(v, j_now, slope, tau, t1 - now, threshold)
            if s is None:
                h = t1 - now
                v = j_now + slope * (h - tau) + (v - j_now + slope * tau) * math.exp(-h / tau)
                break
            now += s
            spikes.append(now)
            v, free = 0.0, now + refractory
    return np.array(spikes)


def _first_crossing(v: float, j: float, m: float, tau: float, h: float,
                    threshold: float) -> float | None:
    """First s in (0, h] with v(s) = threshold for v(s) = j + m s − mτ + (v − j + mτ) e^{−s/τ},
    or None. f(s) = v(s) − threshold is convex or concave (one sign of its curvature), so it
    has at most one root before its maximum: bracket it, then solve to round-off."""
    c = v - j + m * tau

    def f(s):
        return j - m * tau - threshold + m * s + c * math.exp(-s / tau)

    if m == 0.0:  # constant current: the closed form
        if j <= threshold:
            return None
        s = tau * math.log((j - v) / (j - threshold))
        return s if s <= h else None
    if c > 0:  # convex: f(0) < 0, so at most one root, and f(h) >= 0 if it lies in (0, h]
        high = h
    else:  # concave: f rises to its maximum, then falls
        def df(s):
            return m - c / tau * math.exp(-s / tau)
        if df(0.0) <= 0:
            return None
        high = h if df(h) >= 0 else -tau * math.log(m * tau / c)
    if f(high) < 0:
        return None
    low = 0.0
    for _ in range(200):  # bisection to round-off (about 60 halvings)
        mid = 0.5 * (low + high)
        if mid <= low or mid >= high:
            break
        if f(mid) < 0:
            low = mid
        else:
            high = mid
    return high


# --- responses of a run ----------------------------------------------------------------------


@dataclass
class AfferentResponses:
    """The afferents of a run: per receptor (columns) and per sample time (rows, t = 0 at rest
    first).

    `stimulus`: the class's quantity (compression positive); `rate`: LIF spikes in each step
    divided by its length (rate[0] = 0); `mean_rate`: spikes over the whole run per second;
    `spikes`: the LIF spike times per receptor; `sed_rate`: the SED-proportional rate of the
    classes that have a gain (NaN elsewhere).
    """

    time: np.ndarray
    cls: np.ndarray
    index: np.ndarray
    x: np.ndarray
    depth: np.ndarray
    stimulus: np.ndarray
    spikes: list[np.ndarray]
    rate: np.ndarray
    mean_rate: np.ndarray
    sed_rate: np.ndarray

    def of(self, name: str) -> np.ndarray:
        """Column mask of one class."""
        return self.cls == name


def afferent_responses(result, population: ReceptorPopulation | str | None = None, *,
                       hold: str = "linear") -> AfferentResponses:
    """Rates and spike trains of every receptor of a run written with ``output.receptors``.

    The samples start at rest (zero stimulus at t = 0).

    Parameters
    ----------
    result : Result or str or Path
        A run's `Result`, or its directory.
    population : ReceptorPopulation or str or None, optional
        The receptor set whose models are applied (a set, or a set's name or path); None: the
        one the run sampled, as recorded in its receptors.json.
    hold : str, optional
        How the neuron's input current varies over a step: ``"linear"`` (between its values at
        the step's ends) or ``"constant"`` (held at its end value).

    Returns
    -------
    AfferentResponses
        Per receptor and sample time: the stimulus, the integrate-and-fire rate and spike times,
        and the SED-rate model's rate (classes with a gain).

    Raises
    ------
    InputError
        If the run wrote no receptors.csv.
    """
    if not hasattr(result, "receptors"):
        from ..result import Result

        result = Result(result)
    population = _population_of(result, population)
    table = result.receptors()
    times = np.unique(table["time_s"])
    if times[0] > 0:
        times = np.concatenate([[0.0], times])
    keys = sorted({(c, int(i)) for c, i in zip(table["class"], table["index"])},
                  key=lambda k: (CLASSES.index(k[0]) if k[0] in CLASSES else 99, k[1]))
    n_t, n_r = len(times), len(keys)
    stimulus, sed, x, depth = _site_samples(table, population, times, keys)
    spikes, rate = [], np.zeros((n_t, n_r))
    sed_rate = np.full((n_t, n_r), np.nan)
    fitted = _fitted_spikes(population, keys, times, np.nan_to_num(stimulus))
    for j, (name, _) in enumerate(keys):
        c = population[name]
        train = (fitted[j] if c.model == "saal2017" else
                 c.lif.spikes(times, np.nan_to_num(stimulus[:, j]), hold))
        spikes.append(train)
        counts = np.histogram(train, bins=times)[0] if len(train) else np.zeros(n_t - 1)
        rate[1:, j] = counts / np.diff(times)
        if c.sed_gain is not None:
            sed_rate[:, j] = c.sed_gain * np.maximum(sed[:, j], 0.0)
    duration = times[-1] - times[0]
    return AfferentResponses(
        time=times, cls=np.array([k[0] for k in keys]), index=np.array([k[1] for k in keys]),
        x=x, depth=depth, stimulus=stimulus, spikes=spikes, rate=rate,
        mean_rate=np.array([len(s) / duration for s in spikes]), sed_rate=sed_rate)


def _population_of(result, population) -> ReceptorPopulation:
    """The receptor set to apply: the one given (a set, a name or a path), else the one the
    run sampled (its receptors.json, or its scene's `output.receptors`)."""
    if isinstance(population, str | Path):
        return load_receptors(population)
    if population is not None:
        return population
    recorded = Path(result.out) / "receptors.json"
    if recorded.exists():
        return receptors_from_dict(json.loads(recorded.read_text()), str(recorded))
    return load_receptors(result.summary["scene_data"]["output"]["receptors"])


def _site_samples(table: dict, population: ReceptorPopulation, times: np.ndarray,
                  keys: list) -> tuple[np.ndarray, ...]:
    """receptors.csv's rows as arrays per (time, receptor): the stimulus each class reads
    (with its sign), the SED, and each receptor's x and depth."""
    n_t, n_r = len(times), len(keys)
    stimulus, sed = np.zeros((n_t, n_r)), np.zeros((n_t, n_r))
    x, depth = np.zeros(n_r), np.zeros(n_r)
    row_of_time = {float(t): k for k, t in enumerate(times)}
    column = {key: j for j, key in enumerate(keys)}
    for r in range(len(table["time_s"])):
        j = column[(table["class"][r], int(table["index"][r]))]
        k = row_of_time[float(table["time_s"][r])]
        name, sign, _ = QUANTITIES[population[table["class"][r]].quantity]
        stimulus[k, j] = sign * table[name][r]
        sed[k, j] = table["sed_MPa"][r]
        x[j], depth[j] = table["x_mm"][r], table["depth_mm"][r]
    return stimulus, sed, x, depth


# --- spike trains and rate histories of a run ----------------------------------------------

#: The columns of spikes.csv (one row per spike) and afferents.csv (one row per afferent) of a
#: run with receptors; `afferent` numbers the afferents of the run (0, 1, ...), `site` is the
#: index of the site along its class's row (receptors.csv's `index`); `fit`: the row of the
#: class's fits in the parameter file a saal2017 afferent uses, −1 for a model without fits.
SPIKE_COLUMNS = ("class", "afferent", "site", "time_s")
AFFERENT_COLUMNS = ("class", "afferent", "site", "model", "fit", "x_mm", "y_mm", "depth_mm",
                    "spikes", "mean_rate_per_s")
#: The rate histories' bins (rates.npz): 10 ms wide, wider on long runs (at most 1000 bins).
RATE_BIN_S = 0.01
MAX_RATE_BINS = 1000


def afferent_fit(c: ReceptorClass, index: int) -> int:
    """The fit (row of the class in the parameter file) the afferent at site `index` uses:
    the class's fits in turn along the row, as `saal_spikes`; −1 for a model without fits."""
    if c.model != "saal2017":
        return -1
    return c.saal.fits[index % len(c.saal.fits)]


def rate_bins(end: float, width: float = RATE_BIN_S, max_bins: int = MAX_RATE_BINS) -> np.ndarray:
    """Bin edges from 0 to `end` (s): `width` apart (wider if there would be more than
    `max_bins`), the last bin ending at `end` (shorter when `end` is not a whole number of
    widths)."""
    end = positive("rate bins: end", end, "s")
    width = max(width, end / max_bins)
    n = max(1, math.ceil(end / width - 1e-9))
    return np.append(np.arange(n) * width, end)


def rate_histories(responses: AfferentResponses, edges: np.ndarray | None = None) -> dict:
    """Per afferent (columns) the spikes counted in each time bin (rows; np.histogram's bins:
    [e_k, e_k+1), the last one closed) and the rate = count / bin width (spikes/s), as the
    arrays of rates.npz: `edges_s`, `counts`, `rate_per_s`, `afferent`, `class`, `site`."""
    edges = rate_bins(responses.time[-1]) if edges is None else np.asarray(edges, dtype=float)
    counts = np.zeros((len(edges) - 1, len(responses.spikes)), dtype=np.int64)
    for j, train in enumerate(responses.spikes):
        counts[:, j] = np.histogram(train, bins=edges)[0]
    return {"edges_s": edges, "counts": counts, "rate_per_s": counts / np.diff(edges)[:, None],
            "afferent": np.arange(len(responses.spikes)), "class": responses.cls,
            "site": responses.index}


def spike_tables(responses: AfferentResponses, population: ReceptorPopulation,
                 positions: Mapping) -> tuple[list[dict], list[dict]]:
    """(rows of afferents.csv, rows of spikes.csv) of a run's responses. `positions`: the
    reference position (x, y[, z]) of each site by (class, index)."""
    afferents, spikes = [], []
    duration = responses.time[-1] - responses.time[0]
    for j, (name, index) in enumerate(zip(responses.cls, responses.index)):
        c, index = population[name], int(index)
        position = positions[(name, index)]
        afferents.append({
            "class": name, "afferent": j, "site": index, "model": c.model,
            "fit": afferent_fit(c, index), **dict(zip(("x_mm", "y_mm", "z_mm"), position)),
            "depth_mm": responses.depth[j], "spikes": len(responses.spikes[j]),
            "mean_rate_per_s": len(responses.spikes[j]) / duration})
        spikes += [{"class": name, "afferent": j, "site": index, "time_s": float(t)}
                   for t in responses.spikes[j]]
    return afferents, spikes


def write_spike_files(out: Path, population: ReceptorPopulation, sites: Sites) -> dict | None:
    """spikes.csv, afferents.csv and rates.npz of the run in `out` (rank 0), each written
    whole, from its receptors.csv: every afferent's spike train over the run's steps. Returns
    afferents.csv's columns (for the population picture); None if no step was sampled."""
    from ..outputs import save_npz
    from ..result import Result

    result = Result(out)
    if not (Path(out) / "receptors.csv").exists() or not result.receptors():
        return None
    responses = afferent_responses(result, population)
    positions = {(c, int(i)): tuple(p) for c, i, p in zip(sites.cls, sites.index, sites.points)}
    afferents, spikes = spike_tables(responses, population, positions)
    columns = AFFERENT_COLUMNS if sites.points.shape[1] == 2 else (
        *AFFERENT_COLUMNS[:7], "z_mm", *AFFERENT_COLUMNS[7:])
    _write_rows(Path(out) / "afferents.csv", columns, afferents)
    _write_rows(Path(out) / "spikes.csv", SPIKE_COLUMNS, spikes)
    save_npz(Path(out) / "rates.npz", **rate_histories(responses))
    return {k: np.array([row[k] for row in afferents]) for k in columns}


def _write_rows(path: Path, columns, rows: list[dict]) -> None:
    """A whole CSV file; numbers to full precision (spike times read back exactly)."""
    import csv

    from ..outputs import whole

    def cell(v):
        return repr(float(v)) if isinstance(v, float | np.floating) else v

    with whole(path) as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows({k: cell(row[k]) for k in columns} for row in rows)


def _fitted_spikes(population: ReceptorPopulation, keys, t, stimulus) -> dict[int, np.ndarray]:
    """`saal_spikes` of every column j of `stimulus` whose class uses the fitted afferents,
    one vectorised call per class (3D populations have ~1000 sites): {j: spike times}."""
    out = {}
    for c in population.classes:
        if c.model != "saal2017":
            continue
        columns = [j for j, (name, _) in enumerate(keys) if name == c.name]
        if columns:
            trains = saal_spikes(c, [keys[j][1] for j in columns], t, stimulus[:, columns].T)
            out |= dict(zip(columns, trains))
    return out


def saal_spikes(c: ReceptorClass, index, t, s):
    """Spike times (s) of site `index` of a class using the Saal et al. 2017 fits: the site's
    fit is the class's fits in turn along the row (fits[index mod n], a deterministic mix as
    TouchSim's random choice per afferent); the samples s at times t (from rest) are
    interpolated linearly onto the model's 5 kHz grid (the run's steps carry no faster
    content) and mapped to its inputs (SaalModel). Several sites at once: `index` a list and
    s (n, T), a list of spike times back (one vectorised simulation)."""
    if np.ndim(index) == 0:
        return _saal_spikes(c, [int(index)], t, np.reshape(s, (1, -1)))[0]
    return _saal_spikes(c, list(index), t, np.asarray(s))


def _saal_spikes(c: ReceptorClass, index: list[int], t, s) -> list[np.ndarray]:
    """`saal_spikes` of the sites `index` (a list), samples s (n, T)."""
    aff = c.saal.afferents(c.name)
    aff = aff.take([i % len(aff) for i in index])
    grid = np.arange(int(math.floor(t[-1] * aff.fs)) + 1) / aff.fs
    sampled = np.array([np.interp(grid, t, row) for row in s])
    static, dynamic = site_inputs(sampled, aff.fs, c.saal.input_scale, c.saal.kappa(c.name))
    return spike_times(aff, static, dynamic)


def threshold_amplitude(lif: LIF, frequency: float, *, offset: float = 0.0, cycles: int = 4,
                        duration: float = 0.25, settle: int = 1, samples_per_cycle: int = 400,
                        hold: str = "linear", rtol: float = 1e-4) -> float:
    """The smallest amplitude A of s(t) = offset + A sin(2π f t) at which the neuron fires at
    least once after the first `settle` cycles (the switch-on, a step in ṡ, is an impulse in
    s̈): the transduction stage's threshold at one frequency, in the units of the class's
    quantity *at the receptor site*. (The indenter amplitude needs the mechanics' frequency
    response, which the quasi-static model does not have.) The stimulus lasts `cycles`
    cycles, or `duration` seconds if that is longer.

    This stage alone has no high-frequency roll-off: TouchSim low-passes its input first (a
    3rd-order Butterworth at 10 p0 Hz: SA1 88-102 Hz, RA 74-180 Hz, PC 275-370 Hz in its
    fits), which is left out here (the quasi-static runs have no such frequencies).

    The rates are the step differences of the samples, as for a run. Returns 0 if the offset
    alone fires, inf if no amplitude up to 1e12 times the first guess does. Bisection assumes
    the response grows with A (true for non-negative weights).
    """
    frequency = positive("threshold_amplitude: frequency", frequency, "Hz")
    if not 0 <= settle < cycles:
        raise InputError("threshold_amplitude: settle", f"{settle} cycles of {cycles}.",
                         "ignore fewer cycles than the stimulus has.")
    cycles = max(cycles, math.ceil(duration * frequency))
    t = np.linspace(0.0, cycles / frequency, cycles * samples_per_cycle + 1)
    wave = np.sin(2 * np.pi * frequency * t)
    start = settle / frequency

    def fires(amplitude: float) -> bool:
        return bool(np.any(lif.spikes(t, offset + amplitude * wave, hold) > start))

    if fires(0.0):
        return 0.0
    guess = 1.0 / max(max(abs(w) for w in lif.weights), 1e-300)
    low, high = 0.0, guess
    while not fires(high):
        low, high = high, 2.0 * high
        if high > 1e12 * guess:
            return math.inf
    while high - low > rtol * high:
        mid = 0.5 * (low + high)
        low, high = (low, mid) if fires(mid) else (mid, high)
    return high


# --- sampling in a run -----------------------------------------------------------------------


def pressure_sampling(problem, sampler, points: np.ndarray):
    """(sampler of the pore pressure at `points`, mask of the points in subcutaneous cells), or
    (None, None) if the problem has no pressure. The submesh's sampler also answers for points
    just outside the submesh (the closest cell): keep the pressure only where the mask is
    true. `sampler` samples the whole mesh at the same points (the mask is None on ranks that
    receive no samples)."""
    if problem.p is None:
        return None, None
    from dolfinx import fem  # here: reading receptor data needs no DOLFINx

    from ..post import PointSampler

    tags = problem.fmesh.cell_tags
    region = fem.Function(fem.functionspace(problem.mesh, ("DG", 0)))
    region.x.array[tags.indices] = tags.values
    inside = sampler(region)
    in_tissue = None if inside is None else np.isclose(inside[:, 0], problem.tags["subcutaneous"])
    return PointSampler(problem.submesh, points), in_tissue

class ReceptorRecorder:
    """Samples the stimulus quantities at a population's sites after every accepted step and
    writes receptors.csv, and the set itself to receptors.json (rank 0). Collective: every
    rank calls `write`.

    `problem`: the run's FingertipProblem, `derived`: its post.DerivedFields, `outer`: the
    section's outer ellipse; `resume_after`: keep the file's rows up to this time (--resume);
    `sites`: the sites (3D: `surface_sites`), else the section's rows on `outer`.
    """

    def __init__(self, problem, derived, population: ReceptorPopulation, outer, out: Path,
                 comm, resume_after: float | None = None, sites: Sites | None = None):

        from ..outputs import CsvLog
        from ..post import CauchyStress, PointSampler

        self.problem, self.derived, self.population = problem, derived, population
        self.sites = population.sites(outer) if sites is None else sites
        self.gdim = problem.mesh.geometry.dim
        at = self.sites.points if self.sites.sample_points is None else self.sites.sample_points
        self.sampler = PointSampler(problem.mesh, at)
        self.pressure, self.in_tissue = pressure_sampling(problem, self.sampler, at)
        laws = {problem.tags[name]: law for name, law in problem.laws.regions.items()}
        self.stress = CauchyStress(problem.u, problem.fmesh.cell_tags, laws,
                                   problem.options.quadrature_degree)
        columns = RECEPTOR_COLUMNS if self.gdim == 2 else RECEPTOR_COLUMNS_3D
        self.log = CsvLog(Path(out) / "receptors.csv", columns, comm, resume_after)
        self.comm = comm
        if comm.rank == 0:  # the set the run sampled, for afferent_responses
            (Path(out) / "receptors.json").write_text(
                json.dumps(population.record(), indent=2) + "\n")

    def write(self, t: float) -> None:
        rows = self.sample(t)
        if rows is not None:
            self.log.write(rows)

    def sample(self, t: float) -> list[dict] | None:
        """The rows of receptors.csv for the current state (rank 0; None elsewhere)."""
        self.derived.update()
        self.stress.update()
        sed = self.sampler(self.derived.sed)
        principal = self.sampler(self.derived.principal)
        sigma = self.sampler(self.stress.stress)
        p = self.pressure(self.problem.p) if self.pressure is not None else None
        if self.comm.rank != 0:
            return None
        p = (np.full(len(self.sites), np.nan) if p is None
             else np.where(self.in_tissue, p[:, 0], np.nan))
        d = self.gdim  # σ row by row: σ22 is component d + 1 (principal: max, min)
        total = sigma[:, d + 1] - np.nan_to_num(p)  # σ22 − p where there is a pore pressure
        s = self.sites
        where = [{} for _ in range(len(s))] if d == 2 else [
            {"y_mm": y, "z_mm": z} for y, z in s.points[:, 1:]]
        return [{"time_s": t, "class": s.cls[i], "index": int(s.index[i]), "x_mm": s.x[i],
                 **where[i], "depth_mm": s.depth[i], "sed_MPa": sed[i, 0],
                 "e_min": principal[i, 1], "sigma22_MPa": total[i], "p_MPa": p[i]}
                for i in range(len(s))]

    def close(self) -> None:
        self.log.close()

