"""The tissues of the four regions as data: one materials file (TOML) per parameter set.

A materials file has a table per region, each naming its law and giving its parameters:

    [skin]               model = "hyperfoam"; mu, alpha, nu         (+ optional [skin.prony])
    [subcutaneous]       model = "biphasic";  mu, alpha, nu, phi0   (+ [subcutaneous.permeability])
                                 (+ optional [subcutaneous.prony]: the solid's QLV)
    [subcutaneous.permeability]  law = "holmes-mow" (k0, kappa, M) | "constant" (k0)
    [bone], [nail]       model = "linear-elastic" (E, nu) | "rigid"

and each region table may give its mass `density` (N·s²/mm⁴: 1000 kg/m³ = 1e-9), which only
the dynamic analyses read (inertia); a quasi-static run ignores it, a dynamic one without it
stops with an error that names the table.

The built-in sets live in `fingertip_dolfinx/data/materials/` (`wu2004`: the paper's Table 1).
A scene names its set in `[materials] set = "..."` and may override any value in the same
tables (`[materials.subcutaneous.permeability] k0 = 1e-2`, or on the command line
`--set materials.subcutaneous.permeability.k0=1e-2`). Every value is validated by the law that
takes it; an error names the file, the table and the key.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..datafiles import find, read_toml
from ..errors import InputError
from ..validation import check_keys, positive
from .materials import (
    Biphasic,
    ConstantPermeability,
    HolmesMow,
    Hyperfoam,
    LinearElastic,
    Prony,
)

REGIONS = ("skin", "subcutaneous", "bone", "nail")
DEFAULT_SET = "wu2004"


@dataclass(frozen=True)
class Rigid:
    """A region held rigidly in place (bone or nail): its nodes are clamped, it has no law.

    Parameters
    ----------
    where : str, optional
        Where the choice came from, for messages.
    """

    where: str = "rigid"


@dataclass(frozen=True)
class Tissues:
    """The materials of the four regions (one materials set, e.g. ``wu2004``).

    Parameters
    ----------
    skin : Hyperfoam
        The skin's elastic law.
    skin_prony : Prony or None
        The skin's relaxation (quasi-linear viscoelasticity); None: elastic skin.
    subcutaneous : Biphasic
        The subcutaneous tissue: a hyperfoam solid, an inviscid fluid and a permeability law.
    bone, nail : LinearElastic or Rigid
        The distal phalanx and the nail.
    name : str, optional
        The set's name (its file name).
    subcutaneous_prony : Prony or None, optional
        The subcutaneous solid's relaxation (QLV on its hyperfoam stress); None: elastic solid.
    density : mapping of str to float, optional
        Mass density (N·s²/mm⁴; 1000 kg/m³ is 1e-9) by region; only dynamic runs read it.
    """

    skin: Hyperfoam
    skin_prony: Prony | None
    subcutaneous: Biphasic
    bone: LinearElastic | Rigid
    nail: LinearElastic | Rigid
    name: str = "custom"
    #: The subcutaneous solid's QLV relaxation (None: its hyperfoam stress is elastic).
    subcutaneous_prony: Prony | None = None
    #: Mass density of each region that has one (N·s²/mm⁴), by region name.
    density: Mapping[str, float] = dataclasses.field(default_factory=dict, hash=False)

    def densities(self, where: str = "materials") -> dict[str, float]:
        """The density of every region (N·s²/mm⁴): an error naming the table that lacks one.
        A rigid region needs none (its nodes are clamped)."""
        missing = [r for r in REGIONS if r not in self.density
                   and not isinstance(getattr(self, r), Rigid)]
        if missing:
            raise InputError(f"{where}: {', '.join(missing)}.density",
                             "a dynamic analysis needs the mass density of every deformable "
                             "region.", "add density = 1.0e-9 (N·s²/mm⁴, i.e. 1000 kg/m³) or "
                             "the tissue's own value to each table.")
        return {r: self.density.get(r, 0.0) for r in REGIONS}

    def rigid_regions(self) -> tuple[str, ...]:
        return tuple(r for r in ("bone", "nail") if isinstance(getattr(self, r), Rigid))

    def record(self) -> dict:
        """The whole parameter set as plain data, in the materials file's own format."""
        sub = self.subcutaneous
        skin = {"model": "hyperfoam", **_hyperfoam_record(self.skin)}
        if self.skin_prony is not None:
            skin["prony"] = _prony_record(self.skin_prony)
        record = {
            "name": self.name,
            "skin": skin,
            "subcutaneous": {"model": "biphasic", **_hyperfoam_record(sub.solid),
                             "phi0": sub.phi0, "permeability": _permeability_record(sub)},
            "bone": _solid_record(self.bone),
            "nail": _solid_record(self.nail),
        }
        if self.subcutaneous_prony is not None:
            record["subcutaneous"]["prony"] = _prony_record(self.subcutaneous_prony)
        for region, rho in self.density.items():
            record[region]["density"] = rho
        return record


# --- reading ----------------------------------------------------------------------------------


def load_materials(source: str | Path = DEFAULT_SET, overrides: Mapping | None = None) -> Tissues:
    """Read a materials set, with overrides merged over it.

    Parameters
    ----------
    source : str or Path, optional
        A built-in set's name (``"wu2004"``, ``"fast-relaxation"``) or a materials TOML file.
    overrides : mapping or None, optional
        Tables of the same form (``{"subcutaneous": {"permeability": {"k0": 1e-2}}}``), merged
        key by key.

    Returns
    -------
    Tissues
        The validated materials.

    Raises
    ------
    InputError
        For a missing file, an unknown key or an impossible value (named with its file and table).
    """
    path = find("materials", source, "materials set")
    data = merge(read_toml(path), overrides or {})
    data.setdefault("name", path.stem)
    return tissues_from_dict(data, where=str(path))


def tissues_from_dict(data: Mapping, where: str = "materials") -> Tissues:
    """Build and validate the four regions' materials from a materials file's tables."""
    check_keys(where, data, ("name", "description", *REGIONS), required=REGIONS, what="table")
    data, density = _densities(data, where)
    return Tissues(
        skin=_skin(data["skin"], f"{where}: skin"),
        skin_prony=_prony(data["skin"].get("prony"), f"{where}: skin.prony"),
        subcutaneous=_biphasic(data["subcutaneous"], f"{where}: subcutaneous"),
        subcutaneous_prony=_prony(data["subcutaneous"].get("prony"),
                                  f"{where}: subcutaneous.prony"),
        bone=_solid(data["bone"], f"{where}: bone"),
        nail=_solid(data["nail"], f"{where}: nail"),
        name=str(data.get("name", "custom")),
        density=density,
    )


def _densities(data: Mapping, where: str) -> tuple[dict, dict[str, float]]:
    """The region tables without their `density` keys, and the densities (validated)."""
    tables, density = dict(data), {}
    for region in REGIONS:
        table = tables[region]
        if isinstance(table, Mapping) and "density" in table:
            density[region] = positive(f"{where}: {region}.density", table["density"],
                                       "N·s²/mm⁴")
            tables[region] = {k: v for k, v in table.items() if k != "density"}
    return tables, density


def merge(base: Mapping, overrides: Mapping) -> dict:
    """`base` with the values of `overrides` put in, table by table (a deep merge).

    A table whose law changes (another `model` or `law`) is replaced, not merged: the old
    law's parameters would not fit the new one.
    """
    out = dict(base)
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping) and not any(
            k in value and value[k] != out[key].get(k) for k in ("model", "law")
        ):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def _model(data: Mapping, where: str, choices: tuple[str, ...]) -> str:
    if not isinstance(data, Mapping):
        raise InputError(where, f"must be a table, got {data!r}.", f"write [{where}].")
    model = data.get("model", choices[0])
    if model not in choices:
        raise InputError(f"{where}.model", f"unknown model {model!r}.",
                         f"use one of {', '.join(choices)}.")
    return model


def _hyperfoam(data: Mapping, where: str, extra: tuple[str, ...] = ()) -> Hyperfoam:
    """The hyperfoam parameters of a table (the keys in `extra` belong to the caller)."""
    params = {k: v for k, v in data.items() if k not in extra}
    return Hyperfoam.from_dict(params, where=where)


def _skin(data: Mapping, where: str) -> Hyperfoam:
    _model(data, where, ("hyperfoam",))
    return _hyperfoam(data, where, extra=("model", "prony"))


def _prony(data: Mapping | None, where: str) -> Prony | None:
    if data is None:
        return None
    return Prony.from_dict(data, where=where)


def _prony_record(prony: Prony) -> dict:
    return {"g": list(prony.g), "tau": list(prony.tau)}


def _biphasic(data: Mapping, where: str) -> Biphasic:
    _model(data, where, ("biphasic",))
    check_keys(where, data, ("model", "mu", "alpha", "nu", "phi0", "permeability", "prony"),
               required=("mu", "alpha", "nu", "phi0", "permeability"))
    solid = _hyperfoam(data, where, extra=("model", "phi0", "permeability", "prony"))
    permeability = _permeability(data["permeability"], data["phi0"], f"{where}.permeability")
    return Biphasic(solid, permeability, phi0=data["phi0"], where=where)


def _permeability(data: Mapping, phi0, where: str) -> HolmesMow | ConstantPermeability:
    if not isinstance(data, Mapping):
        raise InputError(where, f"must be a table, got {data!r}.", f"write [{where}].")
    law = data.get("law", "holmes-mow")
    params = {k: v for k, v in data.items() if k != "law"}
    if law == "holmes-mow":
        return HolmesMow.from_dict({**params, "phi0": phi0}, where=where)
    if law == "constant":
        return ConstantPermeability.from_dict(params, where=where)
    raise InputError(f"{where}.law", f"unknown permeability law {law!r}.",
                     "use holmes-mow or constant.")


def _solid(data: Mapping, where: str) -> LinearElastic | Rigid:
    model = _model(data, where, ("linear-elastic", "rigid"))
    params = {k: v for k, v in data.items() if k != "model"}
    if model == "rigid":
        if params:
            raise InputError(where, f"a rigid region takes no parameters, got {sorted(params)}.",
                             "remove them, or use model = \"linear-elastic\".")
        return Rigid(where=where)
    return LinearElastic.from_dict(params, where=where)


# --- recording ------------------------------------------------------------------------------


def _hyperfoam_record(h: Hyperfoam) -> dict:
    nu = h.nu if isinstance(h.nu, float) else list(h.nu)
    return {"mu": list(h.mu), "alpha": list(h.alpha), "nu": nu}


def _permeability_record(b: Biphasic) -> dict:
    k = b.permeability
    if isinstance(k, HolmesMow):
        return {"law": "holmes-mow", "k0": k.k0, "kappa": k.kappa, "M": k.M}
    return {"law": "constant", "k0": k.k0}


def _solid_record(m: LinearElastic | Rigid) -> dict:
    if isinstance(m, Rigid):
        return {"model": "rigid"}
    return {"model": "linear-elastic", **{f.name: getattr(m, f.name)
                                          for f in dataclasses.fields(m) if f.name != "where"}}


#: The paper's set (Wu et al. 2004, Table 1), read from the built-in file `wu2004`.
WU2004 = load_materials(DEFAULT_SET)
