"""`jaxarm rerank`: a pool of sets trained on fresh seeds and ranked by how often they reach.

Kept fast like test_reproduce.py: the simple arm, one epoch of 0.2 s and a 0.2 s test (no network reaches in that
time, so the checks are on the closest approach, which differs between every set and seed).
"""
import json

import numpy as np
import pytest

from jaxarm.cli import main
from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import ORIGINAL
from jaxarm.paper import presets
from jaxarm.paper.rerank import RANKING_FILE, preset_from_ranking, rank

TINY = ["--arm", "simple", "--target", "left", "--epochs", "1", "--epoch-s", "0.2", "--test-s", "0.2",
        "--no-progress"]
OTHER = {**ORIGINAL, "learn_rate": 0.05, "em_noise_rate_test_hz": 300.0}


@pytest.fixture(scope="module")
def preset_dir(tmp_path_factory):
    """A preset whose best set is also its top[0] (kept once in the pool) and a second set."""
    d = tmp_path_factory.mktemp("presets")
    presets.save(presets.Preset(name="two", description="", arms=("simple",), best=ORIGINAL,
                                top=({"metaparams": ORIGINAL}, {"metaparams": OTHER})), d)
    return d


@pytest.fixture(scope="module")
def first(preset_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("rerank") / "first"
    assert main(["rerank", *TINY, "--pool", "two", "--preset-dir", str(preset_dir), "--seeds", "2",
                 "--first-seed", "500", "--out", str(out)]) == 0
    return out


def test_each_sets_results_are_a_separate_train_of_that_set(first, tmp_path):
    """The ranking's per-seed results equal `jaxarm train` of each set alone with the same seeds (one batch of
    sets x seeds computes every network as a run of that network alone)."""
    table = json.loads((first / RANKING_FILE).read_text())
    assert len(table["sets"]) == 2 and table["protocol"]["seeds"] == [500, 501]
    by_source = {r["source"]: r for r in table["sets"]}
    assert set(by_source) == {"two best", "two top[1]"}
    for source, mp in (("two best", ORIGINAL), ("two top[1]", OTHER)):
        out = tmp_path / source.replace(" ", "_")
        args = [f"{k}={v}" for k, v in mp.items() if k != "epochs"]
        assert main(["train", "--arm", "simple", "--target", "left", "--networks", "2", "--seed", "500",
                     "--epochs", "1", "--epoch-s", "0.2", "--test-s", "0.2", "--no-progress", "--out", str(out),
                     *sum((["--set", a] for a in args), [])]) == 0
        nets = json.loads((out / "results.json").read_text())["networks"]
        row = by_source[source]
        (run,) = row["runs"]
        assert run["seeds"] == [500, 501]
        assert run["success"] == [n["success"] for n in nets]
        assert run["min_distance_m"] == [n["min_distance_m"] for n in nets]
        assert run["distance_after_m"] == [n["distance_after_m"] for n in nets]
        assert row["n"] == 2 and row["mean_min_distance_m"] == pytest.approx(np.mean(run["min_distance_m"]), abs=1e-5)
    # ranked by closest approach when no set reaches
    d = [r["mean_min_distance_m"] for r in table["sets"]]
    assert d == sorted(d) and [r["rank"] for r in table["sets"]] == [1, 2]


def test_a_second_stage_adds_seeds_and_refuses_reused_ones(first, preset_dir, tmp_path, capsys):
    second = tmp_path / "second"
    assert main(["rerank", *TINY, "--pool", str(first), "--best", "1", "--seeds", "1", "--first-seed", "501",
                 "--out", str(second)]) == 2
    assert "--first-seed = 501: seeds 501..501 already tested" in capsys.readouterr().err
    command = ["rerank", *TINY, "--pool", str(first), "--best", "1", "--seeds", "1", "--first-seed", "502",
               "--out", str(second)]
    assert main(command) == 0
    ranked = (second / RANKING_FILE).read_text()
    capsys.readouterr()
    # the same command again with --make-preset reuses the finished ranking (nothing trained, the file unchanged)
    assert main(command + ["--make-preset", "two-ranked", "--preset-dir", str(preset_dir)]) == 0
    assert "finished earlier, reused" in capsys.readouterr().out and (second / RANKING_FILE).read_text() == ranked
    before = json.loads((first / RANKING_FILE).read_text())["sets"][0]
    (row,) = json.loads((second / RANKING_FILE).read_text())["sets"]
    assert row["metaparams"] == before["metaparams"] and row["source"] == before["source"]
    assert row["runs"][0] == before["runs"][0] and row["runs"][1]["seeds"] == [502] and row["n"] == 3
    p = presets.load("two-ranked", preset_dir)
    assert p.best == presets.check_metaparams(row["metaparams"], "x")
    assert p.targets == ("left",) and p.protocol["epochs"] == 1 and len(p.top) == 1
    assert p.provenance["source"] == "jaxarm rerank" and p.provenance["command"].startswith("jaxarm rerank")
    assert p.provenance["pool"][0]["ranking"] == str(first)
    assert main(["rerank", "--make-preset", "again", "--from-rerank", str(second), "--preset-dir",
                 str(preset_dir)]) == 0
    assert presets.load("again", preset_dir).top == p.top


def test_rank_orders_by_rate_over_every_run_then_closest_approach():
    def s(name, *runs):
        return {"metaparams": {}, "source": name,
                "runs": [{"seeds": list(range(len(ok))), "success": ok, "min_distance_m": d} for ok, d in runs]}

    ranked = rank([s("a", ([True, False], [0.01, 0.1])),                                # 1/2
                   s("b", ([True, True], [0.03, 0.03]), ([False, True], [0.1, 0.02])),  # 3/4, far
                   s("c", ([True, True, True, False], [0.01, 0.01, 0.01, 0.05])),      # 3/4, closer
                   s("d", ([True, False], [0.01, 0.1]))])                               # 1/2, tie with a: pool order
    assert [r["source"] for r in ranked] == ["c", "b", "a", "d"]
    assert [(r["successes"], r["n"]) for r in ranked] == [(3, 4), (3, 4), (1, 2), (1, 2)]
    assert ranked[1]["mean_min_distance_m"] == pytest.approx(0.045)
    # by staying: among equal rates, the smaller mean distance after entry (over the entered networks) first
    def t(name, after):
        return {"metaparams": {}, "source": name, "runs": [{"seeds": [0, 1], "success": [True, True],
                                                            "min_distance_m": [0.01, 0.01], "distance_after_m": after}]}

    stay = rank([t("far", [0.06, 0.05]), t("near", [0.03, 0.04]), t("tie-with-near", [0.02, 0.05])],
                by="stay")
    assert [r["source"] for r in stay] == ["near", "tie-with-near", "far"]
    assert stay[0]["mean_distance_after_m"] == pytest.approx(0.035)
    with pytest.raises(ConfigError, match="--rank-by = 'x'"):
        rank([], by="x")


def test_bad_input_is_one_clear_line(tmp_path, capsys):
    assert main(["rerank", *TINY, "--pool", "no-such-preset", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("jaxarm rerank: --pool 'no-such-preset': neither") and "\n" not in err
    assert main(["rerank", *TINY, "--pool", "original", "--seeds", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--seeds = 0: must be in [1, 1024]" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="ranking.json not found"):
        preset_from_ranking(tmp_path, "x")


@pytest.mark.slow   # the paper's full protocol: 12 epochs of 30 s, 4 networks ranked and 2 trained alone (~70 s)
def test_a_ranking_at_full_length_equals_training_each_set_alone(preset_dir, tmp_path):
    """At the paper's length too (12 epochs of 30 s, 1 s test), a set's networks in a ranking's batch, where they
    sit at other places of their group than when trained alone, end exactly as when each set trains alone: since
    XLA computes without fused multiply-add (jaxarm.cpu_arithmetic) a network's bits do not depend on its place
    (before, networks at places 0 and 4 drifted apart over a full protocol)."""
    full = ["--arm", "simple", "--target", "left", "--epochs", "12", "--epoch-s", "30", "--test-s", "1",
            "--no-progress"]
    out = tmp_path / "ranking"
    assert main(["rerank", *full, "--pool", "two", "--preset-dir", str(preset_dir), "--seeds", "2",
                 "--first-seed", "700", "--out", str(out)]) == 0
    by_source = {r["source"]: r for r in json.loads((out / RANKING_FILE).read_text())["sets"]}
    for source, mp in (("two top[1]", OTHER),):   # the second set: places 2-3 of the ranking's group, 0-1 alone
        alone = tmp_path / source.replace(" ", "_")
        sets = sum((["--set", f"{k}={v}"] for k, v in mp.items() if k != "epochs"), [])
        assert main(["train", *full, "--networks", "2", "--seed", "700", "--out", str(alone), *sets]) == 0
        nets = json.loads((alone / "results.json").read_text())["networks"]
        (run,) = by_source[source]["runs"]
        assert run["seeds"] == [700, 701]
        assert run["min_distance_m"] == [n["min_distance_m"] for n in nets]
        assert run["success"] == [n["success"] for n in nets]
        assert run["distance_after_m"] == [n["distance_after_m"] for n in nets]
