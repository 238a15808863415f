"""Learning rules by name: ``LoopConfig.learning`` and ``jaxarm train --learning`` take their choices from
:data:`RULES`. A new rule is one module (a :class:`~jaxarm.learning.rule.LearningRule`) and one entry here
(``docs/extending.md``)."""
from __future__ import annotations

import dataclasses

from jaxarm.learning.gradient import GradientLearning
from jaxarm.learning.perturbation import WeightPerturbation
from jaxarm.learning.rstdp import RSTDP
from jaxarm.learning.rule import config_from_dict

#: name -> rule class; the first is the default.
RULES = {
    "rstdp": RSTDP,
    "gradient": GradientLearning,
    "weight-perturbation": WeightPerturbation,
}
DEFAULT = "rstdp"


def learning_meta(name: str, config) -> dict:
    """A run folder's record of its rule: nothing for the default rule with its default configuration (folders from
    before the registry read the same), else ``{"learning": {"rule": name, **config's fields}}``."""
    if name == DEFAULT and config == RULES[DEFAULT].Config():
        return {}
    return {"learning": {"rule": name} | dataclasses.asdict(config)}


def rule_from_meta(meta: dict) -> tuple[str, object]:
    """(name, configuration) of a run folder's rule from its :func:`learning_meta` record; a ``learning`` record
    without ``rule`` is gradient learning's (written before the registry)."""
    if "learning" not in meta:
        return DEFAULT, RULES[DEFAULT].Config()
    fields = dict(meta["learning"])
    name = fields.pop("rule", "gradient")
    return name, config_from_dict(RULES[name].Config, fields)
