"""The exporter: joint trajectories -> one packet per 10 ms of simulated time -> a WAM (simulated or real).

Sources (:func:`load_trajectory`):

* CSV with a header naming ``t, shoulder, elbow`` (s, rad; other columns ignored);
* NPZ with arrays ``t`` (s) and ``q`` (rad; (T, 2) or (networks, T, 2)), or ``t``, ``shoulder``, ``elbow``;
* a ``jaxarm test`` result folder: its ``trajectories.npz`` (arrays ``t`` and ``q`` as above; network 0 unless
  ``network`` says otherwise);
* ``synthetic[:SEED]``: the seeded stand-in of :mod:`jaxarm.robot.synthetic`.

The trajectory is linearly interpolated onto the 10 ms update grid (the virtual arm's packet period). Packet ``k``
carries the sample at simulated time ``k * 10 ms``. When packets leave (:func:`send_times`):

* ``live``: at ``k * 10 ms`` of wall-clock time after the first, i.e. simulated time paced 1:1 to the wall clock;
* ``jitter``: after independent Gamma-distributed intervals fitted by moments to the paper's packet statistics
  (mean 15.09 ms, SD 5.65 ms -> shape 7.133, scale 2.1155 ms; :class:`~jaxarm.robot.config.JitterConfig`), drawn
  from ``numpy.random.Generator(PCG64(seed))``. This reproduces the paper's end-to-end link, where the virtual arm
  ran at about 2/3 of real time.

Over UDP both schedules are paced to the wall clock (:func:`stream_udp`). Offline (:func:`simulate`), the same
schedule gives robot arrival times and the simulator runs in simulated time as fast as possible: no sockets,
deterministic for a given seed.
"""
from __future__ import annotations

import csv
import socket
import time
from pathlib import Path
from typing import NamedTuple, Optional

import numpy as np

from jaxarm.robot.config import JitterConfig, JointMap, WamSimConfig
from jaxarm.robot.protocol import encode, encode_raw

UPDATE_PERIOD_S = 0.010


class Trajectory(NamedTuple):
    t: np.ndarray   # (T,) s, increasing
    q: np.ndarray   # (T, 2) rad, (shoulder, elbow)


def _check(t, q, where: str) -> Trajectory:
    t = np.asarray(t, dtype=float).reshape(-1)
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != 2 or len(q) != len(t):
        raise ValueError(f"{where}: expected t (T,) and q (T, 2); got {t.shape} and {q.shape}")
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise ValueError(f"{where}: need at least two samples with strictly increasing t")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
        raise ValueError(f"{where}: non-finite values")
    return Trajectory(t, q)


def load_trajectory(source: str | Path, network: int = 0) -> Trajectory:
    """Read a trajectory from a CSV, an NPZ, a ``jaxarm test`` result folder or ``synthetic[:SEED]``."""
    text = str(source)
    if text == "synthetic" or text.startswith("synthetic:"):
        from jaxarm.robot.synthetic import reach_trajectory
        seed_text = text.partition(":")[2] or "0"
        if not seed_text.isdigit():
            raise ValueError(f"{text!r}: synthetic:SEED needs a non-negative integer SEED")
        seed = int(seed_text)
        return _check(*reach_trajectory(seed), text)
    path = Path(source)
    if path.is_dir():
        npz = path / "trajectories.npz"
        if not npz.exists():
            raise FileNotFoundError(f"{path}: a jaxarm test result folder must contain trajectories.npz")
        path = npz
    if path.suffix == ".npz":
        from jaxarm.runfolder import read_npz

        z = read_npz(path)      # a damaged archive: ValueError naming the file
        if "q" in z:
            q = z["q"]
            if q.ndim == 3:
                if not 0 <= network < q.shape[0]:
                    raise ValueError(f"{path}: network {network} not in 0..{q.shape[0] - 1}")
                q = q[network]
        else:
            q = np.stack([z["shoulder"], z["elbow"]], axis=-1)
        t = z["t"]
        if t.ndim == 2:
            t = t[network]
        return _check(t, q, str(path))
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = [h.strip().lower() for h in next(reader, [])]
        try:
            idx = [header.index(k) for k in ("t", "shoulder", "elbow")]
        except ValueError:
            raise ValueError(f"{path}: the CSV header must name t, shoulder and elbow; got {header}") from None
        rows = []
        for line, r in enumerate(reader, start=2):
            if not r:
                continue
            try:
                rows.append([float(r[i]) for i in idx])
            except (IndexError, ValueError):
                raise ValueError(f"{path}, line {line}: expected numbers in columns t, shoulder, elbow; "
                                 f"got {r}") from None
    rows = np.asarray(rows, dtype=float).reshape(-1, 3)
    return _check(rows[:, 0], rows[:, 1:], str(path))


def save_trajectory_csv(path: str | Path, traj: Trajectory) -> Path:
    path = Path(path)
    np.savetxt(path, np.column_stack([traj.t, traj.q]), delimiter=",", header="t,shoulder,elbow",
               comments="", fmt="%.9g")
    return path


def resample(traj: Trajectory, period_s: float = UPDATE_PERIOD_S) -> Trajectory:
    """Linear interpolation onto ``t0 + k * period_s`` for every k inside the trajectory's span."""
    n = int(np.floor((traj.t[-1] - traj.t[0]) / period_s + 1e-9)) + 1
    t = traj.t[0] + np.arange(n) * period_s
    q = np.column_stack([np.interp(t, traj.t, traj.q[:, j]) for j in range(2)])
    return Trajectory(t, q)


def send_times(n: int, timing: str = "jitter", seed: int = 0, jitter: JitterConfig | None = None,
               period_s: float = UPDATE_PERIOD_S) -> np.ndarray:
    """Times (s, relative to the first packet, which leaves at 0) at which the ``n`` packets leave.

    ``timing="live"``: ``k * period_s``. ``timing="jitter"``: cumulative Gamma intervals (ms -> s) from
    ``numpy.random.Generator(PCG64(seed))``.
    """
    if timing == "live":
        return np.arange(n) * period_s
    if timing != "jitter":
        raise ValueError(f"timing={timing!r}: must be 'live' or 'jitter'")
    jitter = jitter or JitterConfig()
    rng = np.random.Generator(np.random.PCG64(seed))
    gaps = rng.gamma(jitter.shape, jitter.scale_ms, size=max(n - 1, 0)) * 1e-3
    return np.concatenate([[0.0], np.cumsum(gaps)])


def packets(traj: Trajectory, fmt: str = "extended", wam_joints: bool = False,
            joint_map: JointMap | None = None) -> list[bytes]:
    """One datagram per sample of ``traj`` (already on the update grid): extended (seq = index, t = sample time)
    or raw; 2 virtual angles, or the 4 WAM joints after ``joint_map`` when ``wam_joints``."""
    angles = (joint_map or JointMap()).to_wam(traj.q) if wam_joints else traj.q
    if fmt == "extended":
        return [encode(a, k, t) for k, (t, a) in enumerate(zip(traj.t - traj.t[0], angles))]
    if fmt == "raw":
        return [encode_raw(a) for a in angles]
    raise ValueError(f"fmt={fmt!r}: must be 'extended' or 'raw'")


def stream_udp(host: str, port: int, datagrams: list[bytes], times_s: np.ndarray,
               start_delay_s: float = 0.0) -> dict:
    """Send ``datagrams[k]`` at wall time ``start + times_s[k]`` to (host, port). Returns send statistics."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    lateness = np.zeros(len(datagrams))
    errors = 0
    with socket.socket(family, socket.SOCK_DGRAM) as sock:
        t0 = time.perf_counter() + start_delay_s
        for k, data in enumerate(datagrams):
            wait = t0 + times_s[k] - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            lateness[k] = time.perf_counter() - (t0 + times_s[k])
            try:
                sock.sendto(data, (host, port))
            except OSError:   # e.g. ICMP port unreachable reported on a later send: keep pacing, count it
                errors += 1
    return {"sent": len(datagrams) - errors, "send_errors": errors, "duration_s": float(times_s[-1]) if len(times_s) else 0.0,
            "lateness_ms_median": float(np.median(lateness) * 1e3) if len(lateness) else 0.0,
            "lateness_ms_max": float(lateness.max() * 1e3) if len(lateness) else 0.0}


def simulate(traj: Trajectory, config: WamSimConfig | None = None, timing: str = "jitter", seed: int = 0,
             duration_s: Optional[float] = None, jitter: JitterConfig | None = None, fmt: str = "extended",
             wam_joints: bool = False, first_arrival_s: float = 0.0):
    """Offline export: build the packets and their robot arrival times (``first_arrival_s`` + :func:`send_times`),
    run :func:`~jaxarm.robot.simulator.run_offline` and return its :class:`~jaxarm.robot.simulator.SimLog`.
    ``duration_s`` defaults to the last arrival plus 0.5 s."""
    from jaxarm.robot.simulator import run_offline

    config = config or WamSimConfig()
    grid = resample(traj)
    data = packets(grid, fmt, wam_joints, config.joint_map)
    arrivals = first_arrival_s + send_times(len(data), timing, seed, jitter)
    if duration_s is None:
        duration_s = float(arrivals[-1]) + 0.5
    keep = arrivals <= duration_s
    return run_offline(config, arrivals[keep], [d for d, k in zip(data, keep) if k], duration_s)
