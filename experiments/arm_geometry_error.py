"""How far the MJCF arm's muscle paths are from the authors' OpenSim paths, and where its hand is.

    python experiments/arm_geometry_error.py [--json] [--step-deg 2.5] [--mjcf jaxarm/arm/assets/arm.xml]

Compares, on a grid over the authors' joint ranges (shoulder -10..110 deg, elbow 0..140 deg; default 2.5-degree
steps, a finer grid than the 10-degree one the converter fits on):

* the committed MJCF (MuJoCo C: ``mj_kinematics`` + ``mj_tendon``; lengths ``ten_length``, moment arms
  ``-ten_J``) against the true OpenSim path (numpy, :mod:`jaxarm.arm.osim`: every active path point, conditional
  points only where active; moment arm = -dL/dq by central differences with the active set frozen, as OpenSim's);
* the same for the simplest alternative construction, keeping or dropping each conditional point (best subset
  per muscle on this grid), to show what the fitted sites buy;
* the MJCF's own sites against the osim polyline through the same points (exactness of the translation itself);
* moment-arm signs against the anatomy list in ``../shared/spec/arm/NOTES.md``: a muscle passes when its MJCF
  moment arm has the listed sign at the start posture (0.62, 1.53) rad and the true path's sign wherever the true
  moment arm is at least 1 mm (the true paths themselves deviate from the list at range ends: DELT1 extends above
  about 95 deg of shoulder flexion);
* the model's elbow (ulna origin) and hand (hand-body origin) against the authors' planar formula
  hand = L1 (cos q1, sin q1) + L2 (cos(q1 + q2), sin(q1 + q2)), L1 = 0.2904, L2 = 0.2535 m, in the shoulder's
  horizontal plane (authors' x = thorax z - shoulder z (lateral), y = thorax x - shoulder x (anterior)).

Needs the .osim under ``../shared``. Deterministic (no randomness).
"""
from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from jaxarm.arm import convert, osim  # noqa: E402
from jaxarm.config.arm import ARM_SEGMENTS_M, ELBOW_RANGE_DEG, SHOULDER_RANGE_DEG  # noqa: E402

#: The 18 muscles that receive excitation (spec section 8); the other 4 are passive.
DRIVEN = ("DELT1", "DELT2", "DELT3", "Infraspinatus", "Latissimus_dorsi_1", "Latissimus_dorsi_2",
          "Latissimus_dorsi_3", "Teres_minor", "PECM1", "PECM2", "PECM3", "Coracobrachialis", "TRIlong", "TRIlat",
          "TRImed", "BIClong", "BICshort", "BRA")
#: Anatomy (NOTES.md): +1 flexor (moment arm > 0), -1 extensor, 0 changes sign over the range.
SHOULDER_SIGN = {
    "PECM1": 1, "PECM2": 1, "PECM3": 1, "Coracobrachialis": 1, "DELT1": 1, "BICshort": 1,
    "DELT3": -1, "Infraspinatus": -1, "Latissimus_dorsi_1": -1, "Latissimus_dorsi_2": -1, "Latissimus_dorsi_3": -1,
    "Teres_minor": -1, "DELT2": -1, "TRIlong": 0, "BIClong": 0,
}
ELBOW_SIGN = {
    "BIClong": 1, "BICshort": 1, "BRA": 1, "BRD": 1, "ECRL": 1, "PronatorTeres": 1,
    "TRIlong": -1, "TRIlat": -1, "TRImed": -1, "ANC": -1,
}


def keep_drop_baseline(model, muscle, gp, L_true, ma_true):
    """Best keep/drop subset of the conditional points (by RMS length error on this grid)."""
    cond = [i for i, p in enumerate(muscle.path) if p.conditional]
    best = None
    for keep in itertools.product((False, True), repeat=len(cond)):
        kept = {i for i, k in zip(cond, keep) if k}
        pts = [p for i, p in enumerate(muscle.path) if not p.conditional or i in kept]
        L, ma = gp.path_geometry([p.body for p in pts], [p.location for p in pts])
        rms = float(np.sqrt(np.mean((L - L_true) ** 2)))
        if best is None or rms < best[0]:
            best = (rms, L, ma)
    _, L, ma = best
    return L - L_true, ma - ma_true


def stats_mm(err: np.ndarray) -> dict:
    return {"max_mm": round(float(np.abs(err).max()) * 1e3, 3), "rms_mm": round(float(np.sqrt(np.mean(err ** 2))) * 1e3, 3)}


#: Below this magnitude (m) a moment arm is treated as zero when comparing signs with the true path.
SIGN_TOLERANCE_M = 1e-3


def sign_check(name: str, ma: np.ndarray, ma_true: np.ndarray, at_start: float, expected: dict) -> dict:
    """ma, ma_true: (G,) MJCF and true moment arms about one joint (m); at_start: MJCF moment arm at (0.62, 1.53)."""
    want = expected.get(name)
    definite = np.abs(ma_true) >= SIGN_TOLERANCE_M
    out = {"min_mm": round(float(ma.min()) * 1e3, 2), "max_mm": round(float(ma.max()) * 1e3, 2),
           "osim_min_mm": round(float(ma_true.min()) * 1e3, 2), "osim_max_mm": round(float(ma_true.max()) * 1e3, 2),
           "at_start_mm": round(at_start * 1e3, 2),
           # the MJCF's sign equals the true path's wherever the true moment arm is at least 1 mm
           "matches_osim_sign": bool(np.all(np.sign(ma[definite]) == np.sign(ma_true[definite])))}
    if want is None:
        out["expected"] = "not listed"
        out["ok"] = out["matches_osim_sign"]
    elif want == 0:
        out["expected"] = "changes sign"
        out["ok"] = bool(ma.min() < 0 < ma.max()) and out["matches_osim_sign"]
    else:
        out["expected"] = "flexor (> 0)" if want > 0 else "extensor (< 0)"
        out["fraction_with_expected_sign"] = round(float(np.mean(ma * want > 0)), 4)
        out["osim_fraction_with_expected_sign"] = round(float(np.mean(ma_true * want > 0)), 4)
        out["ok"] = bool(at_start * want > 0) and out["matches_osim_sign"]
    return out


def hand_comparison(model, grid) -> dict:
    zero = {c.name: 0.0 for c in model.coordinates}
    shoulder = osim.body_transforms(model, zero)["humerus"][:3, 3]
    l1, l2 = ARM_SEGMENTS_M
    d_elbow, d_hand, off_plane_elbow, off_plane_hand = [], [], [], []
    for g in grid:
        P = osim.body_transforms(model, g)
        q1, q2 = g["arm_flex"], g["elbow_flex"]
        formula_elbow = np.array([l1 * math.cos(q1), l1 * math.sin(q1)])
        formula_hand = formula_elbow + np.array([l2 * math.cos(q1 + q2), l2 * math.sin(q1 + q2)])
        for body, formula, dist, off in (("ulna", formula_elbow, d_elbow, off_plane_elbow),
                                         ("hand", formula_hand, d_hand, off_plane_hand)):
            r = P[body][:3, 3] - shoulder
            planar = np.array([r[2], r[0]])   # authors' (x, y) = (lateral, anterior)
            dist.append(np.linalg.norm(planar - formula))
            off.append(r[1])
    start = {"arm_flex": 0.62, "elbow_flex": 1.53}
    P = osim.body_transforms(model, start)
    r_start = P["hand"][:3, 3] - shoulder
    q1, q2 = start["arm_flex"], start["elbow_flex"]
    f_start = [l1 * math.cos(q1) + l2 * math.cos(q1 + q2), l1 * math.sin(q1) + l2 * math.sin(q1 + q2)]
    d_elbow, d_hand = np.array(d_elbow), np.array(d_hand)
    return {
        "points": "elbow = ulna-body origin (elbow joint centre), hand = hand-body origin; plane distance in the "
                  "authors' (x, y) = (thorax z, thorax x) relative to the shoulder joint centre",
        "elbow_planar_distance_mm": {"min": round(d_elbow.min() * 1e3, 2), "max": round(d_elbow.max() * 1e3, 2)},
        "hand_planar_distance_mm": {"min": round(d_hand.min() * 1e3, 2), "max": round(d_hand.max() * 1e3, 2),
                                    "mean": round(d_hand.mean() * 1e3, 2)},
        "elbow_height_offset_mm": {"min": round(min(off_plane_elbow) * 1e3, 2),
                                   "max": round(max(off_plane_elbow) * 1e3, 2)},
        "hand_height_offset_mm": {"min": round(min(off_plane_hand) * 1e3, 2), "max": round(max(off_plane_hand) * 1e3, 2)},
        "start_posture": {"q_rad": [0.62, 1.53], "model_hand_xy_m": [round(r_start[2], 4), round(r_start[0], 4)],
                          "formula_hand_xy_m": [round(f_start[0], 4), round(f_start[1], 4)]},
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--step-deg", type=float, default=2.5, help="grid step over both joint ranges, degrees")
    ap.add_argument("--mjcf", type=Path, default=convert.ASSETS_DIR / "arm.xml")
    ap.add_argument("--osim", type=Path, default=None)
    args = ap.parse_args(argv)

    import mujoco

    t0 = time.time()
    model = osim.parse_osim(args.osim)
    mjmodel = mujoco.MjModel.from_xml_path(str(args.mjcf))
    names = tuple(mujoco.mj_id2name(mjmodel, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(mjmodel.ntendon))
    if names != model.muscle_names:
        raise SystemExit(f"tendon order {names} differs from the osim muscle order {model.muscle_names}")
    grid = convert.joint_range_grid(args.step_deg)
    gp = convert.GridPoses(model, grid)
    L_mj, ma_mj = convert.mjcf_path_geometry(mjmodel, grid)
    _, ma_start = convert.mjcf_path_geometry(mjmodel, [{"arm_flex": 0.62, "elbow_flex": 1.53}])
    ma_start = ma_start[0]

    # Exactness of the translation: MJCF vs the osim polyline through the MJCF's own site locations.
    site_err = 0.0
    for k, m in enumerate(model.muscles):
        sids = [mjmodel.wrap_objid[mjmodel.tendon_adr[k] + j] for j in range(mjmodel.tendon_num[k])]
        bodies = [mujoco.mj_id2name(mjmodel, mujoco.mjtObj.mjOBJ_BODY, mjmodel.site_bodyid[s]) for s in sids]
        L_sites, _ = gp.path_geometry(bodies, [mjmodel.site_pos[s] for s in sids])
        site_err = max(site_err, float(np.abs(L_sites - L_mj[:, k]).max()))

    muscles = {}
    for k, m in enumerate(model.muscles):
        L_true, ma_true = convert.true_path_geometry(m, gp)
        eL, ema = L_mj[:, k] - L_true, ma_mj[:, k, :] - ma_true
        entry = {
            "conditional_points": sum(p.conditional for p in m.path),
            "length": stats_mm(eL),
            "moment_arm_shoulder": stats_mm(ema[:, 0]),
            "moment_arm_elbow": stats_mm(ema[:, 1]),
            "mtu_length_range_m": {"mjcf": [round(float(L_mj[:, k].min()), 4), round(float(L_mj[:, k].max()), 4)],
                                   "osim": [round(float(L_true.min()), 4), round(float(L_true.max()), 4)]},
            "sign_shoulder": sign_check(m.name, ma_mj[:, k, 0], ma_true[:, 0], ma_start[k, 0], SHOULDER_SIGN),
            "sign_elbow": sign_check(m.name, ma_mj[:, k, 1], ma_true[:, 1], ma_start[k, 1], ELBOW_SIGN),
        }
        if entry["conditional_points"]:
            bL, bma = keep_drop_baseline(model, m, gp, L_true, ma_true)
            entry["keep_drop_baseline"] = {"length": stats_mm(bL), "moment_arm_shoulder": stats_mm(bma[:, 0]),
                                           "moment_arm_elbow": stats_mm(bma[:, 1])}
        muscles[m.name] = entry

    def worst(key, sub="max_mm", src=None):
        vals = {n: e[key][sub] for n, e in muscles.items()}
        n = max(vals, key=vals.get)
        return {"value_mm": vals[n], "muscle": n}

    L_all = L_mj
    report = {
        "command": "python experiments/arm_geometry_error.py --json --step-deg %g" % args.step_deg,
        "config": {"grid_step_deg": args.step_deg, "shoulder_range_deg": list(SHOULDER_RANGE_DEG),
                   "elbow_range_deg": list(ELBOW_RANGE_DEG), "postures": len(grid), "mjcf": str(args.mjcf.name),
                   "moment_arm": "-dL/dq (m); > 0 means tension drives the joint towards +q (flexion)"},
        "translation_exactness_max_m": site_err,
        "summary": {
            "length_max": worst("length"), "length_rms_max": worst("length", "rms_mm"),
            "moment_arm_shoulder_max": worst("moment_arm_shoulder"),
            "moment_arm_elbow_max": worst("moment_arm_elbow"),
            "moment_arm_shoulder_rms_max": worst("moment_arm_shoulder", "rms_mm"),
            "moment_arm_elbow_rms_max": worst("moment_arm_elbow", "rms_mm"),
            "mtu_length_range_all_m": [round(float(L_all.min()), 4), round(float(L_all.max()), 4)],
            "signs_ok": all(e[s]["ok"] for e in muscles.values() for s in ("sign_shoulder", "sign_elbow")),
            "driven_muscles_mtu_length_range_m": [
                round(float(L_mj[:, [model.muscle_names.index(n) for n in DRIVEN]].min()), 4),
                round(float(L_mj[:, [model.muscle_names.index(n) for n in DRIVEN]].max()), 4)],
        },
        "muscles": muscles,
        "hand": hand_comparison(model, grid),
        "seconds": round(time.time() - t0, 1),
    }
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"{'muscle':20s} {'L max/rms mm':>14s} {'MA sh max/rms':>14s} {'MA el max/rms':>14s}  "
              f"{'keep/drop L max/rms':>20s}  MTU range m")
        for n, e in muscles.items():
            b = e.get("keep_drop_baseline")
            bs = f"{b['length']['max_mm']:6.2f}/{b['length']['rms_mm']:5.2f}" if b else ""
            print(f"{n:20s} {e['length']['max_mm']:6.2f}/{e['length']['rms_mm']:5.2f}  "
                  f"{e['moment_arm_shoulder']['max_mm']:6.2f}/{e['moment_arm_shoulder']['rms_mm']:5.2f}  "
                  f"{e['moment_arm_elbow']['max_mm']:6.2f}/{e['moment_arm_elbow']['rms_mm']:5.2f}  {bs:>20s}  "
                  f"{e['mtu_length_range_m']['mjcf']}")
        print(json.dumps({"summary": report["summary"], "hand": report["hand"],
                          "translation_exactness_max_m": site_err}, indent=1))
    return report


if __name__ == "__main__":
    main()
