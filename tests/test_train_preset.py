"""`jaxarm train --preset NAME [--set-from-preset INDEX]`: the metaparameters it trains with are the preset file's,
and a bad name or index is refused in one line naming what is allowed (no training: the train step is replaced)."""
import contextlib
import io
import json
import re
from pathlib import Path

import pytest

from jaxarm import experiment
from jaxarm.learning.metaparams import ORIGINAL, as_current

PRESETS = Path(experiment.__file__).resolve().parent / "paper" / "presets"


def _train(argv, monkeypatch):
    """``jaxarm train ARGV`` up to the training, which is caught: (exit code, stderr, what would train or None)."""
    caught = {}

    def train_targets(ap, args, configs, mp, record):
        caught.update(mp=mp.to_dict(), epochs=[cfg.task.epochs for _, cfg, _task in configs],
                      networks=[cfg.network for _, cfg, _task in configs])
        return 0

    monkeypatch.setattr(experiment, "_train_targets", train_targets)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            code = experiment.train_main(argv)
        except SystemExit as e:
            code = e.code
    return code, err.getvalue(), caught or None


@pytest.mark.parametrize("index", [None, 0, 7])
def test_preset_metaparameters_are_the_files(tmp_path, monkeypatch, index):
    stored = json.loads((PRESETS / "simple-cmaes-left-shoulder.json").read_text())
    want = as_current(stored["best"] if index is None else stored["top"][index]["metaparams"])
    argv = ["--preset", "simple-cmaes-left-shoulder", "--out", str(tmp_path / "run")]
    code, err, caught = _train(argv + ([] if index is None else ["--set-from-preset", str(index)]), monkeypatch)
    assert code == 0, err
    assert caught["mp"] == pytest.approx(want, rel=1e-6)
    assert caught["epochs"] == [stored["protocol"]["epochs"]] == [6]   # the preset's length, not the paper's 12


def test_preset_protocol_epochs_and_set_on_top(tmp_path, monkeypatch):
    stored = json.loads((PRESETS / "simple-rerank-bottom-24.json").read_text())
    code, err, caught = _train(["--preset", "simple-rerank-bottom-24", "--set", "v_em_max=60", "--out",
                                str(tmp_path / "run")], monkeypatch)
    assert code == 0, err
    assert caught["mp"] == pytest.approx({**as_current(stored["best"]), "v_em_max": 60.0}, rel=1e-6)
    assert caught["epochs"] == [stored["protocol"]["epochs"]]


def test_without_preset_the_authors_values_and_12_epochs(tmp_path, monkeypatch):
    from jaxarm.learning.metaparams import ORIGINAL

    code, err, caught = _train(["--out", str(tmp_path / "run")], monkeypatch)
    assert code == 0, err
    assert caught["mp"] == pytest.approx(dict(ORIGINAL), rel=1e-6) and caught["epochs"] == [12]


@pytest.mark.parametrize("argv, says", [
    (["--preset", "no-such-preset"],
     r"--preset: unknown preset 'no-such-preset'; known: original, .*simple-cmaes-left-shoulder"),
    (["--preset", "simple-cmaes-left-shoulder", "--set-from-preset", "30"],
     r"--set-from-preset 30: preset 'simple-cmaes-left-shoulder' has 30 ranked sets; give an index in \[0, 29\]"),
    (["--preset", "simple-cmaes-left-shoulder", "--set-from-preset", "-1"], r"give an index in \[0, 29\]"),
    (["--preset", "original", "--set-from-preset", "0"], r"preset 'original' has no ranked sets"),
    (["--set-from-preset", "3"], r"--set-from-preset 3: give the preset with --preset NAME"),
])
def test_bad_preset_or_index_is_one_line(tmp_path, monkeypatch, argv, says):
    code, err, caught = _train(argv + ["--out", str(tmp_path / "run")], monkeypatch)
    lines = [ln for ln in err.splitlines() if not ln.startswith(("usage:", " "))]
    assert code == 2 and caught is None and len(lines) == 1, err
    assert re.search(says, lines[0]), lines[0]


def test_a_preset_with_a_network_trains_it_unless_given_another(tmp_path, monkeypatch):
    """A preset made from a search with --network carries that network (NetworkConfig's changed fields): it survives
    the file, `jaxarm train --preset` trains it, --network replaces it, and a bad one is named in one line."""
    from jaxarm.config.network import NetworkConfig
    from jaxarm.config.spec import NetworkSpec
    from jaxarm.config.validate import ConfigError
    from jaxarm.paper import presets
    from jaxarm.task.centre_out import CentreOut, with_target_code

    coded = NetworkConfig(spec=with_target_code(NetworkSpec.dura_bernal_2015(), CentreOut(), pmat=0.4)
                          .with_plastic({"T->EM"}))
    preset = presets.Preset(name="coded", description="", arms=("simple",), best=ORIGINAL,
                            network=coded.to_dict(changed_only=True))
    path = presets.save(preset, tmp_path)
    assert presets.load(str(path)).network_config() == coded
    code, err, caught = _train(["--preset", str(path), "--task", "centre-out-8", "--out", str(tmp_path / "a")],
                               monkeypatch)
    assert code == 0, err
    assert caught["networks"] == [coded]                 # the target code is the preset's: kept, not added again
    other = tmp_path / "other.toml"
    NetworkConfig().save(other)
    code, err, caught = _train(["--preset", str(path), "--network", str(other), "--out", str(tmp_path / "b")],
                               monkeypatch)
    assert code == 0, err
    assert caught["networks"][0].spec == NetworkSpec.dura_bernal_2015()
    with pytest.raises(ConfigError, match="preset 'bad' network"):
        presets.Preset(name="bad", description="", arms=("simple",), best=ORIGINAL, network={"populations": 5})
