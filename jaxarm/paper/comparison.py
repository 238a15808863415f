"""The paper's reported numbers and our run folders' statistics beside them (paper §3.2, Fig. 7).

``target_stats(folder)`` reads a ``jaxarm train`` / ``jaxarm reproduce`` output folder (``results.json`` and
``trajectories.npz``, one target) and returns: successes out of N (trained and naive), median closest approach, and
over the **successful** trained networks (as the paper averaged "across successful trajectories") the mean (SD)
speed before and after the first entry into the 4 cm circle (m/s), the distance to the target after it (cm) and the
time inside it (ms); then the dimensionless jerk of every trained and naive test path (:func:`dimensionless_jerk`,
path-length speed). ``markdown(stats)`` lays them out beside the paper's values (Dura-Bernal et al. 2015, §3.2 and
Fig. 7: musculoskeletal arm; jerk also for the simple arm). Metric conventions: :mod:`jaxarm.analysis.reach`.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from jaxarm.analysis.jerk import dimensionless_jerk
from jaxarm.analysis.stats import mean_sd

#: The paper's values, musculoskeletal arm (§3.2): metric -> {target: (mean, sd)}; units as in the row labels.
PAPER_MS = {
    "speed_before_m_s": {"left": (0.327, 0.051), "bottom": (0.208, 0.039)},
    "speed_after_m_s": {"left": (0.167, 0.030), "bottom": (0.184, 0.049)},
    "distance_after_cm": {"left": (3.87, 0.78), "bottom": (3.20, 0.69)},
    "time_inside_ms": {"left": (295.0, 12.0), "bottom": (202.0, 10.0)},
}
#: The paper's mean dimensionless jerk (Fig. 7; both targets together): arm -> (trained, naive).
PAPER_JERK = {"musculoskeletal": (0.76, 1.72), "simple": (28.1, None)}
PAPER_SUCCESS = {"musculoskeletal": {"left": 29, "bottom": 26}, "simple": {"left": 28, "bottom": 27}}

ROWS = (("speed_before_m_s", "speed before first entry, m/s", 1.0),
        ("speed_after_m_s", "speed after first entry, m/s", 1.0),
        ("distance_after_m", "distance to target after entry, cm", 100.0),
        ("time_inside_s", "time inside the circle, ms", 1000.0))
PAPER_KEY = {"speed_before_m_s": "speed_before_m_s", "speed_after_m_s": "speed_after_m_s",
             "distance_after_m": "distance_after_cm", "time_inside_s": "time_inside_ms"}


#: The original NEURON model's training run (simple arm, left target, its seeds; [the original model's reference
#: run](../results.md#the-authors-metaparameters-in-our-model)): epoch -> rates (Hz) over the epoch's last 10 s for
#: ORIGINAL_HISTORY_RATES, then the mean wgain per pathway at its end for ORIGINAL_HISTORY_GAINS.
ORIGINAL_HISTORY = {
    1: (3.46, 2.07, 1.65, 0.78, 0.80, 0.68, 1.014, 1.046, 1.001, 1.015, 1.021, 0.994, 0.990),
    2: (2.94, 1.91, 1.31, 0.43, 0.64, 0.53, 1.029, 1.098, 1.003, 1.033, 1.047, 0.995, 0.978),
    3: (3.14, 2.00, 1.45, 0.52, 0.75, 0.57, 1.042, 1.126, 1.007, 1.040, 1.059, 0.992, 0.970),
    4: (3.50, 2.24, 1.59, 0.86, 0.81, 0.66, 1.047, 1.150, 1.007, 1.048, 1.071, 0.989, 0.966),
    5: (3.56, 2.45, 1.62, 1.07, 1.09, 0.68, 1.057, 1.177, 1.009, 1.060, 1.085, 0.985, 0.959),
    6: (3.66, 2.67, 1.59, 1.19, 1.13, 0.82, 1.080, 1.238, 1.015, 1.083, 1.117, 0.985, 0.943),
    7: (3.04, 2.25, 1.39, 0.93, 1.12, 0.78, 1.100, 1.274, 1.024, 1.099, 1.137, 0.995, 0.928),
    8: (3.18, 2.59, 1.58, 1.41, 1.51, 1.01, 1.138, 1.333, 1.049, 1.131, 1.170, 1.017, 0.904),
    9: (3.84, 3.35, 1.82, 2.55, 3.01, 1.54, 1.191, 1.377, 1.097, 1.164, 1.191, 1.074, 0.871),
    10: (2.04, 1.50, 1.02, 0.37, 0.67, 0.54, 1.196, 1.378, 1.103, 1.166, 1.188, 1.080, 0.867),
    11: (2.23, 1.58, 1.06, 0.44, 0.72, 0.53, 1.200, 1.377, 1.109, 1.168, 1.186, 1.087, 0.866),
    12: (2.74, 2.10, 1.25, 0.89, 0.95, 0.70, 1.204, 1.380, 1.114, 1.174, 1.186, 1.093, 0.862),
}
ORIGINAL_HISTORY_RATES = ("ES", "IS", "ISL", "EM", "IM", "IML")
ORIGINAL_HISTORY_GAINS = ("ES->EM", "ES->ES", "EM->EM", "EM->ES", "ES->IS", "EM->IM", "IS->ES")


def run_folders(paths) -> list[Path]:
    """Run folders (with results.json) from folders that are one, or hold ``<target>/seeds/`` ones (left first)."""
    out = []
    for p in map(Path, paths):
        if (p / "results.json").exists():
            out.append(p)
        else:
            order = {"left": 0, "bottom": 1}
            found = sorted(p.glob("*/seeds/results.json"), key=lambda f: (order.get(f.parent.parent.name, 9), str(f)))
            if not found:
                raise FileNotFoundError(f"{p}: no results.json here nor in {p}/<target>/seeds/")
            out.extend(f.parent for f in found)
    return out


def target_stats(folder: Path) -> dict:
    """The statistics of one run folder (one target); see the module docstring."""
    res = json.loads((folder / "results.json").read_text())
    traj = np.load(folder / "trajectories.npz")
    dt = float(np.median(np.diff(traj["t"])))
    nets = res["networks"]
    success = np.array([n["success"] for n in nets], bool)
    out = {"folder": str(folder), "arm": res["config"]["arm"], "target": res["target"], "n": len(nets),
           "success_count": int(success.sum()), "naive_success_count": int(res["naive"]["success_count"]),
           "closest_median_cm": 100 * float(np.median([n["min_distance_m"] for n in nets])),
           "naive_closest_median_cm": 100 * float(np.median([n["min_distance_m"] for n in res["naive"]["networks"]]))}
    for key, _, scale in ROWS:
        s = mean_sd(np.array([n[key] for n in nets], float) * scale, success)
        out[key] = s
    jt = np.asarray(dimensionless_jerk(traj["hand"], dt))
    jn = np.asarray(dimensionless_jerk(traj["naive_hand"], dt))
    out["jerk_trained"] = mean_sd(jt)
    out["jerk_naive"] = mean_sd(jn)
    out["jerk_trained_successful"] = mean_sd(jt, success)
    return out


#: The quantities of :func:`beside_paper`, in table order: key, label with unit.
MEASURES = (("speed_before_m_s", "speed before first entry, m/s"),
            ("speed_after_m_s", "speed after first entry, m/s"),
            ("distance_after_m", "distance to target after entry, cm"),
            ("time_inside_s", "time inside the circle, ms"),
            ("jerk_trained", "dimensionless jerk, trained (all networks)"),
            ("jerk_naive", "dimensionless jerk, naive (all networks)"),
            ("jerk_ratio", "dimensionless jerk, trained / naive"))


def beside_paper(stats: dict) -> dict:
    """:func:`target_stats` of one folder as ``{quantity: {mean, sd, n, paper, paper_sd, ratio}}`` for
    :data:`MEASURES` (units as their labels; ratio = ours / the paper's, None where the paper reports nothing: the
    after-entry measures exist for the musculoskeletal arm only, and the paper's jerk is over both targets; its
    absolute jerk values cannot come from its formula for movements starting at rest, so compare the trained/naive
    ratio)."""
    arm, target = stats["arm"], stats["target"]
    out = {}
    for key, _ in MEASURES:
        paper = paper_sd = None
        if key == "jerk_ratio":
            t, n = stats["jerk_trained"]["mean"], stats["jerk_naive"]["mean"]
            ours = {"mean": t / n if n else float("nan"), "sd": float("nan"), "n": stats["jerk_trained"]["n"]}
            p = PAPER_JERK.get(arm, (None, None))
            paper = p[0] / p[1] if p[1] else None
        elif key.startswith("jerk_"):
            ours = stats[key]
            paper = PAPER_JERK.get(arm, (None, None))[0 if key == "jerk_trained" else 1]
        else:
            ours = stats[key]
            p = PAPER_MS[PAPER_KEY[key]].get(target) if arm == "musculoskeletal" else None
            paper, paper_sd = p if p else (None, None)
        mean = ours["mean"]
        finite = mean is not None and np.isfinite(mean)
        # The paper's absolute jerk cannot come from its formula (docstring): shown beside ours, never divided.
        comparable = key not in ("jerk_trained", "jerk_naive")
        out[key] = {"mean": round(float(mean), 4) if finite else None,
                    "sd": round(float(ours["sd"]), 4) if np.isfinite(ours["sd"]) else None, "n": int(ours["n"]),
                    "paper": paper, "paper_sd": paper_sd,
                    "ratio": round(float(mean) / paper, 3) if finite and paper and comparable else None}
    return out


def _fmt(s: dict, digits: int = 3) -> str:
    if s["n"] == 0 or not np.isfinite(s["mean"]):
        return "–"
    sd = f" ({s['sd']:.{digits}g})" if np.isfinite(s["sd"]) else ""
    return f"{s['mean']:.{digits}g}{sd}"


def markdown(stats: list[dict]) -> str:
    """A markdown table: one column per run folder, ours / the paper's in each cell."""
    head = "| quantity | " + " | ".join(f"{s['arm']} {s['target']}: jaxarm / paper" for s in stats) + " |"
    lines = [head, "|---|" + "---|" * len(stats)]

    def row(label, cells):
        lines.append(f"| {label} | " + " | ".join(cells) + " |")

    row("networks reaching (naive)", [
        f"{s['success_count']}/{s['n']} ({s['naive_success_count']}/{s['n']}) / "
        f"{PAPER_SUCCESS.get(s['arm'], {}).get(s['target'], '–')}/30" for s in stats])
    row("closest approach, median cm (naive)",
        [f"{s['closest_median_cm']:.1f} ({s['naive_closest_median_cm']:.1f}) / –" for s in stats])
    for key, label, _ in ROWS:
        cells = []
        for s in stats:
            p = PAPER_MS.get(PAPER_KEY[key], {}).get(s["target"]) if s["arm"] == "musculoskeletal" else None
            cells.append(f"{_fmt(s[key])} / " + (f"{p[0]:g} ({p[1]:g})" if p else "–"))
        row(label + " (successful networks)", cells)
    for which, idx in (("trained", 0), ("naive", 1)):
        cells = []
        for s in stats:
            p = PAPER_JERK.get(s["arm"], (None, None))[idx]
            cells.append(f"{_fmt(s['jerk_' + which])} / " + (f"{p:g}" if p is not None else "–"))
        row(f"dimensionless jerk, {which}, all networks", cells)
    cells = []
    for s in stats:
        p = PAPER_JERK.get(s["arm"], (None, None))
        ours = s["jerk_trained"]["mean"] / s["jerk_naive"]["mean"]
        cells.append(f"{ours:.2f} / " + (f"{p[0] / p[1]:.2f}" if p[1] else "–"))
    row("jerk ratio trained / naive", cells)
    return "\n".join(lines)


#: The original NEURON model's 1 s test after that training (simple arm, left target, its seeds; [the original
#: model's reference run](../results.md#the-authors-metaparameters-in-our-model)): hand–target distance (cm) at test
#: times (ms), as the spec reports them ("15.1 cm until t≈130 ms" gives the first two points).
ORIGINAL_TEST_DISTANCE_CM = {0: 15.1, 130: 15.1, 200: 12.9, 400: 7.3, 600: 4.3, 700: 3.5, 800: 1.7, 900: 2.5,
                             1000: 3.3}
#: Its closest approach and final distance, cm; its joint angles at the test's end (shoulder, elbow), rad.
ORIGINAL_TEST_CLOSEST_CM, ORIGINAL_TEST_FINAL_CM = 1.59, 3.31
ORIGINAL_TEST_FINAL_Q_RAD = (1.007, 1.692)
#: Its firing rates over the test (spkstats2), Hz.
ORIGINAL_TEST_RATES_HZ = {"ES": 5.0, "IS": 5.6, "ISL": 3.4, "EM": 5.1, "IM": 9.9, "IML": 3.4}


def _percentile_of(values: np.ndarray, x: float) -> float:
    """Percent of ``values`` at or below ``x`` (ties count half): where the original's one value sits among ours."""
    values = np.asarray(values, float)
    return 100.0 * (np.sum(values < x) + 0.5 * np.sum(values == x)) / len(values)


def original_test_comparison(folder: Path) -> dict:
    """Our trained networks' 1 s test beside the original model's one test (:data:`ORIGINAL_TEST_DISTANCE_CM`).

    ``folder`` is a ``jaxarm train`` output (simple arm, left target: the only target the original was run on).
    For each reference time from 200 ms on (before it the original's hand had not moved): our median, 10th and 90th percentile distance (cm) over networks, and the percentile at
    which the original's value sits among ours (low = the original was closer than most of ours); the same for the
    closest approach and the final distance; the median final joint angles (rad) and the test's firing rates (Hz,
    mean over networks) beside the original's. Distances at a reference time are read at the nearest sample of the
    10 ms trajectory. Ours are rounded to the reference's precision (0.1 cm; 0.01 cm for the closest approach and the
    final distance) before the percentile, so that equal values tie (count half) rather than differ in the last digit."""
    res = json.loads((folder / "results.json").read_text())
    if res["config"]["arm"] != "simple" or res["target"] != "left":
        raise ValueError(f"{folder}: arm={res['config']['arm']!r}, target={res['target']!r}; the original's reference "
                         "test is the simple arm on the left target")
    traj = np.load(folder / "trajectories.npz")
    t_ms = 1000.0 * np.asarray(traj["t"], float)
    dist_cm = 100.0 * np.asarray(traj["distance"], float)          # (networks, T)
    rows = []
    for t_ref, d_ref in ORIGINAL_TEST_DISTANCE_CM.items():
        if t_ref < 200:   # the start distance, before the first readout window filled ("until t≈130 ms"): no test
            continue
        i = int(np.argmin(np.abs(t_ms - t_ref)))
        d = np.round(dist_cm[:, i], 1)
        rows.append({"t_ms": t_ref, "original_cm": d_ref, "median_cm": float(np.median(d)),
                     "p10_cm": float(np.percentile(d, 10)), "p90_cm": float(np.percentile(d, 90)),
                     "original_percentile": _percentile_of(d, d_ref)})
    closest, final = dist_cm.min(axis=1), dist_cm[:, -1]
    q_final = np.asarray(traj["q"], float)[:, -1]
    return {
        "folder": str(folder), "n": int(dist_cm.shape[0]), "success_count": int(res["success_count"]),
        "distance": rows,
        "closest": {"original_cm": ORIGINAL_TEST_CLOSEST_CM, "median_cm": float(np.median(closest)),
                    "p10_cm": float(np.percentile(closest, 10)), "p90_cm": float(np.percentile(closest, 90)),
                    "original_percentile": _percentile_of(np.round(closest, 2), ORIGINAL_TEST_CLOSEST_CM)},
        "final": {"original_cm": ORIGINAL_TEST_FINAL_CM, "median_cm": float(np.median(final)),
                  "p10_cm": float(np.percentile(final, 10)), "p90_cm": float(np.percentile(final, 90)),
                  "original_percentile": _percentile_of(np.round(final, 2), ORIGINAL_TEST_FINAL_CM)},
        "final_q_rad": {"original": list(ORIGINAL_TEST_FINAL_Q_RAD), "median": np.median(q_final, axis=0).tolist()},
        "test_rates_hz": {"original": ORIGINAL_TEST_RATES_HZ, "ours": res.get("test_rates_hz"),
                          "original_percentile": _rate_percentiles(res["networks"])},
    }


def _rate_percentiles(networks: list[dict]) -> dict | None:
    """Per population, the percentile of the original's test rate among our networks' (None for folders written
    before results.json had per-network test rates)."""
    if not networks or "test_rates_hz" not in networks[0]:
        return None
    return {p: _percentile_of(np.round([n["test_rates_hz"][p] for n in networks], 1), r)
            for p, r in ORIGINAL_TEST_RATES_HZ.items()}


def per_network_history(history) -> np.ndarray:
    """(epochs, networks, 13) per-network training history in the column order of :data:`ORIGINAL_HISTORY`
    (rates of ORIGINAL_HISTORY_RATES in Hz, then mean gains of ORIGINAL_HISTORY_GAINS), from a run's
    ``history.npz`` (a mapping with ``populations``, ``pathways``, ``rates_last10s_hz`` and ``mean_wgain``)."""
    pops, pws = [str(p) for p in history["populations"]], [str(p) for p in history["pathways"]]
    rates = np.asarray(history["rates_last10s_hz"], float)[:, :, [pops.index(p) for p in ORIGINAL_HISTORY_RATES]]
    gains = np.asarray(history["mean_wgain"], float)[:, :, [pws.index(g) for g in ORIGINAL_HISTORY_GAINS]]
    return np.concatenate([rates, gains], axis=2)


def original_history_percentiles(history) -> list[tuple[int, list[tuple[float, float, float]]]]:
    """Where the original's one training run sits among our networks, epoch by epoch ([the original model's reference
    run](../results.md#the-authors-metaparameters-in-our-model) beside ours).

    ``history``: a run's ``history.npz`` as a mapping (:func:`per_network_history`). Returns, for every epoch that
    both have, (epoch, [(percentile, p10, p90) per column of :data:`ORIGINAL_HISTORY`]): the percentile of the
    original's value among ours (ties count half; ours rounded to the reference's precision, 0.01 Hz and 0.001)
    and our 10th and 90th percentiles (unrounded)."""
    values = per_network_history(history)
    n_rates = len(ORIGINAL_HISTORY_RATES)
    out = []
    for e in range(values.shape[0]):
        ref = ORIGINAL_HISTORY.get(e + 1)
        if ref is None:
            continue
        cols = []
        for j, x in enumerate(ref):
            ours = values[e, :, j]
            p10, p90 = np.percentile(ours, [10, 90])
            cols.append((_percentile_of(np.round(ours, 2 if j < n_rates else 3), x), float(p10), float(p90)))
        out.append((e + 1, cols))
    return out


#: The original NEURON model run with many seeds (simple arm, authors' metaparameters, the full protocol): one JSON
#: file per target, measured outside this repository (how: the file's ``measured`` entry; docs/results.md).
ORIGINAL_SEEDS_DIR = Path(__file__).parent / "data"
#: The test times (ms) at which the seed runs' hand–target distances are compared.
COMPARISON_TIMES_MS = (200, 400, 600, 800, 1000)


def original_seed_runs(target: str = "left") -> dict:
    """The original NEURON model's runs with many seeds on ``target`` (simple arm, authors' metaparameters, 12 x 30 s
    of training and the 1 s test): ``{"target", "measured": how, "runs": [{"k", "inputseed", "dvseed", "success",
    "min_distance_cm", "final_distance_cm", "final_q_rad", "test_rates_hz", "distance_cm": the test's hand–target
    distance every 10 ms from 0 to 1000 ms, and where measured "fresh_noise_min_distance_cm": the same trained
    network's closest approach in re-tests with other noise streams}, ...]}``. ValueError for a target without runs."""
    path = ORIGINAL_SEEDS_DIR / f"original_seeds_{target}.json"
    if not path.exists():
        known = sorted(p.stem.removeprefix("original_seeds_") for p in ORIGINAL_SEEDS_DIR.glob("original_seeds_*.json"))
        raise ValueError(f"target={target!r}: the original model was run with many seeds on {known} only")
    return json.loads(path.read_text())


def _summary_cm(x) -> dict:
    x = np.asarray(x, float)
    return {"median_cm": float(np.median(x)), "p10_cm": float(np.percentile(x, 10)),
            "p90_cm": float(np.percentile(x, 90))}


def _count(success) -> dict:
    """k of n with the exact (Clopper–Pearson) 95 % interval of the rate."""
    from scipy import stats

    success = np.asarray(success, bool).reshape(-1)
    k, n = int(success.sum()), int(success.size)
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return {"k": k, "n": n, "rate": k / n, "ci95": [float(ci.low), float(ci.high)]}


def seed_distribution_comparison(folder, original: dict | None = None, fresh_folders=(), goal: int = 26,
                                 goal_of: int = 30, radius_cm: float = 4.0) -> dict:
    """Our networks beside the original NEURON model's, both trained with the authors' metaparameters over many
    seeds and tested the same way (the test re-uses each network's training noise streams).

    * ``success``: counts with exact 95 % intervals and Fisher's exact test between the two;
    * ``closest``, ``final``, ``distance_at_ms`` (:data:`COMPARISON_TIMES_MS`): median and 10–90 % range, cm, and
      the two-sided Mann–Whitney U test (do one model's distances tend to be larger?);
    * ``blocks``: the same counts per block of ``goal_of`` seeds (the original's runs in order, ours per folder),
      own-noise test and fresh re-tests, to show how much a count of 30 networks varies;
    * ``goal``: the probability that ``goal`` or more of ``goal_of`` networks of the original would reach, at its
      measured rate and at the upper end of its interval (how plausible such a count is for the model as it ran);
    * ``fresh``: the trained networks re-tested with other noise streams: the original's from the reference data,
      ours from ``fresh_folders`` (``jaxarm test --from FOLDER --fresh-noise J`` outputs of any of the folders,
      pooled by network seed), each as a count of tests and the mean per-network rate.

    ``folder``: a ``jaxarm train`` output on the simple arm, or a list of them on the same target (pooled, e.g. seeds
    0–29 and 30–59); ``original``: :func:`original_seed_runs` of its
    target (read by default)."""
    from scipy import stats

    folders = [Path(folder)] if isinstance(folder, (str, Path)) else [Path(f) for f in folder]
    results = [json.loads((f / "results.json").read_text()) for f in folders]
    for f, r in zip(folders, results):
        if r["config"]["arm"] != "simple":
            raise ValueError(f"{f}: arm={r['config']['arm']!r}; the original was run on the simple arm")
        if r["target"] != results[0]["target"]:
            raise ValueError(f"{f}: target={r['target']!r}, but {folders[0]} has {results[0]['target']!r}")
    res = {"target": results[0]["target"], "networks": [n for r in results for n in r["networks"]]}
    original = original_seed_runs(res["target"]) if original is None else original
    runs = original["runs"]
    trajs = [np.load(f / "trajectories.npz") for f in folders]
    t_ms = 1000.0 * np.asarray(trajs[0]["t"], float)
    ours_cm = 100.0 * np.concatenate([np.asarray(t["distance"], float) for t in trajs])   # (networks, T)
    orig_cm = np.asarray([r["distance_cm"] for r in runs], float)                 # (runs, 101): 0..1000 ms
    orig_t = 10.0 * np.arange(orig_cm.shape[1])

    def compare(ours, orig):
        return {"ours": _summary_cm(ours), "original": _summary_cm(orig),
                "mannwhitney_p": float(stats.mannwhitneyu(ours, orig, alternative="two-sided").pvalue)}

    at = {}
    for t_ref in COMPARISON_TIMES_MS:
        i, j = int(np.argmin(np.abs(t_ms - t_ref))), int(np.argmin(np.abs(orig_t - t_ref)))
        at[t_ref] = compare(ours_cm[:, i], orig_cm[:, j])
    c_ours = _count([n["success"] for n in res["networks"]])
    c_orig = _count([r["success"] for r in runs])
    table = [[c_ours["k"], c_ours["n"] - c_ours["k"]], [c_orig["k"], c_orig["n"] - c_orig["k"]]]
    fresh = {}
    with_fresh = [r for r in runs if r.get("fresh_noise_min_distance_cm")]
    if with_fresh:
        per = [np.asarray(r["fresh_noise_min_distance_cm"], float) <= radius_cm for r in with_fresh]
        fresh["original"] = _count(np.concatenate(per)) | {
            "networks": len(per), "mean_network_rate": float(np.mean([p.mean() for p in per])),
            "own_noise": _count([r["success"] for r in with_fresh])}
    if fresh_folders:
        by_seed: dict = {}                     # network seed -> its re-tests' outcomes (folders of any of the runs)
        for f in fresh_folders:
            for i, n in enumerate(json.loads((Path(f) / "results.json").read_text())["networks"]):
                by_seed.setdefault(n.get("seed", i), []).append(bool(n["success"]))
        tests = np.concatenate([np.asarray(v, bool) for v in by_seed.values()])
        per_network = tests.size / len(by_seed)
        fresh["ours"] = _count(tests) | {
            "networks": len(by_seed),
            "tests_per_network": int(per_network) if per_network.is_integer() else round(per_network, 2),
            "mean_network_rate": float(np.mean([np.mean(v) for v in by_seed.values()]))}
    # per block of goal_of seeds (the original's runs in order; ours per folder): how much a count of 30 varies
    blocks = {"original": [], "ours": []}
    for b in range(0, len(runs), goal_of):
        chunk = runs[b:b + goal_of]
        fr = [np.asarray(r.get("fresh_noise_min_distance_cm") or [], float) <= radius_cm for r in chunk]
        blocks["original"].append({"label": f"runs {chunk[0].get('k', b)}–{chunk[-1].get('k', b + len(chunk) - 1)}",
                                   "own_noise": _count([r["success"] for r in chunk]),
                                   "fresh": _count(np.concatenate(fr)) if sum(f.size for f in fr) else None})
    for f, r in zip(folders, results):
        seeds = [n.get("seed", i) for i, n in enumerate(r["networks"])]
        fr = [v for sd in seeds for v in (by_seed.get(sd, []) if fresh_folders else [])]
        blocks["ours"].append({"label": str(f), "own_noise": _count([n["success"] for n in r["networks"]]),
                               "fresh": _count(fr) if fr else None})
    return {
        "folder": ", ".join(map(str, folders)), "target": res["target"], "measured": original["measured"],
        "blocks": blocks,
        "after_entry": after_entry_comparison(ours_cm, float(t_ms[1] - t_ms[0]) / 1000.0, orig_cm, 0.010, radius_cm),
        "success": {"ours": c_ours, "original": c_orig, "fisher_p": float(stats.fisher_exact(table).pvalue)},
        "closest": compare(ours_cm.min(axis=1), orig_cm.min(axis=1)),
        "final": compare(ours_cm[:, -1], orig_cm[:, -1]),
        "distance_at_ms": at,
        "goal": {"k": goal, "n": goal_of,
                 "p_at_original_rate": float(stats.binom.sf(goal - 1, goal_of, c_orig["rate"])),
                 "p_at_original_upper_ci": float(stats.binom.sf(goal - 1, goal_of, c_orig["ci95"][1]))},
        "fresh": fresh,
    }


def after_entry_comparison(ours_cm, ours_dt_s, original_cm, original_dt_s, radius_cm: float = 4.0) -> dict:
    """The paper's after-entry measures that a distance trace alone gives, for the networks that entered the circle:
    mean distance to the target centre from first entry to the end of the test (cm), time inside (ms) and time of
    first entry (ms), each as mean, SD and n (the paper's "mean (SD) over successful trajectories"), median and 10–90
    %, with the two-sided Mann–Whitney p between the models. ``ours_cm``, ``original_cm``: (networks, T) hand–target
    distances in cm sampled every ``*_dt_s`` s from the test's start (:func:`jaxarm.analysis.distance_metrics`)."""
    from scipy import stats

    from jaxarm.analysis import distance_metrics, mean_sd

    out: dict = {}
    per_model = {"ours": distance_metrics(np.asarray(ours_cm, np.float64), ours_dt_s, radius_cm),
                 "original": distance_metrics(np.asarray(original_cm, np.float64), original_dt_s, radius_cm)}
    for key, field, scale in (("distance_after_cm", "distance_after_m", 1.0), ("time_inside_ms", "time_inside_s", 1e3),
                              ("first_entry_ms", "first_entry_s", 1e3)):
        values = {m: scale * np.asarray(getattr(d, field), float)[np.asarray(d.success, bool)]
                  for m, d in per_model.items()}
        out[key] = {m: mean_sd(v) | {"median": float(np.median(v)) if v.size else float("nan"),
                                     "p10": float(np.percentile(v, 10)) if v.size else float("nan"),
                                     "p90": float(np.percentile(v, 90)) if v.size else float("nan")}
                    for m, v in values.items()}
        out[key]["mannwhitney_p"] = (float(stats.mannwhitneyu(values["ours"], values["original"],
                                                             alternative="two-sided").pvalue)
                                     if values["ours"].size and values["original"].size else float("nan"))
    return out


#: Per-epoch quantities compared by :func:`original_epoch_comparison`: the critic's counts, the EM rate over the
#: epoch (Hz) and the mean gain of these pathways at the epoch's end.
EPOCH_GAINS = ("ES->EM", "ES->ES", "EM->EM", "ES->IS", "EM->IM", "EM->ES", "IS->ES")
EPOCH_COLUMNS = ("rewards", "punishments", "EM_hz") + EPOCH_GAINS


def original_epoch_comparison(history, original: dict) -> list[dict]:
    """Training epoch by epoch, our networks beside the original's seed runs that recorded every epoch.

    ``history``: a run's ``history.npz`` as a mapping (``rewards``, ``punishments``, ``rates_hz``, ``mean_wgain``
    of shape (epochs, networks, ...), with ``populations`` and ``pathways``); ``original``: :func:`original_seed_runs`.
    Returns one dict per epoch both have: ``{"epoch": 1-based, column: {"ours": summary, "original": summary}}`` for
    :data:`EPOCH_COLUMNS`, each summary the median and 10th/90th percentiles over networks (no unit conversion:
    counts, Hz, gains)."""
    runs = [r for r in original["runs"] if r.get("epochs")]
    if not runs:
        raise ValueError("the original's runs carry no per-epoch records")
    pops, pws = [str(p) for p in history["populations"]], [str(p) for p in history["pathways"]]
    ours = {"rewards": np.asarray(history["rewards"], float), "punishments": np.asarray(history["punishments"], float),
            "EM_hz": np.asarray(history["rates_hz"], float)[:, :, pops.index("EM")]}
    for g in EPOCH_GAINS:
        ours[g] = np.asarray(history["mean_wgain"], float)[:, :, pws.index(g)]
    n_epochs = min(ours["rewards"].shape[0], min(len(r["epochs"]) for r in runs))

    def orig(e, col):
        rows = [r["epochs"][e] for r in runs]
        if col == "EM_hz":
            return np.array([np.mean(x["em_rate_hz_by_group"]) for x in rows])
        return np.array([x[col] if col in x else x["mean_wgain"][col] for x in rows], float)

    def summ(x):
        return {"median": float(np.median(x)), "p10": float(np.percentile(x, 10)), "p90": float(np.percentile(x, 90)),
                "n": int(np.size(x))}

    return [{"epoch": e + 1} | {c: {"ours": summ(ours[c][e]), "original": summ(orig(e, c))} for c in EPOCH_COLUMNS}
            for e in range(n_epochs)]
