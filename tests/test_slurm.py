"""The docs' SLURM recipe: the page shows the script that is submitted, its numbers fill their groups, and (slow suite)
it runs under a real one-machine SLURM (experiments/slurm_local.sh) to the same bits as one process."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
RECIPE = ROOT / "experiments" / "slurm_evolve.sbatch"
SCRIPT = ROOT / "experiments" / "slurm_local.sh"
CANNOT_START = 77     # experiments/slurm_local.sh: SLURM cannot start here


def _section(page: str, title: str) -> str:
    text = (ROOT / "docs" / page).read_text()
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def test_the_docs_show_the_recipe_that_is_submitted():
    """docs/scaling.md's SLURM recipe is experiments/slurm_evolve.sbatch, character for character, and its log goes
    to a folder that exists when SLURM opens it (the submit folder; `runs/...` failed unless runs/ existed)."""
    blocks = re.findall(r"```bash\n(.*?)```", _section("scaling.md", "A SLURM cluster"), re.S)
    assert blocks and blocks[0] == RECIPE.read_text()
    output = re.search(r"^#SBATCH --output=(\S+)$", RECIPE.read_text(), re.M).group(1)
    assert "/" not in output


def test_the_recipes_numbers_fill_their_groups():
    """Nodes x tasks per node x CPUs per task devices, jaxarm.parallel.CPU_NETWORKS_AT_ONCE networks each at once:
    a generation's candidates x seeds is a whole number of such rounds, so nothing is padding; in the groups of 8
    of `--networks-at-once 8` too."""
    from jaxarm import parallel

    text = RECIPE.read_text()
    sbatch = dict(re.findall(r"^#SBATCH --([\w-]+)=(\S+)$", text, re.M))
    command = " ".join(line.rstrip("\\") for line in text[text.index("\nsrun "):].splitlines())
    option = lambda name: int(re.search(rf"--{name} (\d+)", command).group(1))      # noqa: E731
    devices = int(sbatch["nodes"]) * int(sbatch["ntasks-per-node"]) * int(sbatch["cpus-per-task"])
    evaluations = option("population") * option("seeds-per-candidate")
    assert evaluations % (devices * parallel.CPU_NETWORKS_AT_ONCE) == 0
    for at_once in (parallel.CPU_NETWORKS_AT_ONCE, 8):
        assert evaluations % (devices * at_once) == 0
        assert parallel.padding_note(evaluations, "g", devices, at_once).endswith("no padding)" if at_once > 1 else "no padding")


def _fake_run(folder: Path, fitness: np.ndarray, meta: dict) -> None:
    import orbax.checkpoint as ocp

    folder.mkdir(parents=True)
    (folder / "history.json").write_text(json.dumps({"history": {"best": [float(fitness[0])]}}))
    (folder / "top_k.json").write_text(json.dumps({"top_k": [{"fitness": float(fitness[0])}]}))
    step = folder / "checkpoints" / "1"
    step.mkdir(parents=True)
    with ocp.StandardCheckpointer() as ckpt:
        ckpt.save(step / "state", {"fitness": fitness, "generation": np.int32(1)})
    (step / "meta").mkdir()
    (step / "meta" / "metadata").write_text(json.dumps(meta))


def test_the_comparison_sees_one_bit_and_ignores_only_timings(tmp_path):
    """experiments/slurm_local_compare.py: the same arrays and meta (timings aside) are identical; the last bit of
    one checkpointed float, not written in the JSON files, is a difference."""
    sys.path.insert(0, str(ROOT / "experiments"))
    try:
        from slurm_local_compare import compare
    finally:
        sys.path.remove(str(ROOT / "experiments"))
    x = np.array([0.25, 1.5], np.float32)
    y = x.copy()
    y.view(np.uint32)[1] ^= 1
    _fake_run(tmp_path / "a", x, {"costs": {"compile_s": 1.0, "evaluations": 4}})
    _fake_run(tmp_path / "b", x, {"costs": {"compile_s": 2.0, "evaluations": 4}})
    _fake_run(tmp_path / "c", y, {"costs": {"compile_s": 1.0, "evaluations": 5}})
    same = compare(tmp_path / "a", tmp_path / "b")
    assert all(v["identical"] for v in same.values()) and same["checkpoint 1 state"]["arrays"] == 2
    other = compare(tmp_path / "a", tmp_path / "c")
    assert other["history.json history"]["identical"] and other["top_k.json"]["identical"]
    assert other["checkpoint 1 state"] == {"identical": False, "arrays": 2, "bytes": 12, "differ": ["['fitness']"]}
    assert not other["checkpoint 1 meta"]["identical"]


@pytest.mark.slow
def test_the_recipe_under_a_real_slurm_gives_the_bits_of_one_process(tmp_path):
    """experiments/slurm_local.sh: a one-machine SLURM from Debian's packages runs the docs' recipe, scaled to 2 tasks
    of 1 CPU, with sbatch; its two processes join through jax.distributed from SLURM's environment and give the same
    history, top-k and checkpoints as one process. Skipped, with the script's one-line reason, where SLURM cannot
    start (not root and no passwordless sudo, no apt-get, the packages not to be had, a daemon that does not
    start)."""
    result = tmp_path / "slurm_local.json"
    env = dict(os.environ, PYTHON=sys.executable, WORK=str(tmp_path / "work"))
    env = {k: v for k, v in env.items() if not k.startswith("SLURM_")}
    proc = subprocess.Popen(["bash", str(SCRIPT), "--result", str(result)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=env)
    try:
        out = proc.communicate(timeout=1800)[0]
    except subprocess.TimeoutExpired:
        proc.terminate()            # the script cancels the job and stops its daemons on TERM
        out = proc.communicate(timeout=120)[0]
        pytest.fail(f"experiments/slurm_local.sh ran over 30 min:\n{out[-6000:]}")
    if proc.returncode == CANNOT_START:
        reason = next((ln for ln in out.splitlines() if "cannot start SLURM" in ln), out.strip()[-300:])
        pytest.skip(reason)
    assert proc.returncode == 0, out[-6000:]
    record = json.loads(result.read_text())
    assert record["identical"] and record["slurm"]["job_status"] == 0
    assert any(k.startswith("checkpoint") and k.endswith("state") for k in record["comparison"])
    # the job's processes met through SLURM's environment: 2 processes of 1 device, 8 x 2 evaluations, no padding
    assert "on 2 devices of 2 processes one network at a time, no padding" in record["slurm"]["log_text"]
