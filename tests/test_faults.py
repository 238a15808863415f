"""Fault injection: what a careless user or a bad day does to the commands, and what they answer (issue 51).

Every case of :data:`CASES` runs a command on a damaged input, a busy or broken output folder or an unreachable
coordinator and asserts its exit status and that its answer is one line on stderr (an argparse usage block before
it is allowed; no ``Traceback``), matching the case's pattern; where the folder holds a checkpoint, that nothing
in it changed and that the same command as before still resumes it to the same results, bit for bit.

Most cases call the command line's entry point in this process (``jaxarm.cli.main``: an exception that escapes it
fails the test as a traceback would); the coordinator cases, which must start JAX afresh, run ``python -m
jaxarm.cli`` as a subprocess. A real ``kill -9`` of a run and a damaged newest checkpoint are tested in
tests/test_kill_resume.py and test_closed_loop.py / test_evolve.py / test_reproduce.py, not again here.
``experiments/fault_table.py`` runs the same cases and prints docs/faults.md's table.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import re
import resource
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable
from unittest import mock

import numpy as np
import pytest

#: A tiny training run (1 network, 2 epochs of 0.1 s): every case that trains or resumes uses these options.
TINY = ["--arm", "simple", "--target", "left", "--networks", "1", "--epochs", "2", "--epoch-s", "0.1", "--test-s",
        "0.1", "--seed", "0", "--no-progress"]
#: The last line argparse prints after its usage block.
ARGPARSE_ERROR = re.compile(r"^jaxarm[\w -]*: error: ")


@dataclass
class Outcome:
    code: int
    err: str
    out: str = ""
    shown: str | None = None     # what the table shows when the answer is not a stderr line (a valid report)


@dataclass
class Case:
    name: str                            # what was done, for the table
    run: Callable[["Workspace"], Outcome]
    code: int                            # the exit status asserted
    message: str | None                  # regex the one line must match (None: no line at all)
    notes: tuple[str, ...] = ()          # regexes of further lines allowed (a warning, a note)
    group: str = ""
    slow: bool = False


class Workspace:
    """A folder for the cases and a finished tiny run in it (:meth:`reference`), trained once in this process."""

    def __init__(self, root: Path):
        self.root = Path(root)
        self._reference: Path | None = None
        self._n = 0

    def fresh(self, name: str) -> Path:
        self._n += 1
        return self.root / f"{self._n:02d}-{name}"

    def reference(self) -> Path:
        if self._reference is None:
            out = self.root / "reference"
            done = cli(["train", *TINY, "--out", str(out)])
            assert done.code == 0, done.err
            self._reference = out
        return self._reference

    def copy_of_reference(self, name: str) -> Path:
        dst = self.fresh(name)
        shutil.copytree(self.reference(), dst)
        return dst


# -- running a command ----------------------------------------------------------------------------------------------

def cli(argv: list[str]) -> Outcome:
    """``jaxarm ARGV`` in this process; an exception escaping the command line propagates (a traceback)."""
    from jaxarm.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as e:        # argparse, and messages given as SystemExit("...")
            if isinstance(e.code, str):
                err.write(e.code + "\n")
                code = 1
            else:
                code = e.code or 0
    return Outcome(int(code), err.getvalue(), out.getvalue())


def cli_process(argv: list[str], timeout: float = 120) -> Outcome:
    """``python -m jaxarm.cli ARGV`` as a subprocess."""
    p = subprocess.run([sys.executable, "-m", "jaxarm.cli", *map(str, argv)], capture_output=True, text=True,
                       timeout=timeout)
    return Outcome(p.returncode, p.stderr, p.stdout)


def one_line(err: str, notes: tuple[str, ...] = ()) -> str | None:
    """The one line of a command's answer on stderr: no traceback, an argparse usage block before it dropped, lines
    matching ``notes`` set aside; fails unless exactly one line (or, for None, none) is left."""
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    if lines and lines[0].startswith("usage:"):
        last = max(i for i, line in enumerate(lines) if ARGPARSE_ERROR.match(line))
        lines = lines[last:]
    rest = [line for line in lines if not any(re.search(n, line) for n in notes)]
    assert len(rest) <= 1, "more than one line:\n" + "\n".join(lines)
    return rest[0] if rest else None


def check(case: Case, ws: Workspace) -> Outcome:
    """Run ``case`` and assert what it promises; returns the outcome."""
    got = case.run(ws)
    line = one_line(got.err, case.notes)
    assert got.code == case.code, (got.code, got.err[-2000:])
    if case.message is None:
        assert line is None, line
    else:
        assert line is not None and re.search(case.message, line), line
    for note in case.notes:
        assert any(re.search(note, x) for x in got.err.splitlines()), (note, got.err)
    return got


# -- what "nothing lost" means ----------------------------------------------------------------------------------------

def snapshot(folder: Path) -> dict:
    """{relative path: (size, mtime)} of every file below ``folder`` but its lock file."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name != "jaxarm.lock"}


def same_results(a: Path, b: Path) -> None:
    ra, rb = (json.loads((f / "results.json").read_text()) for f in (a, b))
    assert ra["networks"] == rb["networks"] and ra["naive"] == rb["naive"] and ra["history"] == rb["history"]
    with np.load(a / "trajectories.npz") as ta, np.load(b / "trajectories.npz") as tb:
        for k in ta.files:
            np.testing.assert_array_equal(ta[k], tb[k], err_msg=k)


def resumes_to_reference(ws: Workspace, folder: Path) -> None:
    """The reference's own command, rerun on ``folder``, ends with the reference's results."""
    done = cli(["train", *TINY, "--out", str(folder)])
    assert done.code == 0, done.err
    same_results(ws.reference(), folder)


def checkpoint_steps(folder: Path) -> list[str]:
    return sorted(p.name for p in (folder / "checkpoints").iterdir())


@contextlib.contextmanager
def lock_held_by_another_process(folder: Path):
    """A live process (not this one) holding ``folder``'s lock as `jaxarm train` does; yields it."""
    code = ("import sys, time\nfrom jaxarm.runfolder import FolderLock\n"
            "FolderLock(sys.argv[1], 'jaxarm train').acquire()\nprint('held', flush=True)\ntime.sleep(600)\n")
    folder.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen([sys.executable, "-c", code, str(folder)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "held"
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()


@contextlib.contextmanager
def lock_held_here(folder: Path):
    """``folder``'s lock held through another open file of this process (flock locks exclude each other per open
    file, within one process too)."""
    from jaxarm.runfolder import FolderLock

    folder.mkdir(parents=True, exist_ok=True)
    with FolderLock(folder, "jaxarm train"):
        yield


@contextlib.contextmanager
def unwritable_folder(ws: Workspace):
    """A folder no file can be written in: read-only by its mode, or for root (whom modes do not stop) a read-only
    tmpfs mounted on it; skipped where neither can be made."""
    folder = ws.fresh("read-only")
    folder.mkdir(parents=True)
    if os.geteuid() != 0:
        folder.chmod(0o555)
        try:
            yield folder
        finally:
            folder.chmod(0o755)
        return
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(folder)],
                      capture_output=True).returncode != 0:
        pytest.skip("running as root without mount: no folder can be made unwritable")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], capture_output=True)


@contextlib.contextmanager
def free_space(nbytes: int):
    """The output folder's file system reports ``nbytes`` free (what ``shutil.disk_usage`` says on a full disk)."""
    with mock.patch("jaxarm.runfolder.free_bytes", lambda path: nbytes):
        yield


@contextlib.contextmanager
def file_size_limit_at_step(step: int, limit: int = 256 * 1024):
    """While checkpoint ``step`` is written, no file may grow past ``limit`` bytes (RLIMIT_FSIZE; Python ignores
    SIGXFSZ, so the write fails with EFBIG inside orbax's TensorStore, as a full disk fails it with ENOSPC)."""
    from jaxarm.checkpoint import Checkpointer

    real = Checkpointer.save

    def save(self, s, state, meta):
        if int(s) != step:
            return real(self, s, state, meta)
        soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
        try:
            return real(self, s, state, meta)
        finally:
            resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))

    with mock.patch.object(Checkpointer, "save", save):
        yield


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- the cases ------------------------------------------------------------------------------------------------------

def _out_empty(ws):
    return cli(["train", *TINY, "--out", ""])


def _out_is_file(ws):
    f = ws.fresh("a-file")
    f.write_text("not a folder")
    got = cli(["train", *TINY, "--out", str(f)])
    assert f.read_text() == "not a folder"
    return got


def _out_below_file(ws):
    f = ws.fresh("a-file")
    f.write_text("not a folder")
    return cli(["train", *TINY, "--out", str(f / "run")])


def _out_read_only(ws):
    with unwritable_folder(ws) as ro:
        return cli(["train", *TINY, "--out", str(ro)])


def _out_below_read_only(ws):
    with unwritable_folder(ws) as ro:
        return cli(["train", *TINY, "--out", str(ro / "run")])


def _disk_full(ws):
    out = ws.fresh("disk-full")
    with free_space(0):
        got = cli(["train", *TINY, "--out", str(out)])
    assert not (out / "checkpoints").exists()
    return got


def _no_room_for_checkpoint(ws):
    out = ws.fresh("little-space")
    with free_space(3 << 20):      # 3 MB: above the full-disk floor, below one checkpoint of this run
        got = cli(["train", *TINY, "--out", str(out)])
    assert checkpoint_steps(out) == []       # refused before the first epoch
    return got


def _checkpoint_write_fails(ws):
    out = ws.fresh("write-fails")
    with file_size_limit_at_step(2):
        got = cli(["train", *TINY, "--out", str(out)])
    # the step that failed is gone, whole; the last good one is untouched and resumes to the reference's bits
    assert checkpoint_steps(out) == ["1"], checkpoint_steps(out)
    assert not (out / "jaxarm.lock").exists()
    resumes_to_reference(ws, out)
    return got


def _lock_held(ws):
    out = ws.copy_of_reference("busy")
    before = snapshot(out)
    with lock_held_by_another_process(out) as holder:
        got = cli(["train", *TINY, "--out", str(out)])
        assert f"PID {holder.pid} " in got.err
    assert snapshot(out) == before
    resumes_to_reference(ws, out)
    return got


def _lock_stale(ws):
    out = ws.copy_of_reference("stale-lock")
    with lock_held_by_another_process(out) as holder:
        holder.send_signal(signal.SIGKILL)      # killed: its lock file stays, its flock goes with it
        holder.wait()
    assert (out / "jaxarm.lock").exists()
    got = cli(["train", *TINY, "--out", str(out)])
    same_results(ws.reference(), out)
    assert not (out / "jaxarm.lock").exists()
    return got


def _lock_held_for(command: list[str]):
    def run(ws):
        out = ws.fresh(f"busy-{command[0]}")
        with lock_held_here(out):
            return cli([*command, "--out", str(out)])
    return run


def _test_into_busy(ws):
    return _lock_held_for(["test", "--from", str(ws.reference())])(ws)


def _different_run(ws):
    out = ws.copy_of_reference("other-run")
    before = snapshot(out)
    args = list(TINY)
    args[args.index("--seed") + 1] = "1"
    got = cli(["train", *args, "--out", str(out)])
    assert snapshot(out) == before
    resumes_to_reference(ws, out)
    return got


def _devices_above_cores(ws):
    import jax

    from jaxarm import parallel

    jax.devices()                # JAX started first: the case must not set this process's device count
    parallel._warned_devices = False
    return cli(["evolve", "--devices", str(parallel.usable_cores() + 62), "--list-strategies"])


def _coordinator_absent(ws):
    return cli_process(["train", *TINY, "--out", str(ws.fresh("coord")), "--coordinator", "127.0.0.1:1",
                        "--num-processes", "2", "--process-id", "1", "--coordinator-timeout", "1"])


def _coordinator_alone(ws):
    return cli_process(["train", *TINY, "--out", str(ws.fresh("coord")), "--coordinator", f"127.0.0.1:{free_port()}",
                        "--num-processes", "2", "--process-id", "0", "--coordinator-timeout", "1"])


def _coordinator_port_busy(ws):
    with socket.socket() as s:
        s.bind(("", 0))
        s.listen()
        return cli_process(["train", *TINY, "--out", str(ws.fresh("coord")), "--coordinator",
                            f"127.0.0.1:{s.getsockname()[1]}", "--num-processes", "2", "--process-id", "0"])


def _refused_on_process_0(ws):
    """Two processes on a folder another command holds: process 0 (which alone locks) is refused, and process 1,
    which would otherwise wait in its first collective until gloo's timeout and a traceback, stops with it."""
    out = ws.copy_of_reference("busy-2")
    before = snapshot(out)
    port = free_port()
    argv = ["train", *TINY, "--out", str(out), "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2",
            "--devices", "1", "--process-id"]
    with lock_held_by_another_process(out) as holder:
        first = subprocess.Popen([sys.executable, "-m", "jaxarm.cli", *argv, "0"], stderr=subprocess.PIPE, text=True)
        got = cli_process([*argv, "1"], timeout=60)
        err0 = first.communicate(timeout=60)[1]
        assert first.returncode == 2 and one_line(err0).startswith("jaxarm train: --out ") and \
            f"PID {holder.pid} " in err0, err0
        assert f"PID {holder.pid} " in got.err
    assert snapshot(out) == before
    resumes_to_reference(ws, out)
    return got


def _damaged(command: str, file: str, damage: str, *extra: str):
    """``jaxarm COMMAND`` on a copy of the reference run whose ``file`` is damaged (``damage``: garbage, {},
    random bytes, truncated, empty)."""
    def run(ws):
        folder = ws.copy_of_reference(f"{command}-{Path(file).stem}-{damage.replace(' ', '-')}")
        path = folder / file
        data = path.read_bytes()
        path.write_bytes({"garbage": b"{not json", "{}": b"{}", "random bytes": np.random.default_rng(0).bytes(4096),
                          "truncated": data[: len(data) * 9 // 10], "empty": b""}[damage])
        out = folder / "figures-out" if command == "figures" else folder / "video.mp4"
        got = cli([command, str(folder), "--out", str(out), *extra])
        assert not out.exists() or not any(out.glob("*.png"))       # answered before anything was drawn
        return got
    return run


def _bad_robot_log(command: str, content: bytes):
    def run(ws):
        log = ws.fresh("robot-log.csv")
        log.write_bytes(content)
        out = ws.fresh("figures-out")
        got = cli([command, str(ws.reference()), "--robot-log", str(log), "--out",
                   str(out if command == "figures" else out.with_suffix(".mp4"))])
        assert not out.exists() and not out.with_suffix(".mp4").exists()      # no PNG, no video before the answer
        return got
    return run


def _trajectory_csv(ws, name: str, rows: np.ndarray) -> Path:
    path = ws.fresh(name).with_suffix(".csv")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("t,shoulder,elbow\n" + "".join(f"{t:.4f},{s:.6f},{e:.6f}\n" for t, s, e in rows))
    return path


def _strict_json(path: Path) -> dict:
    def refuse(constant):
        raise AssertionError(f"{path}: bare {constant} is not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def _export_three_rows(ws):
    csv = _trajectory_csv(ws, "three-rows", np.array([[0.0, 0.5, 1.0], [0.01, 0.5, 1.0], [0.02, 0.51, 1.0]]))
    report = csv.with_suffix(".json")
    got = cli(["export", "--trajectory", str(csv), "--to", "offline", "--report", str(report)])
    jerk = _strict_json(report)["dimensionless_jerk"]
    assert jerk["virtual"] is None       # 3 samples: no jerk
    got.shown = f"(none) report written; dimensionless_jerk.virtual: {json.dumps(jerk['virtual'])}"
    return got


def _export_fifty_rad(ws):
    t = np.arange(200) * 0.01
    csv = _trajectory_csv(ws, "fifty-rad", np.column_stack([t, 50 * (-1) ** np.arange(200), -50 * np.ones(200)]))
    report = csv.with_suffix(".json")
    got = cli(["export", "--trajectory", str(csv), "--to", "offline", "--report", str(report)])
    assert not report.exists()
    return got


def _export_constant(ws):
    t = np.arange(200) * 0.01
    csv = _trajectory_csv(ws, "constant", np.column_stack([t, np.full(200, 0.4), np.full(200, 1.2)]))
    report = csv.with_suffix(".json")
    got = cli(["export", "--trajectory", str(csv), "--to", "offline", "--report", str(report)])
    r = _strict_json(report)
    assert r["dimensionless_jerk"]["virtual"] is None and r["delay_ms"]["windowed"]["shoulder"]["mean"] is None
    got.shown = ("(none) report written; dimensionless_jerk.virtual: null, delay_ms.windowed.shoulder.mean: null "
                 "(was bare NaN)")
    return got


def _export_truncated_npz(ws):
    folder = ws.copy_of_reference("export-truncated")
    path = folder / "trajectories.npz"
    path.write_bytes(path.read_bytes()[:-200])
    return cli(["export", "--trajectory", str(folder), "--to", "offline"])


def _test_from_nothing(ws):
    return cli(["test", "--from", str(ws.fresh("empty"))])


REPRODUCE = ["reproduce", "--arm", "simple", "--preset", "original", "--targets", "left", "--networks", "1", "--top",
             "1", "--epochs", "1", "--epoch-s", "0.1", "--test-s", "0.1", "--no-progress"]
EVOLVE = ["evolve", "--arm", "simple", "--targets", "left", "--population", "4", "--generations", "1", "--train-s",
          "0.1"]
RERANK = ["rerank", "--arm", "simple", "--target", "left", "--pool", "original", "--seeds", "1", "--epochs", "1",
          "--epoch-s", "0.1", "--test-s", "0.1", "--no-progress"]
BUSY = (r"--out .*: in use by jaxarm train \(PID \d+ on host [^,]+, since [^)]+\); wait for it to end or give "
        r"another --out")
STALE = r"jaxarm: note: .*jaxarm.lock: taking over the lock of jaxarm train \(PID \d+ .*no longer running"
OUT_DEVICE = r"jaxarm: warning: --devices \d+ is more than the \d+ core\(s\) this process may use"

CASES = [
    # the output folder
    Case("`train --out \"\"`", _out_empty, 2, r"argument --out: must name a folder, not be empty", group="folder"),
    Case("`train --out FILE` (an existing file)", _out_is_file, 2, r"--out .*: is a file, not a folder",
         group="folder"),
    Case("`train --out FILE/run` (below a file)", _out_below_file, 2, r"--out .*: cannot create it",
         group="folder"),
    Case("`train --out DIR`, DIR read-only", _out_read_only, 2,
         r"--out .*: cannot write there: (Read-only file system|Permission denied)", group="folder"),
    Case("`train --out DIR/run`, DIR read-only", _out_below_read_only, 2,
         r"--out .*: cannot create it: (Read-only file system|Permission denied)", group="folder"),
    Case("`train` on a full disk (0 bytes free)", _disk_full, 2, r"--out .*: its file system is full \(0\.0 MB free\)",
         group="folder"),
    Case("`train` with 3 MB free, less than one checkpoint", _no_room_for_checkpoint, 2,
         r"--out .*: 3\.0 MB free on its file system, and the next checkpoint needs about [\d.]+ MB", group="folder"),
    Case("checkpoint 2 cannot be written (file-size limit: EFBIG, as ENOSPC)", _checkpoint_write_fails, 2,
         r"cannot write checkpoint step 2 in .*: File too large; the last good checkpoint \(step 1\) is intact",
         group="folder"),
    Case("second `train` on a folder another process holds", _lock_held, 2, BUSY, group="lock"),
    Case("`train` on a folder whose holder was killed (stale lock)", _lock_stale, 0, None, notes=(STALE,),
         group="lock"),
    Case("`reproduce` on a folder in use", _lock_held_for(REPRODUCE), 2, BUSY, group="lock"),
    Case("`evolve` on a folder in use", _lock_held_for(EVOLVE), 2, BUSY, group="lock"),
    Case("`rerank` on a folder in use", _lock_held_for(RERANK), 2, BUSY, group="lock"),
    Case("`train` into a folder of another run (`--seed 1`)", _different_run, 1,
         r"holds a different run: seed saved 0, now 1; give the same options to resume it", group="lock"),
    # options
    Case("`train --epochs 0`", lambda ws: cli(["train", "--epochs", "0", "--out", str(ws.fresh("e0"))]), 2,
         r"--epochs = 0: must be >= 1", group="options"),
    Case("`train --target left left`",
         lambda ws: cli(["train", "--target", "left", "left", "--out", str(ws.fresh("tt"))]), 2,
         r"--target left left: left given more than once; give each target once", group="options"),
    Case("`--devices` above the usable cores", _devices_above_cores, 0, None, notes=(OUT_DEVICE,), group="options"),
    Case("`train --devices 0`", lambda ws: cli(["train", "--devices", "0", "--out", str(ws.fresh("d0"))]), 2,
         r"--devices = 0: must be >= 1", group="options"),
    Case("`train --networks 0`", lambda ws: cli(["train", "--networks", "0", "--out", str(ws.fresh("n0"))]), 2,
         r"--networks = 0: must be in \[1, 4096\]", group="options"),
    Case("`train --set v_em_max=5` (outside its bounds)",
         lambda ws: cli(["train", "--set", "v_em_max=5", "--out", str(ws.fresh("set"))]), 2,
         r"--set v_em_max = 5 is outside its range", group="options"),
    # several processes
    Case("`--coordinator-timeout 0`",
         lambda ws: cli(["train", "--coordinator-timeout", "0", "--out", str(ws.fresh("ct"))]), 2,
         r"--coordinator-timeout = 0: must be in \(0, 86400\] s", group="processes"),
    Case("`--coordinator` without `--process-id`",
         lambda ws: cli(["train", "--coordinator", "127.0.0.1:1", "--num-processes", "2", "--out",
                         str(ws.fresh("c"))]), 2,
         r"--coordinator, --num-processes and --process-id go together", group="processes"),
    Case("process 1 of 2, no coordinator at the address (1 s timeout)", _coordinator_absent, 2,
         r"--coordinator 127\.0\.0\.1:1: process 1 of 2 could not join within 1 s", group="processes"),
    Case("process 0 of 2, the other never starts (1 s timeout)", _coordinator_alone, 2,
         r"--coordinator 127\.0\.0\.1:\d+: process 0 waited 1 s and not all 2 processes joined", group="processes"),
    Case("process 0, the coordinator's port in use", _coordinator_port_busy, 2,
         r"--coordinator 127\.0\.0\.1:\d+: process 0 cannot listen on port \d+ \(Address already in use\)",
         group="processes"),
    # reading a run folder
    Case("`figures`, results.json garbage", _damaged("figures", "results.json", "garbage"), 2,
         r"results\.json: not valid JSON", group="readers"),
    Case("`figures`, results.json `{}`", _damaged("figures", "results.json", "{}"), 2,
         r"results\.json: lacks config", group="readers"),
    Case("`figures`, trajectories.npz random bytes", _damaged("figures", "trajectories.npz", "random bytes"), 2,
         r"trajectories\.npz: not an \.npz archive \(overwritten or random bytes\)", group="readers"),
    Case("`figures`, trajectories.npz truncated", _damaged("figures", "trajectories.npz", "truncated"), 2,
         r"trajectories\.npz: a damaged \.npz archive", group="readers"),
    Case("`figures`, history.npz empty", _damaged("figures", "history.npz", "empty"), 2,
         r"history\.npz: not an \.npz archive \(empty\)", group="readers"),
    Case("`figures --robot-log` a CSV of other columns", _bad_robot_log("figures", b"a,b\n1,2\n"), 2,
         r"--robot-log .*: lacks the column\(s\) t, target_shoulder", group="readers"),
    Case("`figures --robot-log` binary bytes",
         _bad_robot_log("figures", np.random.default_rng(1).bytes(600)), 2,
         r"--robot-log .*: not (a text CSV|a CSV of numbers)", group="readers"),
    Case("`video`, results.json `{}`", _damaged("video", "results.json", "{}"), 2, r"results\.json: lacks config",
         group="readers"),
    Case("`video`, trajectories.npz truncated", _damaged("video", "trajectories.npz", "truncated"), 2,
         r"trajectories\.npz: a damaged \.npz archive", group="readers"),
    Case("`video --robot-log` with a word among the numbers",
         _bad_robot_log("video", b"t,target_shoulder,target_elbow,robot_shoulder,robot_elbow,new_target\n"
                                 b"0,1,x,1,1,1\n"), 2,
         r"--robot-log .*: not a CSV of numbers below its header", group="readers"),
    Case("`test --from` a folder without checkpoints", _test_from_nothing, 2, r"--from .*: no checkpoints/ folder",
         group="readers"),
    # the robot
    Case("`export --to offline`, a 3-row CSV", _export_three_rows, 0, None, group="robot"),
    Case("`export --to offline`, angles of +-50 rad", _export_fifty_rad, 2,
         r"--trajectory .*: the simulated robot took none of its 200 packets \(out_of_range 200", group="robot"),
    Case("`export --to offline`, a constant trajectory", _export_constant, 0, None, group="robot"),
    Case("`export --trajectory` a run folder, trajectories.npz truncated", _export_truncated_npz, 2,
         r"--trajectory .*trajectories\.npz: a damaged \.npz archive", group="robot"),
    Case("`export --trajectory` a missing file",
         lambda ws: cli(["export", "--trajectory", str(ws.fresh("missing.csv")), "--to", "offline"]), 2,
         r"--trajectory .*missing\.csv: .*No such file", group="robot"),
    Case("`test` writing into a folder in use", _test_into_busy, 2, BUSY, group="lock"),
    Case("process 1 of 2 when process 0 is refused (its folder in use)", _refused_on_process_0, 2,
         r"--out .*: in use by jaxarm train .* \[process 0 of 2; process 1 stops with it\]$", group="processes"),
]


@pytest.fixture(scope="module")
def ws(tmp_path_factory):
    return Workspace(tmp_path_factory.mktemp("faults"))


# a checkpoint write failed in this process leaves orbax's pending writes behind; at garbage collection they say
# "Event loop is closed" (the command line silences that as its process ends)
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("case", [c for c in CASES if not c.slow], ids=lambda c: re.sub(r"\W+", "-", c.name)[:60])
def test_fault_answers_in_one_line(case, ws):
    check(case, ws)


def test_at_least_30_cases():
    assert len(CASES) >= 30


@pytest.mark.slow   # two real `jaxarm train` processes, the second started while the first trains (about 40 s)
def test_two_train_processes_on_one_folder(tmp_path):
    out = tmp_path / "run"
    args = ["train", "--arm", "simple", "--networks", "1", "--epochs", "4", "--epoch-s", "1", "--test-s", "0.1",
            "--no-progress", "--out", str(out)]
    first = subprocess.Popen([sys.executable, "-m", "jaxarm.cli", *args], stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while not (out / "jaxarm.lock").exists():
            assert first.poll() is None and time.time() < deadline
            time.sleep(0.05)
        second = cli_process(args)
        assert second.code == 2 and re.search(rf"in use by jaxarm train \(PID {first.pid} ", one_line(second.err))
        assert first.wait(timeout=300) == 0, first.stderr.read()
    finally:
        if first.poll() is None:
            first.kill()
    assert json.loads((out / "results.json").read_text())["n_networks"] == 1


@pytest.mark.slow   # root only (a tmpfs): a real full disk in the middle of a run, then the same command resumes
def test_real_full_disk_mid_run_keeps_the_last_checkpoint(tmp_path):
    if os.geteuid() != 0:
        pytest.skip("needs root to mount a small tmpfs")
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs", str(disk)]).returncode:
        pytest.skip("cannot mount a tmpfs")
    try:
        args = ["train", "--arm", "simple", "--networks", "1", "--epochs", "3", "--epoch-s", "1", "--test-s", "0.1",
                "--no-progress", "--out", str(disk / "run")]
        run = subprocess.Popen([sys.executable, "-m", "jaxarm.cli", *args], stderr=subprocess.PIPE, text=True)
        while not (disk / "run" / "checkpoints" / "1" / "MANIFEST").exists():
            assert run.poll() is None
            time.sleep(0.02)
        with open(disk / "filler", "wb") as f:           # fill the disk
            with contextlib.suppress(OSError):
                while True:
                    f.write(b"\0" * (1 << 20))
        err = run.stderr.read()
        assert run.wait() == 2
        line = one_line(err)
        assert re.search(r"cannot write checkpoint step 2 in .*: No space left on device; the last good checkpoint "
                         r"\(step 1\) is intact", line), err
        assert checkpoint_steps(disk / "run") == ["1"]
        (disk / "filler").unlink()
        assert cli_process(args).code == 0 and checkpoint_steps(disk / "run") == ["2", "3"]
    finally:
        subprocess.run(["umount", str(disk)])


# -- the pieces, on strings and small files -----------------------------------------------------------------------

def test_cgroup_cpu_quota_parsing():
    from jaxarm.parallel import cores_from, parse_cfs_quota, parse_cgroup_path, parse_cpu_max

    assert parse_cpu_max("max 100000\n") is None
    assert parse_cpu_max("200000 100000\n") == 2.0
    assert parse_cpu_max("150000 100000") == 1.5
    assert parse_cpu_max("50000 100000") == 0.5
    assert parse_cpu_max("") is None and parse_cpu_max("garbage here") is None
    assert parse_cfs_quota("-1\n", "100000\n") is None and parse_cfs_quota("300000", "100000") == 3.0
    assert cores_from(64, None) == 64 and cores_from(64, 2.0) == 2 and cores_from(64, 1.5) == 1
    assert cores_from(64, 0.5) == 1 and cores_from(2, 8.0) == 2
    text = "12:cpu,cpuacct:/docker/abc\n3:memory:/docker/abc\n0::/system.slice/job.scope\n"
    assert parse_cgroup_path(text) == "/system.slice/job.scope"
    assert parse_cgroup_path(text, "cpu") == "/docker/abc" and parse_cgroup_path("0::/\n") == "/"
    assert parse_cgroup_path("1:name=systemd:/\n") is None


def test_cgroup_cpu_limit_takes_the_smallest_quota_up_the_tree(tmp_path):
    from jaxarm.parallel import cgroup_cpu_limit

    root = tmp_path / "cgroup"
    (root / "a" / "b").mkdir(parents=True)
    (root / "cpu.max").write_text("max 100000\n")
    (root / "a" / "cpu.max").write_text("300000 100000\n")
    (root / "a" / "b" / "cpu.max").write_text("max 100000\n")
    proc = tmp_path / "cgroup-of-self"
    proc.write_text("0::/a/b\n")
    assert cgroup_cpu_limit(str(root), str(proc)) == 3.0
    proc.write_text("0::/\n")
    assert cgroup_cpu_limit(str(root), str(proc)) is None
    (root / "cpu" / "x").mkdir(parents=True)                     # cgroup v1
    (root / "cpu" / "x" / "cpu.cfs_quota_us").write_text("200000\n")
    (root / "cpu" / "x" / "cpu.cfs_period_us").write_text("100000\n")
    proc.write_text("4:cpu,cpuacct:/x\n0::/\n")
    assert cgroup_cpu_limit(str(root), str(proc)) == 2.0


def test_different_run_names_the_fields_that_differ():
    from jaxarm.run import describe_differences

    saved = {"epochs": 12, "seed": 0, "metaparams": {"learn_rate": 0.1, "v_em_max": 40.0}, "kernel": "native"}
    now = {"epochs": 6, "seed": 0, "metaparams": {"learn_rate": 0.2, "v_em_max": 40.0}, "kernel": "native",
           "dt_ms": 0.1}
    assert describe_differences(saved, now) == ("epochs saved 12, now 6; metaparams.learn_rate saved 0.1, now 0.2; "
                                                "dt_ms saved (absent), now 0.1")
    many = describe_differences({f"k{i}": i for i in range(6)}, {f"k{i}": -i - 1 for i in range(6)})
    assert many.endswith("; and 2 more field(s)")


def test_a_lock_without_flock_falls_back_to_the_pid(tmp_path, monkeypatch):
    """On a file system without flock (some network mounts) the lock file's PID decides: a live holder on this host
    refuses, a dead one is taken over."""
    import errno
    import fcntl

    from jaxarm.config.validate import ConfigError
    from jaxarm.runfolder import LOCK_FILE, FolderLock

    def no_flock(fd, op):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(fcntl, "flock", no_flock)
    lock = tmp_path / LOCK_FILE
    lock.write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "command": "jaxarm evolve"}))
    with pytest.raises(ConfigError, match=rf"in use by jaxarm evolve \(PID {os.getpid()} on host"):
        FolderLock(tmp_path, "jaxarm train").acquire()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    lock.write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname(), "command": "jaxarm evolve"}))
    notes = []
    with FolderLock(tmp_path, "jaxarm train", warn=notes.append):
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert "no longer running" in notes[0] and not lock.exists()
