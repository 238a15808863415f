"""`jaxarm reproduce` and the metaparameter presets.

Kept fast the way test_closed_loop.py keeps `jaxarm train` fast: the simple arm, 2 networks, one target, 2 epochs
of 0.2 s and a 0.2 s test. Every run below uses that one loop configuration, so the compiled functions are shared.
"""
import json
import re
import shlex

import pytest

from jaxarm.cli import main
from jaxarm.config.validate import ConfigError
from jaxarm.paper import presets
from jaxarm.learning.metaparams import BOUNDS, NAMES, ORIGINAL, MetaParams

TINY = ["--arm", "simple", "--targets", "left", "--networks", "2", "--epochs", "2", "--epoch-s", "0.2",
        "--test-s", "0.2", "--no-progress"]
TABLE_KEYS = {"seeds", "seeds_n", "top30", "top30_n", "top30_note", "seeds_median_min_distance_m",
              "seeds_median_final_distance_m", "top30_median_min_distance_m", "paper", "paper_n"}


@pytest.fixture(scope="module")
def search(tmp_path_factory):
    """A finished (tiny) search: `jaxarm evolve --fitness quadratic`, the real top_k.json/history.json format."""
    out = tmp_path_factory.mktemp("search")
    assert main(["evolve", "--fitness", "quadratic", "--strategy", "SimpleGA", "--population", "4",
                 "--generations", "1", "--chunk", "1", "--top-k", "3", "--arm", "simple", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def preset_dir(search, tmp_path_factory):
    d = tmp_path_factory.mktemp("presets")
    assert main(["reproduce", "--make-preset", "quad", "--from-search", str(search), "--preset-dir", str(d)]) == 0
    return d


def test_list_presets_original_first(capsys, preset_dir):
    assert main(["reproduce", "--list-presets", "--preset-dir", str(preset_dir)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[0] == "original"
    assert [ln.split()[0] for ln in lines] == ["original", "quad"]


def test_original_preset_is_the_published_values():
    p = presets.load("original")
    assert p.best == ORIGINAL and p.top == ()
    assert p.best_metaparams().to_dict() == MetaParams.original().to_dict()
    assert "main.hoc" in p.provenance["source"]


def test_unknown_preset_is_a_clear_error(capsys, tmp_path):
    with pytest.raises(ConfigError, match="unknown preset 'nope'; known: original"):
        presets.load("nope", tmp_path)
    assert main(["reproduce", "--preset", "nope", "--out", str(tmp_path / "o"), "--preset-dir", str(tmp_path),
                 *TINY]) == 2
    assert "unknown preset 'nope'; known: original" in capsys.readouterr().err


def test_preset_validation_names_field_and_range():
    with pytest.raises(ConfigError, match=r"best.learn_rate = 0.5 is out of range; allowed \[0.001, 0.2\]"):
        presets.Preset(name="x", description="", arms=("simple",), best={**ORIGINAL, "learn_rate": 0.5})
    with pytest.raises(ConfigError, match="missing explore_tot"):
        presets.Preset(name="x", description="", arms=("simple",), best={k: ORIGINAL[k] for k in NAMES if k != "explore_tot"})
    with pytest.raises(ConfigError, match=r"top\[1\].v_em_max"):
        presets.Preset(name="x", description="", arms=("simple",), best=ORIGINAL,
                       top=({"metaparams": ORIGINAL}, {"metaparams": {**ORIGINAL, "v_em_max": 5.0}}))
    with pytest.raises(ConfigError, match="at most 30"):
        presets.Preset(name="x", description="", arms=("simple",), best=ORIGINAL, top=({"metaparams": ORIGINAL},) * 31)
    with pytest.raises(ConfigError, match="arms"):
        presets.Preset(name="x", description="", arms=("robot",), best=ORIGINAL)
    with pytest.raises(ConfigError, match="built in"):
        presets.save(presets.original())
    # the bounds themselves are allowed (a search clips to them)
    presets.Preset(name="edge", description="", arms=("simple",), best={n: BOUNDS[n].hi for n in NAMES})


def test_preset_round_trip_from_search(search, preset_dir):
    top_k = json.loads((search / "top_k.json").read_text())["top_k"]
    p = presets.load("quad", preset_dir)
    assert p.best == top_k[0]["metaparams"]
    assert [r["metaparams"] for r in p.top] == [r["metaparams"] for r in top_k]
    assert [r["rank"] for r in p.top] == [1, 2, 3] and p.arms == ("simple",)
    assert presets.load(str(preset_dir / "quad.json")).to_json() == p.to_json()
    prov = p.provenance
    assert prov["seed"] == 0 and prov["command_reconstructed"] and prov["cost"]["evaluations"] == 4
    assert prov["date"] and prov["search_finished"]
    # the reconstructed command is a valid `jaxarm evolve` command for the same search
    from jaxarm.evolve.cli import build_parser

    args = build_parser().parse_args(shlex.split(prov["command"])[2:])
    assert (args.fitness, args.strategy, args.population, args.generations, args.seed, args.top_k, args.arm) == \
        ("quadratic", "SimpleGA", 4, 1, 0, 3, "simple")
    with pytest.raises(ConfigError, match="exists"):
        presets.save(p, preset_dir)


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_reconstructed_command_resumes_its_search(tmp_path, capsys):
    """A preset's reconstructed command carries start, frozen and sigma values exactly (not rounded to 6 digits,
    which is a different search space the checkpoint refuses): run again, it extends the search it came from."""
    out = tmp_path / "s"
    assert main(["evolve", "--fitness", "quadratic", "--strategy", "CMA_ES", "--population", "4", "--generations",
                 "1", "--chunk", "1", "--top-k", "3", "--arm", "simple", "--sigma", "0.123456789",
                 "--search", "learn_rate,v_em_max", "--start", "learn_rate=0.0897119433,v_em_max=156.2515123",
                 "--freeze", "plast_ei_maxw=9.108501234", "--out", str(out)]) == 0
    command = presets.from_search(out, "exact").provenance["command"]
    assert "0.0897119" in command and "9.108501" in command
    argv = shlex.split(command)[1:]
    argv[argv.index("--generations") + 1] = "2"
    capsys.readouterr()
    assert main(argv) == 0
    assert "resuming from the checkpoint at generation 1/2 (extended from 1 generations)" in capsys.readouterr().out
    assert json.loads((out / "history.json").read_text())["generations_done"] == 2


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_reevaluation_on_one_target_makes_a_preset_for_it(tmp_path, capsys):
    """--reevaluate-targets ranks a two-target search's top-k for one target (the paper's "best 30 configurations
    for each case"): top_k.json says so, the preset is for that target, its command re-creates the re-evaluation,
    and a target outside --targets is refused by name."""
    out = tmp_path / "s"
    base = ["evolve", "--fitness", "quadratic", "--strategy", "CMA_ES", "--population", "4", "--generations", "1",
            "--chunk", "1", "--top-k", "3", "--arm", "simple", "--targets", "left,bottom", "--out", str(out)]
    assert main(base + ["--reevaluate-seeds", "2", "--reevaluate-targets", "top"]) == 2
    assert "--reevaluate-targets = 'top'" in capsys.readouterr().err
    assert main(base + ["--reevaluate-targets", "bottom"]) == 2
    assert "needs --reevaluate-seeds" in capsys.readouterr().err
    assert main(base + ["--reevaluate-seeds", "2", "--reevaluate-targets", "bottom"]) == 0
    top = json.loads((out / "top_k.json").read_text())
    assert top["reevaluated"] and top["reevaluation"]["targets"] == ["bottom"]
    assert json.loads((out / "reevaluation.json").read_text())["targets"] == ["bottom"]
    p = presets.from_search(out, "bottom-only")
    assert p.targets == ("bottom",) and "re-ranked for bottom" in p.description
    args = shlex.split(p.provenance["command"])
    assert args[args.index("--reevaluate-targets") + 1] == "bottom" and args[args.index("--targets") + 1] == \
        "left,bottom"
    # both targets again: the one-target results are not reused, all 3 are evaluated again
    capsys.readouterr()
    assert main(base + ["--reevaluate-seeds", "2"]) == 0
    out_text = capsys.readouterr().out
    assert "resuming the re-evaluation" not in out_text and "re-evaluated 3/3" in out_text
    assert presets.from_search(out, "both").targets == ("left", "bottom")


def test_preset_from_a_stopped_search_needs_allow_unfinished(tmp_path, capsys):
    out = tmp_path / "stopped"
    assert main(["evolve", "--fitness", "quadratic", "--strategy", "SimpleGA", "--population", "4",
                 "--generations", "3", "--chunk", "1", "--max-chunks", "1", "--top-k", "3", "--arm", "simple",
                 "--out", str(out)]) == 0
    with pytest.raises(ConfigError, match=r"unfinished \(1 of 3 generations\).*--allow-unfinished"):
        presets.from_search(out, "early")
    assert main(["reproduce", "--make-preset", "early", "--from-search", str(out), "--preset-dir", str(tmp_path)]) == 2
    assert "--allow-unfinished" in capsys.readouterr().err
    assert main(["reproduce", "--make-preset", "early", "--from-search", str(out), "--preset-dir", str(tmp_path),
                 "--allow-unfinished"]) == 0
    search = presets.load("early", tmp_path).provenance["search"]
    assert search["generations_done"] == 1 and search["config"]["generations"] == 3 and search["search_stopped_early"]


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_reproduce_both_modes_resumes_after_interruption(tmp_path, preset_dir):
    from jaxarm.paper.reproduce import reproduce

    out = tmp_path / "repro"
    p = presets.load("quad", preset_dir)
    kw = dict(networks=2, epochs=2, epoch_s=0.2, test_s=0.2, top=2, progress=False, log=lambda _: None)
    assert reproduce(p, "simple", ["left"], out, stop_after=1, **kw) is None   # "killed" after one epoch
    assert not (out / "success_table.json").exists()
    assert main(["reproduce", "--preset", "quad", "--preset-dir", str(preset_dir), "--top", "2", "--out", str(out),
                 *TINY]) == 0
    table = json.loads((out / "success_table.json").read_text())
    row = table["targets"]["left"]
    assert TABLE_KEYS <= set(row)
    assert (row["seeds_n"], row["top30_n"], row["paper"], row["paper_n"]) == (2, 2, 28, 30)
    for mode in ("seeds", "top30"):   # the table counts what the folders' per-network results say
        nets = json.loads((out / "left" / mode / "results.json").read_text())["networks"]
        assert row[mode] == sum(n["success"] for n in nets) and len(nets) == 2
    assert {"arm", "preset", "command", "date", "machine", "commit", "seed", "timing", "paper"} <= set(table)
    assert table["command"].startswith("jaxarm reproduce --preset quad")
    batch = table["timing"]["batches"]["2 epochs"]   # both modes trained in one batch of 4 networks
    assert batch["epochs_run"] == 1 and batch["batch_networks"] == 4     # resumed: only the second epoch ran
    # (b) trains network i with set i: the folder records the sets, and `jaxarm test` re-tests it identically
    top30 = json.loads((out / "left" / "top30" / "results.json").read_text())
    assert top30["config"]["metaparams"] == [r["metaparams"] for r in p.top[:2]]
    assert main(["test", "--from", str(out / "left" / "top30"), "--test-s", "0.2"]) == 0
    again = json.loads((out / "left" / "top30" / "test" / "results.json").read_text())
    assert again["networks"] == top30["networks"]


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_reproduce_resumes_past_a_damaged_checkpoint(tmp_path, preset_dir, capsys):
    from conftest import truncate_newest_checkpoint
    from jaxarm.paper.reproduce import reproduce

    p = presets.load("quad", preset_dir)
    kw = dict(networks=2, epochs=2, epoch_s=0.2, test_s=0.2, top=2, progress=False, log=lambda _: None)
    assert reproduce(p, "simple", ["left"], tmp_path / "full", **kw) is not None
    out = tmp_path / "killed"
    assert reproduce(p, "simple", ["left"], out, stop_after=1, **kw) is None
    truncate_newest_checkpoint(out / "checkpoints")
    assert reproduce(p, "simple", ["left"], out, **kw) is not None
    assert "no earlier checkpoint: starting afresh" in capsys.readouterr().err
    for folder in ("seeds", "top30"):
        a = json.loads((tmp_path / "full" / "left" / folder / "results.json").read_text())
        b = json.loads((out / "left" / folder / "results.json").read_text())
        assert a["networks"] == b["networks"] and a["history"] == b["history"]


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_original_preset_reports_top30_null(tmp_path, capsys):
    out = tmp_path / "orig"
    assert main(["reproduce", "--preset", "original", "--out", str(out), *TINY]) == 0
    row = json.loads((out / "success_table.json").read_text())["targets"]["left"]
    assert row["top30"] is None and row["top30_n"] == 0 and "no top list" in row["top30_note"]
    text = capsys.readouterr().out
    assert "n/a" in text and "no top list" in text and "28/30" in text
    # a rerun reuses the finished folder
    assert main(["reproduce", "--preset", "original", "--out", str(out), *TINY]) == 0
    assert "reused" in capsys.readouterr().out


def test_every_shipped_preset_loads_and_is_within_bounds():
    """Each jaxarm/paper/presets/*.json validates (fields, bounds, provenance) and names the arm it was tuned for."""
    from jaxarm.paper import presets

    names = presets.available(archive=True)
    assert list(names)[0] == "original"
    # the README's presets and the centre-out default sit in the package folder, the other searches' in archive/,
    # loadable by name
    assert set(presets.available()) == {"original", "msarm-cmaes-2cm-rerank", "msarm-rerank-bottom-stay",
                                        "simple-rerank-left-32", "simple-rerank-bottom-24",
                                        "simple-cmaes-left-shoulder", "simple-centre-out-code"}
    from jaxarm.paper.reproduce import CENTRE_OUT_PRESETS
    for arm, name in CENTRE_OUT_PRESETS.items():      # the centre-out default carries its network, with a code
        preset = presets.load(name)
        assert arm in preset.arms and preset.network_config().spec.target_codes == ("T",)
    assert "simple-fixedseed-left" in names and presets.load("simple-fixedseed-left").name == "simple-fixedseed-left"
    assert {"simple-cmaes-left-fixed", "simple-cmaes-shortfall-long", "simple-cmaes-bottom-local",
            "simple-cmaes-left-local", "simple-cmaes-bottom-fixed", "msarm-rerank-left-stay", "simple-rerank-left",
            "simple-rerank-bottom"} <= set(names)
    for name in names:
        p = presets.load(name)
        assert p.name == name and p.arms
        if name != "original":
            assert p.provenance.get("command") and "seed" in p.provenance


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_a_one_target_preset_reproduces_its_target_by_default(tmp_path, preset_dir):
    """A preset tuned for one target (a one-target search or re-ranking) runs that target when --targets is not
    given; a target it was not tuned for is run when asked, with a note saying so."""
    from jaxarm.paper.reproduce import reproduce

    quad = presets.load("quad", preset_dir)
    kw = dict(networks=2, epochs=2, epoch_s=0.2, test_s=0.2, progress=False)
    left_only = presets.Preset(name="left-only", description="", arms=("simple",), best=quad.best, targets=("left",))
    lines = []
    table = reproduce(left_only, "simple", None, tmp_path / "a", log=lines.append, **kw)
    assert list(table["targets"]) == ["left"] and not any("tuned for the" in ln for ln in lines)
    bottom_only = presets.Preset(name="bottom-only", description="", arms=("simple",), best=quad.best,
                                 targets=("bottom",))
    lines = []
    table = reproduce(bottom_only, "simple", ["left"], tmp_path / "b", log=lines.append, **kw)
    assert list(table["targets"]) == ["left"]
    assert "note: preset 'bottom-only' was tuned for the bottom target; running it on left too" in lines


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_set_changes_a_metaparameter_in_every_set(tmp_path, preset_dir, capsys):
    """`--set NAME=VALUE` replaces that metaparameter in the best set (a) and in each top set (b), is recorded in
    success_table.json, and a value outside its bound is refused naming the field and its range; `--dt-ms` sets
    every run's clock step."""
    out = tmp_path / "set"
    assert main(["reproduce", "--preset", "quad", "--preset-dir", str(preset_dir), "--top", "2", "--out", str(out),
                 "--set", "explore_tot=8", "--dt-ms", "0.5", *TINY]) == 0
    table = json.loads((out / "success_table.json").read_text())
    assert table["set"] == {"explore_tot": 8.0}
    for mode in ("seeds", "top30"):   # --dt-ms: the clock step of every run, recorded in its meta
        cfg = json.loads((out / "left" / mode / "results.json").read_text())["config"]
        assert cfg["dt_ms"] == 0.5 and cfg["loop"]["network"]["dt_ms"] == 0.5
    p = presets.load("quad", preset_dir)
    a = json.loads((out / "left" / "seeds" / "results.json").read_text())["config"]["metaparams"]
    b = json.loads((out / "left" / "top30" / "results.json").read_text())["config"]["metaparams"]
    assert a["explore_tot"] == 8.0 and [m["explore_tot"] for m in b] == [8.0, 8.0]
    assert {k: v for k, v in a.items() if k != "explore_tot"} == \
        {k: v for k, v in p.best_metaparams().to_dict().items() if k != "explore_tot"}
    capsys.readouterr()
    assert main(["reproduce", "--preset", "quad", "--preset-dir", str(preset_dir), "--out", str(tmp_path / "bad"),
                 "--set", "explore_tot=99", *TINY]) == 2
    err = capsys.readouterr().err
    assert "explore_tot" in err and "outside its range" in err
    assert main(["reproduce", "--preset", "quad", "--preset-dir", str(preset_dir), "--out", str(tmp_path / "bad"),
                 "--dt-ms", "0.3", *TINY]) == 2
    assert "dt_ms = 0.3" in capsys.readouterr().err


@pytest.mark.slow   # 45 s: the default suite's 8-minute budget (CI runs the slow suite too)
def test_musculoskeletal_reproduce_with_the_shipped_preset_then_retest(tmp_path):
    """The headline path at tiny size: the shipped musculoskeletal preset, both modes, one target, then `jaxarm
    test` re-tests the trained networks identically."""
    out = tmp_path / "msarm"
    assert main(["reproduce", "--arm", "musculoskeletal", "--preset", "msarm-cmaes-2cm-rerank", "--targets", "left",
                 "--networks", "2", "--top", "2", "--epochs", "1", "--epoch-s", "0.3", "--test-s", "0.2",
                 "--no-progress", "--out", str(out)]) == 0
    row = json.loads((out / "success_table.json").read_text())["targets"]["left"]
    assert (row["seeds_n"], row["top30_n"], row["paper"]) == (2, 2, 29)
    seeds = json.loads((out / "left" / "seeds" / "results.json").read_text())
    assert seeds["config"]["arm"] == "musculoskeletal" and seeds["config"]["metaparams"] == \
        presets.load("msarm-cmaes-2cm-rerank").best
    assert main(["test", "--from", str(out / "left" / "seeds"), "--test-s", "0.2"]) == 0
    again = json.loads((out / "left" / "seeds" / "test" / "results.json").read_text())
    assert again["networks"] == seeds["networks"]


@pytest.mark.slow  # moved to the slow suite: the default suite's 8-minute budget on CI
def test_the_default_protocol_runs_each_arms_headline_presets(tmp_path, capsys):
    """Without --preset, each (target, mode) runs the preset, epochs and settings of the README's headline row
    (read from the shipped preset files), says so first, and the table records it with the paper's measures."""
    from jaxarm.paper.reproduce import DEFAULT_PROTOCOL, reproduction_plan

    plan = reproduction_plan(None, "simple", None, None, 30, {}, presets.PRESET_DIR)
    assert {t: {m: (s["preset"].name, s["epochs"], s["set"]) for m, s in modes.items()} for t, modes in plan.items()} \
        == {"left": {"seeds": ("simple-rerank-left-32", 6, {}), "top30": ("simple-rerank-left-32", 6, {})},
            "bottom": {"seeds": ("simple-rerank-bottom-24", 16, {}), "top30": ("simple-rerank-bottom-24", 16, {})}}
    assert all(float(m.explore_tot) == 8.0 for m in plan["bottom"]["seeds"]["sets"])
    assert len(plan["left"]["top30"]["sets"]) == 30
    ms = reproduction_plan(None, "musculoskeletal", None, None, 30, {}, presets.PRESET_DIR)
    assert {(t, m): (s["preset"].name, s["epochs"]) for t, modes in ms.items() for m, s in modes.items()} \
        == {("left", "seeds"): ("msarm-cmaes-2cm-rerank", 12), ("left", "top30"): ("msarm-cmaes-2cm-rerank", 12),
            ("bottom", "seeds"): ("msarm-cmaes-2cm-rerank", 12), ("bottom", "top30"): ("msarm-rerank-bottom-stay", 12)}
    assert list(ms) == ["left", "bottom"] and len(ms["bottom"]["top30"]["sets"]) == 30
    assert set(DEFAULT_PROTOCOL) == {"simple", "musculoskeletal"}
    out = tmp_path / "default"
    assert main(["reproduce", "--out", str(out), "--top", "1", *TINY]) == 0
    text = capsys.readouterr().out
    assert "default protocol" in text and "(a) simple-rerank-left-32" in text
    table = json.loads((out / "success_table.json").read_text())
    row = table["targets"]["left"]
    assert row["protocol"]["seeds"]["preset"] == "simple-rerank-left-32"
    assert row["protocol"]["top30"] == {"preset": "simple-rerank-left-32", "epochs": 2, "set": {}}
    assert set(table["presets"]) == {"simple-rerank-left-32"}
    assert row["measures"]["seeds"]["jerk_trained"]["paper"] == 28.1
    assert "| left | networks reaching" in text
    with pytest.raises(ConfigError, match="default protocol has left, bottom"):
        reproduction_plan(None, "simple", ["up"], None, 30, {}, presets.PRESET_DIR)


def test_a_presets_protocol_sets_its_default_length(tmp_path):
    """A preset's `protocol` (the length its published numbers used) is what reproduce trains unless --epochs says
    otherwise; the headline musculoskeletal preset carries the paper's 12 epochs; a bad protocol names the field."""
    from jaxarm.paper.reproduce import reproduction_plan

    ms = presets.load("msarm-cmaes-2cm-rerank")
    assert ms.protocol["epochs"] == 12 and ms.epochs == 12
    plan = reproduction_plan(ms, "musculoskeletal", None, None, 30, {}, presets.PRESET_DIR)
    assert {s["epochs"] for modes in plan.values() for s in modes.values()} == {12}
    plan = reproduction_plan(ms, "musculoskeletal", ["left"], 3, 30, {}, presets.PRESET_DIR)
    assert {s["epochs"] for s in plan["left"].values()} == {3}
    assert presets.Preset.from_json(ms.to_json()).protocol == ms.protocol
    with pytest.raises(ConfigError, match="protocol = .*must be"):
        presets.Preset(name="x", description="", arms=("simple",), best=ORIGINAL, protocol={"epochs": 0})
    # a preset saved when sets carried `epochs` and `max_w_scaling`: the sets' epochs is its protocol, both dropped
    old = {**ORIGINAL, "max_w_scaling": 0.7, "epochs": 6.0}
    p = presets.Preset(name="old", description="", arms=("simple",), best=old, top=({"metaparams": old},))
    assert p.epochs == 6 and p.best == ORIGINAL and p.top[0]["metaparams"] == ORIGINAL
    assert reproduction_plan(p, "simple", ["left"], None, 30, {}, presets.PRESET_DIR)["left"]["seeds"]["epochs"] == 6
    assert presets.Preset(name="new", description="", arms=("simple",), best=ORIGINAL).epochs == 12   # the paper's
    with pytest.raises(ConfigError, match=r"sets' epochs \[4.0, 6.0\]"):
        presets.Preset(name="old", description="", arms=("simple",), best=old,
                       top=({"metaparams": {**old, "epochs": 4.0}},))


def test_a_result_names_its_date_machine_and_commit():
    """success_table.json (and every result page that quotes it, docs/results/) says when, where and from which
    code it was measured."""
    from jaxarm.paper.reproduce import measured_on

    m = measured_on()
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", m["date"]) and re.search(r", \d+ cores$", m["machine"])
    assert m["commit"] is None or re.fullmatch(r"[0-9a-f]{7,40}(-dirty)?", m["commit"])
