"""The learning-rule interface: what the closed loop and ``make_train`` call, and when.

A rule is a class with a static configuration (a frozen dataclass, hashable, validated when built) and pure
functions over its own state pytrees, evosax-style; the loop knows no rule by name (:mod:`jaxarm.learning.registry`
maps names to rules). ``make_train`` and the loop call a rule at four points:

* ``init(key) -> state``: once, at the start of training; ``state`` is carried from epoch to epoch
  (``Trained.rule``, checkpointed with the gains);
* ``begin_epoch(state, wgain, mp) -> (run, em_rates_hz)``: at the start of every epoch (a fresh run of network and
  arm, with the gains ``wgain``); ``run`` is the rule's state within the epoch (``LoopState.rule``), ``em_rates_hz``
  the (4,) EM noise rates (Hz) the epoch starts with;
* ``update(run, net, key, moment, mp) -> (run, net, signal)``: after every 10 ms training interval, with the network
  state (it may change the gains ``net.wgain``, the tags ``net.pdope_ms`` and the noise ``net.noise``), a fresh key
  and what the loop observed (:class:`Moment`); ``signal`` (+1 reward, -1 punishment, 0 none) is recorded
  (``IntervalRecord.critic``; an epoch's ``rewards`` and ``punishments`` count it);
* ``end_epoch(run, net, mp) -> (state, wgain)``: at the end of the epoch; ``wgain`` is what the epoch trained (kept,
  tested, and the next epoch's start).

``mp`` is the traced :class:`~jaxarm.learning.metaparams.MetaParams` (a rule reads the fields it uses), so every
function ``vmap``-s over networks and metaparameter sets. A rule that does not learn inside the loop's intervals
(gradient learning trains by whole reaches) sets :attr:`LearningRule.make_train` instead and builds its own
``TrainFns`` (:mod:`jaxarm.learning.training`).
"""
from __future__ import annotations

import dataclasses
import typing
from typing import Any, Callable, ClassVar, NamedTuple

import jax.numpy as jnp


class Moment(NamedTuple):
    """What the loop observed in one training interval, for the rule's ``update``."""

    t_ms: jnp.ndarray       # () time since the start of the run (epoch) at the end of the interval, ms
    err_hist_m: jnp.ndarray  # (2,) the critic's error at the two interface times before the interval's arm step,
    #                          older first (m: hand-target distance; rad with LoopConfig.critic_error = "angle")
    err_m: jnp.ndarray      # () the same error after the interval's arm step


def plastic_upper(is_ee, mp):
    """Upper bound of every plastic synapse's gain: plast_ee_maxw onto E cells, plast_ei_maxw onto I cells (``is_ee``:
    the loop's ``plastic_tables``)."""
    return jnp.where(is_ee, mp.plast_ee_maxw, mp.plast_ei_maxw)


class LearningRule:
    """Base of every learning rule: the static configuration and the loop it runs in.

    A subclass sets :attr:`Config` (its frozen configuration dataclass), :attr:`summary` (one line for
    ``jaxarm train --help``) and implements the four functions of the module docstring, or sets :attr:`make_train`.
    ``loop`` (a :class:`jaxarm.loop.ClosedLoop`) gives the static tables a rule may need: ``loop.net.layout``
    (``n_plastic``: the plastic synapses come first in ``wgain``), ``loop.plastic_tables``, ``loop.config``.
    """

    Config: ClassVar[type]
    summary: ClassVar[str]
    #: (loop_config, record, interval_train) -> TrainFns for a rule that replaces the epoch loop (None: the interval
    #: hooks run); ``interval_train(loop_config, record)`` (:func:`jaxarm.train.make_interval_train`) builds the
    #: interval rules' TrainFns, whose ``loop`` and ``test`` such a rule may reuse: the rule imports neither the loop
    #: nor ``jaxarm.train``, which sit above it
    make_train: ClassVar[Callable | None] = None

    def __init__(self, config, loop):
        self.config = config
        self.loop = loop

    def init(self, key) -> Any:
        raise NotImplementedError

    def begin_epoch(self, state, wgain, mp):
        raise NotImplementedError

    def update(self, run, net, key, moment: Moment, mp):
        raise NotImplementedError

    def end_epoch(self, run, net, mp):
        raise NotImplementedError

    # -- the command line (jaxarm train): a rule's own options, none by default -----------------------------------
    @classmethod
    def add_arguments(cls, group) -> None:
        """Add this rule's ``jaxarm train`` options to the argparse ``group``."""

    @classmethod
    def config_from_arguments(cls, args):
        """This rule's configuration from the parsed ``jaxarm train`` options."""
        return cls.Config()


def config_from_dict(cls: type, values: dict):
    """A configuration dataclass from its :func:`dataclasses.asdict` (a run folder's JSON), nested ones included. A
    field renamed since the record was written is read under its new name (the class's ``RENAMED_FIELDS``, former
    name -> current one)."""
    hints = typing.get_type_hints(cls)
    renamed = getattr(cls, "RENAMED_FIELDS", {})
    values = {renamed.get(k, k): v for k, v in values.items()}
    return cls(**{k: config_from_dict(hints[k], v) if isinstance(v, dict) and dataclasses.is_dataclass(hints[k])
                  else v for k, v in values.items()})
