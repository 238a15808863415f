"""Fit the fast path's geometry from the MJCF: ``python -m jaxarm.arm.fit [--degree D] [--out PATH]``.

Muscle-tendon lengths: least-squares bivariate polynomial of total degree D in the normalised joint angles, on a
grid that covers the joint ranges plus a 10 degree margin (the penalty limits let the arm overshoot a little). The
smallest degree whose worst error on a finer validation grid is below ``--tol-mm`` is kept (precedent: OpenSim's
polynomial path fitting, Rankin & Neptune 2012). Mass matrix: degree-2 trigonometric polynomial in the elbow angle,
exact for a two-hinge chain. Everything is computed with MuJoCo's C library in float64 and stored in
``jaxarm/arm/assets/fast_fit.npz`` (committed). The errors are printed and stored beside the coefficients.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from jaxarm.arm.geometry import (FIT_PATH, MJCF_PATH, c_geometry, file_sha256, load_mjmodel, poly_exponents,
                                  poly_features, tendon_names, trig_features)
from jaxarm.config.arm import ELBOW_RANGE_DEG, SHOULDER_RANGE_DEG

MARGIN_DEG = 10.0


def fit_range_rad() -> tuple[np.ndarray, np.ndarray]:
    lo = np.radians([SHOULDER_RANGE_DEG[0] - MARGIN_DEG, ELBOW_RANGE_DEG[0] - MARGIN_DEG])
    hi = np.radians([SHOULDER_RANGE_DEG[1] + MARGIN_DEG, ELBOW_RANGE_DEG[1] + MARGIN_DEG])
    return lo, hi


def sample_lengths(model, n: int):
    lo, hi = fit_range_rad()
    g0, g1 = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n), indexing="ij")
    q = np.stack([g0.ravel(), g1.ravel()], axis=1)
    lengths = np.stack([c_geometry(model, qi).mtu_length_m for qi in q])
    return q, lengths


def fit(mjcf: Path = MJCF_PATH, degrees=range(3, 10), tol_mm: float = 0.1, grid: int = 41) -> dict:
    model = load_mjmodel(mjcf)
    lo, hi = fit_range_rad()
    center, halfwidth = (lo + hi) / 2, (hi - lo) / 2
    q_fit, l_fit = sample_lengths(model, grid)
    q_val, l_val = sample_lengths(model, 2 * grid - 1)  # includes every midpoint between fitting nodes
    chosen = None
    for degree in degrees:
        exps = poly_exponents(degree)
        coef, *_ = np.linalg.lstsq(poly_features((q_fit - center) / halfwidth, exps), l_fit, rcond=None)
        err = np.abs(poly_features((q_val - center) / halfwidth, exps) @ coef - l_val)
        chosen = dict(degree=degree, exponents=exps, length_coef=coef, max_err_m=err.max(axis=0))
        if err.max() * 1e3 < tol_mm:
            break
    q2 = np.linspace(-math.pi, math.pi, 73)
    masses = np.stack([c_geometry(model, np.array([0.0, a])).mass_matrix for a in q2])
    targets = np.stack([masses[:, 0, 0], masses[:, 0, 1], masses[:, 1, 1]], axis=1)
    mass_coef, *_ = np.linalg.lstsq(trig_features(q2), targets, rcond=None)
    mass_err = np.abs(trig_features(q2) @ mass_coef - targets).max()
    return dict(mjcf_sha256=np.array(file_sha256(mjcf)), names=np.array(tendon_names(model)), exponents=chosen["exponents"], length_coef=chosen["length_coef"],
                q_center=center, q_halfwidth=halfwidth, mass_coef=mass_coef, degree=chosen["degree"],
                length_max_err_m=chosen["max_err_m"], mass_max_err=mass_err)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mjcf", type=Path, default=MJCF_PATH)
    ap.add_argument("--out", type=Path, default=FIT_PATH)
    ap.add_argument("--tol-mm", type=float, default=0.1, help="worst length error to accept, mm (default 0.1)")
    args = ap.parse_args(argv)
    result = fit(args.mjcf, tol_mm=args.tol_mm)
    np.savez(args.out, **result)
    report = {"degree": int(result["degree"]),
              "length_max_err_mm": {str(n): round(float(e) * 1e3, 4)
                                    for n, e in zip(result["names"], result["length_max_err_m"])},
              "mass_matrix_max_err_kg_m2": float(result["mass_max_err"])}
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
