"""Named metaparameter presets: the sets ``jaxarm reproduce`` trains, with where they came from.

A preset is a JSON file ``jaxarm/paper/presets/NAME.json`` (shipped with the package) holding:

* ``name``, ``description``, ``arms`` (the arm(s) it was tuned for) and optionally ``targets``;
* ``best``: a complete metaparameter set (every :class:`~jaxarm.learning.metaparams.MetaParams` field, in the
  field's own units) -- what ``jaxarm reproduce`` trains with N seeds;
* ``top`` (optional): up to 30 ranked sets, best first, each ``{"rank", "fitness", "generation",
  "metaparams"}`` -- the paper's statistic trains one network with each;
* ``provenance``: the command, search seed, cost (wall time, evaluations, network-seconds) and date that produced
  it;
* ``protocol`` (optional): ``{"epochs", "why"}``, the training length its published numbers used (without one,
  the paper's 12 epochs);
* ``network`` (optional): the network its sets were found for, as the fields that differ from the paper's
  (``NetworkConfig.to_dict(changed_only=True)``, what ``jaxarm evolve --network`` records); ``jaxarm train`` and
  ``jaxarm reproduce`` with the preset train that network unless given ``--network``. A search made with
  ``--network`` passes it on to its preset.

Sets saved before ``epochs`` and ``max_w_scaling`` left the metaparameters (:data:`~jaxarm.learning.metaparams.RETIRED`)
load unchanged: ``max_w_scaling`` is dropped, and the sets' ``epochs`` becomes the protocol of a preset that has none.

The presets behind the README's tables sit in this folder; the sets of every other search of the project's history
(``docs/searches.md``) in ``archive/``, still loadable by name and listed by ``jaxarm reproduce --list-presets
--all``.

The built-in preset ``original`` is :meth:`MetaParams.original` (the authors' values from ``main.hoc``, [model:
metaparameters](../model.md#metaparameters)); it has no top list: the authors' other 29 configurations are not
available.

Making a preset from a finished search (its ``top_k.json`` and ``history.json``)::

    jaxarm evolve --arm musculoskeletal --targets left,bottom --out runs/evolve-msarm ...
    jaxarm reproduce --make-preset msarm-cmaes --from-search runs/evolve-msarm \\
        --search-command "jaxarm evolve --arm musculoskeletal ..."      # the exact command, if you have it
    git add jaxarm/paper/presets/msarm-cmaes.json

or from Python, :func:`from_search` then :func:`save`. Every set is checked against
:data:`~jaxarm.learning.metaparams.BOUNDS` when a preset is made and when it is loaded; a value outside raises
:class:`ConfigError` naming the field and the range.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jaxarm.arm.registry import ARMS
from jaxarm.config.network import NetworkConfig
from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import BOUNDS, NAMES, ORIGINAL, MetaParams, as_current

#: Where the package's preset files live (``--make-preset`` writes here by default, so the file can be committed).
PRESET_DIR = Path(__file__).resolve().parent
#: Presets of earlier searches (docs/searches.md), loadable by name, listed with ``--list-presets --all``.
ARCHIVE = "archive"
#: The built-in preset's name.
ORIGINAL_NAME = "original"
#: The paper reported its 30 best configurations.
MAX_TOP = 30
#: The paper's training length, epochs of 30 s (a preset without a protocol trains for it).
PAPER_EPOCHS = 12
_NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_.-]{0,63}$")


@dataclass(frozen=True)
class Preset:
    """A named metaparameter preset (see the module docstring). ``best`` and the sets of ``top`` are complete
    ``{field: value}`` dicts, checked against BOUNDS on construction."""

    name: str
    description: str
    arms: tuple[str, ...]
    best: dict
    top: tuple[dict, ...] = ()
    provenance: dict = field(default_factory=dict)
    targets: tuple[str, ...] | None = None
    #: The protocol of the preset's published numbers, used by `jaxarm reproduce` unless told otherwise:
    #: ``{"epochs": E, "why": "..."}`` (None: the paper's 12 epochs).
    protocol: dict | None = None
    #: The network its sets were found for: NetworkConfig fields that differ from the paper's (None: the paper's).
    network: dict | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not _NAME_RE.match(self.name):
            raise ConfigError(f"preset name {self.name!r}: use 1-64 characters of a-z, 0-9, '_', '.', '-' "
                              "(starting with a letter or digit)")
        arms = tuple(self.arms)
        bad = [a for a in arms if a not in ARMS]
        if not arms or bad:
            raise ConfigError(f"preset {self.name!r} arms = {list(arms)!r}: must be a non-empty list of "
                              f"{', '.join(map(repr, ARMS))}")
        object.__setattr__(self, "arms", arms)
        if self.protocol is None:
            object.__setattr__(self, "protocol", _protocol_of_old_sets(self.name, self.best, self.top))
        object.__setattr__(self, "best", check_metaparams(self.best, f"preset {self.name!r} best"))
        top = tuple(self.top or ())
        if len(top) > MAX_TOP:
            raise ConfigError(f"preset {self.name!r} top: {len(top)} sets; at most {MAX_TOP}")
        rows = []
        for i, row in enumerate(top):
            if not isinstance(row, dict) or "metaparams" not in row:
                raise ConfigError(f"preset {self.name!r} top[{i}]: must be an object with a 'metaparams' set")
            rows.append({**row, "metaparams": check_metaparams(row["metaparams"], f"preset {self.name!r} top[{i}]")})
        object.__setattr__(self, "top", tuple(rows))
        if self.targets is not None:
            object.__setattr__(self, "targets", tuple(self.targets))
        if self.network is not None:
            if not isinstance(self.network, dict):
                raise ConfigError(f"preset {self.name!r} network: must be an object of NetworkConfig fields")
            NetworkConfig.from_dict(self.network, what=f"preset {self.name!r} network")   # validated, named
        if self.protocol is not None:
            ep = self.protocol.get("epochs") if isinstance(self.protocol, dict) else None
            if set(self.protocol or {}) - {"epochs", "why"} or isinstance(ep, bool) or not isinstance(ep, int) \
                    or not 1 <= ep <= 1000:
                raise ConfigError(f"preset {self.name!r} protocol = {self.protocol!r}: must be "
                                  '{"epochs": an integer in [1, 1000], "why": "..."}')

    # ------------------------------------------------------------------ use
    @property
    def epochs(self) -> int:
        """The training length of the preset's published numbers: its protocol's, else the paper's."""
        return self.protocol["epochs"] if self.protocol is not None else PAPER_EPOCHS

    def network_config(self) -> NetworkConfig | None:
        """The network the preset's sets were found for, or None for the paper's."""
        return None if self.network is None else NetworkConfig.from_dict(self.network)

    def best_metaparams(self) -> MetaParams:
        return MetaParams.from_dict(self.best)

    def top_metaparams(self, n: int = MAX_TOP) -> list[MetaParams]:
        """The first ``n`` sets of the top list (fewer when the list is shorter; none without one)."""
        return [MetaParams.from_dict(row["metaparams"]) for row in self.top[:n]]

    def to_json(self) -> dict:
        d = {"name": self.name, "description": self.description, "arms": list(self.arms)}
        if self.targets is not None:
            d["targets"] = list(self.targets)
        if self.protocol is not None:
            d["protocol"] = self.protocol
        if self.network is not None:
            d["network"] = self.network
        d.update(best=self.best, top=list(self.top), provenance=self.provenance)
        return d

    @classmethod
    def from_json(cls, d: dict, where: str = "preset") -> "Preset":
        if not isinstance(d, dict):
            raise ConfigError(f"{where}: a preset file holds one JSON object")
        known = {"name", "description", "arms", "targets", "protocol", "network", "best", "top", "provenance"}
        unknown = sorted(set(d) - known)
        missing = [k for k in ("name", "arms", "best") if k not in d]
        if unknown or missing:
            raise ConfigError(f"{where}: " + "; ".join(
                ([f"unknown key(s) {unknown}"] if unknown else []) + ([f"missing key(s) {missing}"] if missing else []))
                + f" (keys: {', '.join(sorted(known))})")
        return cls(name=d["name"], description=d.get("description", ""), arms=tuple(d["arms"]), best=d["best"],
                   top=tuple(d.get("top") or ()), provenance=d.get("provenance") or {}, targets=d.get("targets"),
                   protocol=d.get("protocol"), network=d.get("network"))


def _protocol_of_old_sets(name: str, best, top) -> dict | None:
    """The protocol that sets saved with an ``epochs`` metaparameter imply (None when they carry none)."""
    sets = [best] + [row.get("metaparams") for row in top or () if isinstance(row, dict)]
    values = sorted({v["epochs"] for v in sets if isinstance(v, dict) and "epochs" in v}, key=str)
    if not values:
        return None
    if len(values) > 1 or isinstance(values[0], bool) or not isinstance(values[0], (int, float)) \
            or values[0] != round(values[0]) or not 1 <= values[0] <= 1000:
        raise ConfigError(f"preset {name!r}: its sets' epochs {values} must be one whole number in [1, 1000] (the "
                          'training length); give the preset a protocol {"epochs": E, "why": "..."}')
    return {"epochs": int(values[0]), "why": "the training length stored with its sets"}


def check_metaparams(values, where: str) -> dict:
    """A complete ``{field: float}`` set inside :data:`BOUNDS` (compared in float32, the type the model uses), or
    :class:`ConfigError` naming the field and its range. The :data:`~jaxarm.learning.metaparams.RETIRED` names of
    older sets are dropped, and the :data:`~jaxarm.learning.metaparams.ADDED` ones take their values when absent."""
    if not isinstance(values, dict):
        raise ConfigError(f"{where}: must be an object {{field: value}} with every metaparameter ({', '.join(NAMES)})")
    values = as_current(values)
    unknown = [k for k in values if k not in NAMES]
    if unknown:
        raise ConfigError(f"{where}: unknown metaparameter {unknown[0]!r}; known: {', '.join(NAMES)}")
    missing = [k for k in NAMES if k not in values]
    if missing:
        raise ConfigError(f"{where}: missing {', '.join(missing)} (a preset gives every metaparameter)")
    out = {}
    for name in NAMES:
        v, b = values[name], BOUNDS[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{where}.{name} = {v!r}: must be a finite number in [{b.lo:g}, {b.hi:g}] {b.unit}")
        if not np.float32(b.lo) <= np.float32(v) <= np.float32(b.hi):
            raise ConfigError(f"{where}.{name} = {v!r} is out of range; allowed [{b.lo:g}, {b.hi:g}] {b.unit} "
                              "(jaxarm.learning.metaparams.BOUNDS)")
        out[name] = float(v)
    return out


def original() -> Preset:
    """The built-in preset: the published values, no top list."""
    return Preset(
        name=ORIGINAL_NAME,
        description="the authors' metaparameters (main.hoc, marked 'optimized'); no top-30 list is available",
        arms=("musculoskeletal", "simple"), best=dict(ORIGINAL), top=(),
        provenance={"source": "the authors' values from main.hoc (jaxarm.learning.metaparams.ORIGINAL)",
                    "command": None, "seed": None, "cost": None, "date": None})


def _file_presets(directory: Path, archive: bool = True) -> dict[str, Path]:
    """``{name: path}`` of ``directory``'s preset files, then (``archive``) those of its archive folder."""
    found = {p.stem: p for p in sorted(Path(directory).glob("*.json"))}
    if archive:
        for p in sorted((Path(directory) / ARCHIVE).glob("*.json")):
            found.setdefault(p.stem, p)
    return found


def available(directory: Path = PRESET_DIR, archive: bool = False) -> dict[str, str]:
    """``{name: one-line description}``: ``original`` first, then the preset files by name (with ``archive``, the
    archived ones after them)."""
    out = {ORIGINAL_NAME: original().description}
    for name, path in _file_presets(directory, archive).items():
        try:
            d = json.loads(path.read_text())
            desc = d.get("description", "") if isinstance(d, dict) else ""
        except (OSError, json.JSONDecodeError) as e:
            desc = f"(unreadable: {e})"
        out.setdefault(name, desc)
    return out


def load(name_or_path: str | Path, directory: Path = PRESET_DIR) -> Preset:
    """A preset by name (``original`` or a file in ``directory``) or by the path of a ``.json`` file."""
    text = str(name_or_path)
    if text == ORIGINAL_NAME:
        return original()
    path = Path(text) if (text.endswith(".json") or "/" in text) else _file_presets(directory).get(text)
    if path is None or not path.is_file():
        raise ConfigError(f"unknown preset {text!r}; known: {', '.join(available(directory, archive=True))} "
                          "(or give the path of a preset .json file)")
    try:
        d = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ConfigError(f"preset file {path}: not valid JSON ({e})") from None
    preset = Preset.from_json(d, where=f"preset file {path}")
    if path.parent.resolve() in (Path(directory).resolve(), (Path(directory) / ARCHIVE).resolve()) \
            and preset.name != path.stem:
        raise ConfigError(f"preset file {path} is named {preset.name!r} inside; the file must be {preset.name}.json")
    return preset


def save(preset: Preset, directory: Path = PRESET_DIR, overwrite: bool = False) -> Path:
    """Write ``directory/NAME.json``; refuses to replace a file unless ``overwrite``."""
    if preset.name == ORIGINAL_NAME:
        raise ConfigError(f"preset name {ORIGINAL_NAME!r} is built in; choose another")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{preset.name}.json"
    if path.exists() and not overwrite:
        raise ConfigError(f"{path} exists; choose another name or delete it")
    path.write_text(json.dumps(preset.to_json(), indent=1) + "\n")
    return path


def _number(v) -> str:
    """A number as a command-line value that parses back to the same value: ``repr`` of the stored float (the
    shortest round-trip form), so a reconstructed command resumes the search it describes (a rounded start or frozen
    value is a different search space, and the checkpoint refuses it)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return str(v)
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def _evolve_command(history: dict, top_k: dict, search_dir: Path) -> str:
    """The ``jaxarm evolve`` command equivalent to the search described in history.json (same fitness, space,
    strategy and seeds; --eval-batch and --chunk only change memory use and checkpoint spacing). Values are written
    exactly (:func:`_number`): running the command again with the same ``--out`` resumes or extends that search."""
    c, fit, space = history["config"], history.get("fitness", {}), history.get("space", {})
    args = ["jaxarm", "evolve", "--fitness", str(fit.get("name", "?"))]
    if fit.get("arm"):
        args += ["--arm", fit["arm"]]
    if fit.get("targets"):
        args += ["--targets", ",".join(fit["targets"])]
    if fit.get("train_s") is not None:
        args += ["--train-s", _number(fit["train_s"])]
    args += ["--strategy", c["strategy"], "--population", str(c["population_size"]),
             "--seeds-per-candidate", str(c["seeds_per_candidate"]), "--generations", str(c["generations"]),
             "--chunk", str(c["chunk_size"]), "--seed", str(c["seed"]), "--sigma", _number(c["sigma_init"]),
             "--top-k", str(c["top_k"]), "--seed-mode", c["seed_mode"], "--seed-reduce", c["seed_reduce"]]
    if c.get("strategy_params"):
        args += ["--strategy-param", ",".join(f"{k}={_number(v)}" for k, v in c["strategy_params"].items())]
    if c.get("eval_batch_size"):
        args += ["--eval-batch", str(c["eval_batch_size"])]
    if space.get("frozen"):
        args += ["--freeze", ",".join(f"{k}={_number(v)}" for k, v in space["frozen"].items())]
    starts = {k: v["start"] for k, v in space.get("searched", {}).items() if v.get("start") != ORIGINAL.get(k)}
    if starts:
        args += ["--start", ",".join(f"{k}={_number(v)}" for k, v in starts.items())]
    rows = top_k.get("top_k", [])
    if top_k.get("reevaluated") and rows and "reevaluation" in rows[0]:
        args += ["--reevaluate-seeds", str(len(rows[0]["reevaluation"].get("fitness_per_seed", [])))]
        again = top_k.get("reevaluation") or {}
        if again.get("train_s") is not None and again["train_s"] != fit.get("train_s"):
            args += ["--reevaluate-train-s", _number(again["train_s"])]
        if again.get("targets"):
            args += ["--reevaluate-targets", ",".join(again["targets"])]
    return shlex.join(args + ["--out", str(search_dir)])


def from_search(search_dir: str | Path, name: str, description: str | None = None, command: str | None = None,
                max_top: int = MAX_TOP, arms: tuple[str, ...] | None = None,
                allow_unfinished: bool = False) -> Preset:
    """A preset from a finished ``jaxarm evolve`` folder (or, with ``allow_unfinished``, one stopped early: its
    provenance then records ``generations_done`` below the planned ``generations`` and ``search_stopped_early``): ``best`` = its rank-1 set, ``top`` = its first
    ``max_top`` sets (ranked as in top_k.json: by the re-evaluation when the search did one). Provenance: the
    command (``command`` as given, else reconstructed from history.json and marked so), the search seed and
    configuration, its cost (run and compile seconds, evaluations, network-seconds) and the dates. ``arms``:
    default the search's fitness arm (needed when history.json does not name one)."""
    search_dir = Path(search_dir)
    try:
        top_k = json.loads((search_dir / "top_k.json").read_text())
        history = json.loads((search_dir / "history.json").read_text())
    except FileNotFoundError as e:
        raise ConfigError(f"--from-search {search_dir}: {e.filename} not found (a `jaxarm evolve --out` folder "
                          "holds top_k.json and history.json)") from None
    rows = top_k.get("top_k") or []
    if not rows:
        raise ConfigError(f"{search_dir / 'top_k.json'} holds no candidates")
    config = history.get("config", {})
    stopped_early = history.get("generations_done", 0) < config.get("generations", 0)
    if stopped_early and not allow_unfinished:
        raise ConfigError(f"{search_dir}: the search is unfinished ({history.get('generations_done')} of "
                          f"{config.get('generations')} generations); run the same `jaxarm evolve` command to finish, or allow_unfinished "
                          "(--allow-unfinished) for a preset from the generations done")
    if not 1 <= max_top <= MAX_TOP:
        raise ConfigError(f"max_top = {max_top}: must be in [1, {MAX_TOP}]")
    fit = top_k.get("fitness") or history.get("fitness", {})
    # A re-evaluation on a subset of the targets ranked the sets for those targets: the preset is for them.
    targets = (top_k.get("reevaluation") or {}).get("targets") or fit.get("targets")
    arms = tuple(arms) if arms else ((fit["arm"],) if fit.get("arm") else ())
    if not arms:
        raise ConfigError(f"{search_dir}: the search does not name its arm; give arms=(...)")
    top = []
    for row in rows[:max_top]:
        entry = {"rank": row.get("rank"), "fitness": row.get("fitness"), "generation": row.get("generation")}
        if row.get("reevaluation") is not None:
            entry["reevaluated_fitness"] = row["reevaluation"].get("fitness")
        entry["metaparams"] = row["metaparams"]
        top.append(entry)
    costs = history.get("costs", {})
    evals = costs.get("evaluations")
    per_eval = fit.get("network_seconds_per_eval") or 0.0
    stamp = _dt.datetime.fromtimestamp((search_dir / "top_k.json").stat().st_mtime, _dt.timezone.utc)
    provenance = {
        "source": "jaxarm evolve",
        "command": command if command else _evolve_command(history, top_k, search_dir),
        "command_reconstructed": not command,
        "seed": config.get("seed"),
        "search": {"config": config, "fitness": fit, "space": history.get("space"),
                   "generations_done": history.get("generations_done"), "search_stopped_early": stopped_early,
                   "reevaluated": bool(top_k.get("reevaluated")),
                   "reevaluation": top_k.get("reevaluation"),
                   "folder": str(search_dir)},
        "cost": {"run_s": costs.get("run_s"), "compile_s": costs.get("compile_s"), "evaluations": evals,
                 "network_seconds": evals * per_eval if evals is not None and per_eval else None,
                 "network_seconds_per_s": costs.get("network_seconds_per_s"),
                 "note": "the search only; a re-evaluation of the top-k (if any) is not included"},
        "search_finished": stamp.isoformat(timespec="seconds"),
        "date": _dt.datetime.now(_dt.timezone.utc).date().isoformat(),
    }
    if description is None:
        description = (f"best of a {config.get('strategy', '?')} search ({history.get('generations_done')} "
                       f"generations x {config.get('population_size')} candidates, fitness {fit.get('name', '?')}"
                       f"{', ' + ','.join(fit['targets']) if fit.get('targets') else ''}) on the {'/'.join(arms)} arm")
        if targets != fit.get("targets"):
            description += f", its top {len(rows)} re-ranked for {','.join(targets)}"
    epochs = fit.get("epochs")     # searches from before the fitness recorded it: the sets' own (protocol routing)
    protocol = None if epochs is None else {"epochs": int(epochs), "why": f"the search trained {epochs} epochs"}
    return Preset(name=name, description=description, arms=arms,
                  best=rows[0]["metaparams"], top=tuple(top), provenance=provenance,
                  targets=tuple(targets) if targets else None, protocol=protocol, network=fit.get("network"))
