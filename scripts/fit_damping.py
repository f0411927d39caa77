"""Fit the damped-fingerpad skin's and pulp's fast Prony terms to the fingerpad's damping target.

Reads scripts/data/fingerpad_damping.toml (what was found, with sources; the target is an
estimate: a constant loss tangent eta0 over 20-1000 Hz from the 81 % energy a tapping fingertip
dissipates), and fits weights g_i >= 0 of fast terms with fixed times tau_i (0.1-10 ms, two a
decade) so that the skin's complex modulus

    G*(w) = g_inf + sum_i g_i i w tau_i / (1 + i w tau_i) = 1 - sum_i g_i / (1 + i w tau_i)

matches A (i w / w_ref)^n, n = (2/pi) atan(eta0), over the band. The paper's slow terms (Wu
2004: 0.148 at 2.123 s, 0.252 at 9.371 s) are kept, scaled by (1 - S), S the fast terms' sum,
and every hyperfoam mu is scaled by 1/(1 - S): the stress at t >> 10 ms is then the paper's
(the construction of fast-relaxation.toml). The subcutaneous solid (the pulp) is fitted the same
way to the same target (the dissipation was measured on the whole pad, not on a layer): it has
no slow terms (the paper's solid is elastic), so its relaxed modulus mu (1 - S) x 1/(1 - S) is
the paper's mu. G* is linear in the g_i: for each amplitude A a non-negative least squares on
the relative complex error; A by a scan.

    PYTHONPATH=. python scripts/fit_damping.py [--figure PATH]

prints, for the skin and the pulp, the fit, its residual (the largest relative error of G* and
of the loss tangent over the band) and the TOML lines of data/materials/damped-fingerpad.toml;
--figure draws the skin's loss tangent and dynamic modulus, 1-1000 Hz, for the shipped sets
against the target.
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import nnls

DATA = Path(__file__).with_name("data") / "fingerpad_damping.toml"
FAST_TAU = tuple(float(t) for t in np.round(np.logspace(-4, -2, 5), 7))  # s: 0.1 ... 10 ms
PAPER_G, PAPER_TAU = (0.148, 0.252), (2.123, 9.371)  # Wu 2004 Table 1
PAPER_MU = (-7.594e-2, 1.138e-2, 6.572e-2)  # MPa, Wu 2004 Table 1
PAPER_SUB_MU = (-4.895e-2, 9.889e-3, 3.964e-2)  # MPa, Wu 2004 Table 1 (subcutaneous solid)
#: Per region: the paper's slow Prony terms (g, tau) kept under the fast ones, and its mu.
REGIONS = {"skin": ((PAPER_G, PAPER_TAU), PAPER_MU),
           "subcutaneous": (((), ()), PAPER_SUB_MU)}


def target(data: dict) -> tuple[np.ndarray, float]:
    """The band's frequencies (Hz) and the target loss tangent eta0 (see the data file)."""
    f0, f1 = data["target"]["band_Hz"]
    d = data["target"]["dissipated_fraction"]
    eta0 = d / (np.pi * (1 - d / 2))  # one tap: D = pi eta / (1 + pi eta / 2)
    return np.logspace(np.log10(f0), np.log10(f1), data["target"]["points"]), eta0


def modulus(g, tau, f) -> np.ndarray:
    """G*(2 pi f) of a Prony series g(t) = 1 - sum g_i (1 - exp(-t/tau_i))."""
    w = 2 * np.pi * np.asarray(f)[:, None]
    return 1 - np.sum(np.asarray(g) / (1 + 1j * w * np.asarray(tau)), axis=1)


def full_series(g_fast, slow=(PAPER_G, PAPER_TAU)) -> tuple[list[float], list[float]]:
    """The fast terms with the paper's slow terms (g, tau) scaled by (1 - S)."""
    scale = 1 - float(np.sum(g_fast))
    return [*g_fast, *(scale * g for g in slow[0])], [*FAST_TAU, *slow[1]]


def solve(f, eta0: float, amplitude: float, slow=(PAPER_G, PAPER_TAU)) -> np.ndarray:
    """Non-negative fast weights minimising |G* / T - 1| over f, T = A (i f / f_ref)^n.

    With the slow terms (1 - S) g_p / (1 + i w tau_p) ~ (1 - S) g_p (i w tau_p)^-1: their
    contribution is linear in the g_fast too (through S); it is kept exactly below."""
    n = 2 / np.pi * np.arctan(eta0)
    ref = np.sqrt(f[0] * f[-1])
    T = amplitude * (1j * f / ref) ** n
    w = 2 * np.pi * f[:, None]
    slow = np.sum(np.array(slow[0]) / (1 + 1j * w * np.array(slow[1])), axis=1)
    # G* = 1 - slow - sum_i g_i (1/(1 + i w tau_i) - slow)
    cols = (1 / (1 + 1j * w * np.array(FAST_TAU)) - slow[:, None]) / T[:, None]
    rhs = (1 - slow) / T - 1
    a = np.vstack([cols.real, cols.imag])
    b = np.concatenate([rhs.real, rhs.imag])
    g, _ = nnls(a, b)
    return g


def residuals(g_fast, f, eta0: float, slow=(PAPER_G, PAPER_TAU)) -> dict:
    """The fit's errors over the band: the loss tangent's largest absolute and relative error
    and the largest relative error of |G*| against the power law through its band mean."""
    g, tau = full_series(g_fast, slow)
    G = modulus(g, tau, f)
    loss = G.imag / G.real
    n = 2 / np.pi * np.arctan(eta0)
    law = np.abs(G) / (f / np.sqrt(f[0] * f[-1])) ** n
    return {"loss_min": loss.min(), "loss_max": loss.max(),
            "loss_rel": float(np.max(np.abs(loss / eta0 - 1))),
            "magnitude_rel": float(np.max(np.abs(law / np.exp(np.mean(np.log(law))) - 1)))}


def fit(data: dict, slow=(PAPER_G, PAPER_TAU)) -> tuple[np.ndarray, dict, float]:
    """The fast weights (rounded to 3 decimals, as shipped), their residuals and A."""
    f, eta0 = target(data)
    best = None
    for amplitude in np.linspace(0.05, 1.0, 381):
        g = solve(f, eta0, amplitude, slow)
        if np.sum(g) >= 0.95:  # keep g_inf >= 0.05 x the paper's: the mu scale <= 20
            continue
        r = residuals(g, f, eta0, slow)
        if best is None or r["loss_rel"] < best[1]["loss_rel"]:
            best = (g, r, amplitude)
    g = np.round(best[0], 3)
    return g, residuals(g, f, eta0, slow), best[2]


def plot(path: Path, eta0: float, band) -> None:
    """The skin's loss tangent and dynamic modulus |mu G*| / mu_paper of the built-in sets."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import ScalarFormatter

    from fingertip_dolfinx.physics.tissues import load_materials

    f = np.logspace(0, 3, 300)
    fig = Figure(figsize=(6.4, 5.6))
    top, bottom = fig.subplots(2, 1, sharex=True)
    lowest = eta0
    for name in ("wu2004", "fast-relaxation", "damped-fingerpad"):
        tissues = load_materials(name)
        prony = tissues.skin_prony
        G = modulus(prony.g, prony.tau, f)
        top.loglog(f, G.imag / G.real, lw=1.2, label=name)
        lowest = min(lowest, float(np.min(G.imag / G.real)))
        bottom.loglog(f, np.abs(G) * tissues.skin.mu[0] / PAPER_MU[0], lw=1.2)
    top.loglog(band, [eta0, eta0], "k--", lw=1, label=f"target {eta0:.3f} (estimate)")
    top.set_ylabel("skin loss tangent")
    top.set_ylim(lowest / 2, 2)  # every curve whole, the paper's nearly elastic skin too
    top.legend(fontsize=7, loc="lower left")
    bottom.set_ylabel("skin |μ G*| / μ (Wu 2004)")
    bottom.yaxis.set_major_formatter(ScalarFormatter())
    bottom.yaxis.set_minor_formatter(ScalarFormatter())
    bottom.set_xlabel("frequency (Hz)")
    for ax in (top, bottom):
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def report(region: str, data: dict) -> None:
    """Print one region's fit, its residuals and its TOML lines."""
    slow, paper_mu = REGIONS[region]
    f, eta0 = target(data)
    g_fast, r, amplitude = fit(data, slow)
    scale = 1 / (1 - float(np.sum(g_fast)))
    g, tau = full_series(g_fast, slow)
    print(f"== {region}: target loss tangent {eta0:.4f} over {f[0]:g}-{f[-1]:g} Hz "
          f"(|G*| ~ f^{2 / np.pi * np.arctan(eta0):.4f}); amplitude A = {amplitude:.3f}")
    print("fast terms: " + ", ".join(f"g = {gi:.3f} at {ti * 1e3:g} ms"
                                     for gi, ti in zip(g_fast, FAST_TAU)))
    print(f"sum of fast g: {np.sum(g_fast):.3f}; mu scale 1/(1 - S) = {scale:.6g}")
    print(f"loss tangent over the band: {r['loss_min']:.4f} .. {r['loss_max']:.4f} "
          f"(largest relative error {r['loss_rel']:.3f})")
    print(f"|G*| against the power law: largest relative error {r['magnitude_rel']:.3f}")
    G = modulus(g, tau, [1.0, 20.0, 100.0, 250.0, 1000.0])
    print("G* at 1, 20, 100, 250, 1000 Hz: " + ", ".join(f"{z:.3f}" for z in G))
    print(f"\n[{region}]\nmu = [" + ", ".join(f"{m * scale:.6g}" for m in paper_mu) + "]")
    print(f"[{region}.prony]\ng = [" + ", ".join(f"{x:.6g}" for x in g) + "]")
    print("tau = [" + ", ".join(f"{x:g}" for x in tau) + "]\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--figure", type=Path, help="draw the loss tangents to this PNG")
    args = parser.parse_args()
    data = tomllib.loads(DATA.read_text())
    for region in REGIONS:
        report(region, data)
    if args.figure:
        f, eta0 = target(data)
        plot(args.figure, eta0, [f[0], f[-1]])


if __name__ == "__main__":
    main()
