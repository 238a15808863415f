"""The metaparameters the authors tuned by evolution, as a pytree of float arrays ([model:
metaparameters](../model.md#metaparameters)).

``MetaParams.original()`` holds the values of the published model (``main.hoc``, marked "optimized" there). Every field
is a float array so that evolution can ``vmap`` over sets of them; code that needs an integer (``explore_tot``)
converts it where it is used, the way the original did (``int()``).

The authors' evolutionary interface (2016 code, same model) has 21 parameters. We keep the 13 that the network, the
readout, the critic and the learning rule read, and add three of our own for the centre-out task's target code
(:data:`CODE_NAMES`, read only by a network with a target code). Left out, with reasons:

* p1 ``maxwscaling`` (0.70): the maxw of I->X synapses, which are not plastic in the 2015 model: no effect. Sets saved
  before it left (presets, results.json) still carry it; :meth:`MetaParams.from_dict` drops it (:data:`RETIRED`).
* p21 ``epochs`` (12): the training length, a property of the protocol (:class:`jaxarm.task.config.TaskConfig`'s
  ``epochs``, a preset's ``protocol``), not of the model; old sets carry it, and a preset without a protocol takes
  its sets' value as the protocol's.
* p7 ``mineligtrdur`` (30.54 ms): not a variable of INTF6; setting it has no effect ([model:
  learning](../model.md#learning-reward-modulated-stdp)).
* p8 msarm ``damping``: a parameter of the musculoskeletal arm executable (an arm option, not a learning one).
* p13: unused; p14 ``COMBERR``, p15/p17 (second training phase with the trajectory error): 2016 paper features,
  off in the 2015 model.

The original's bounds for the search are not available (its Supplementary Material could not be found). The table
:data:`BOUNDS` is ours: each range contains the published value and the 2016 example candidate
(``stimdata/gen_86_cand_151_params``; except its p18 = 0 s, which made the 2016 code rescale at every 10-ms update),
and keeps ``learn_rate <= min(maxw)`` so the soft-bounded update can never leave
[0, maxw] (see :mod:`jaxarm.learning.stdp`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxarm.network.proprio import MAX_CODE_RATE_SCALE


@struct.dataclass
class MetaParams:
    """Tuned metaparameters (float arrays; scalars, or with leading batch axes under ``vmap``).

    Attributes (original value in brackets):
        learn_rate: wgain step ``inc`` of every plastic E->E and E->I synapse, dimensionless [0.040].
        plast_ee_maxw: soft upper bound of wgain on E->E synapses, in units of the initial weight [7.85].
        plast_ei_maxw: soft upper bound of wgain on E->I synapses [5.00].
        max_plast_t_ms: pre-before-post pairing window for tagging, ms [69.57].
        max_elig_tr_dur_ms: lifetime of a tag, ms [62.28].
        v_em_max: motor readout normaliser, EM spikes per muscle group per readout window [117.92].
        mcmd_spk_wd_ms: motor-command spike-counting window, ms [76.08] (with the 50 ms lag and 10 ms rows the
            original counts spikes in (t-130, t-60] ms).
        rl_dt_ms: critic period; an update runs when t - last > rl_dt_ms, checked every 10 ms [55.55 -> 60 ms].
        random_muscle_dt_max_ms: babbling durations ~ U(100, this) ms [624.12]; <= 0 switches to the fixed cycle.
        em_noise_rate_train_hz: AMPA noise rate to the babbling EM group(s) in training, Hz [152.76].
        em_noise_rate_test_hz: AMPA noise rate to all EM cells in the test, Hz [99.01].
        syn_scaling_dt_ms: period of global synaptic scaling in training, ms [5000] (the EA's p18, in s there).
        explore_tot: length of the babbling pattern sequence; patterns 0 .. ceil(explore_tot/2)-1 are drawn [16].
        code_weight_scale: a target code's pathway weights times this, dimensionless [1].
        code_rate_scale: a target code's firing rate times this, dimensionless [1].
        code_density_scale: a target code's pathway density times this (at most 1: the spec's density is the
            largest; the first inputs of each cell are kept), dimensionless [1].

    The last three are ours, not the authors': they tune the target code of the centre-out task
    (:func:`jaxarm.task.centre_out.with_target_code`, :func:`jaxarm.network.proprio.target_code_wiring`) relative to
    the network spec, so evolution can search the code in the same compiled loop. A network without a target code
    (the paper's) does not read them; the reaching fitnesses freeze them.
    """

    learn_rate: jnp.ndarray
    plast_ee_maxw: jnp.ndarray
    plast_ei_maxw: jnp.ndarray
    max_plast_t_ms: jnp.ndarray
    max_elig_tr_dur_ms: jnp.ndarray
    v_em_max: jnp.ndarray
    mcmd_spk_wd_ms: jnp.ndarray
    rl_dt_ms: jnp.ndarray
    random_muscle_dt_max_ms: jnp.ndarray
    em_noise_rate_train_hz: jnp.ndarray
    em_noise_rate_test_hz: jnp.ndarray
    syn_scaling_dt_ms: jnp.ndarray
    explore_tot: jnp.ndarray
    code_weight_scale: jnp.ndarray
    code_rate_scale: jnp.ndarray
    code_density_scale: jnp.ndarray

    @classmethod
    def original(cls) -> "MetaParams":
        """The published model's values (float32 scalars)."""
        return cls.from_dict({})

    @classmethod
    def from_dict(cls, values: dict) -> "MetaParams":
        """Build from ``{name: value}``; missing names take the original values (:data:`ADDED` ones too); the
        :data:`RETIRED` names of sets saved before they left are dropped; other unknown names raise KeyError."""
        values = as_current(values)
        unknown = set(values) - set(ORIGINAL)
        if unknown:
            raise KeyError(f"unknown metaparameter(s) {sorted(unknown)}; known: {', '.join(ORIGINAL)}")
        merged = {**ORIGINAL, **values}
        return cls(**{k: jnp.asarray(v, dtype=jnp.float32) for k, v in merged.items()})

    def to_dict(self) -> dict:
        """``{name: float}`` (unbatched only), e.g. for results.json."""
        # str(float32) is the shortest repr that round-trips, so 0.7 stays 0.7 rather than 0.699999988.
        return {name: float(str(np.float32(getattr(self, name)))) for name in NAMES}


#: The original values (``main.hoc`` setPlastParams/setArmParams/train/test, [model: equations](../model.md#equations)).
ORIGINAL: dict[str, float] = {
    "learn_rate": 0.040,
    "plast_ee_maxw": 7.85,
    "plast_ei_maxw": 5.00,
    "max_plast_t_ms": 69.57,
    "max_elig_tr_dur_ms": 62.28,
    "v_em_max": 117.92,
    "mcmd_spk_wd_ms": 76.08,
    "rl_dt_ms": 55.55,
    "random_muscle_dt_max_ms": 624.12,
    "em_noise_rate_train_hz": 152.76,
    "em_noise_rate_test_hz": 99.01,
    "syn_scaling_dt_ms": 5000.0,
    "explore_tot": 16.0,
    "code_weight_scale": 1.0,   # ours: the target code, relative to its spec (see MetaParams)
    "code_rate_scale": 1.0,
    "code_density_scale": 1.0,
}

#: The metaparameters of a target code (ours; read only by a network that has one).
CODE_NAMES: tuple[str, ...] = ("code_weight_scale", "code_rate_scale", "code_density_scale")

#: Field order (the order of :func:`to_unit` vectors).
NAMES: tuple[str, ...] = tuple(ORIGINAL)

#: Names that sets saved by earlier versions carry and that are no longer metaparameters (see the module docstring):
#: name -> where it went. ``from_dict``, the presets and a resumed run's description drop them.
RETIRED: dict[str, str] = {
    "max_w_scaling": "no effect (I->X synapses are not plastic)",
    "epochs": "the protocol's training length (--epochs, TaskConfig.epochs, a preset's protocol)",
}


#: Names added after sets were first saved (presets, results.json): a set saved without them takes these values,
#: the ones it was made with.
ADDED: dict[str, float] = {name: ORIGINAL[name] for name in CODE_NAMES}


def as_current(values: dict) -> dict:
    """A saved set in this version's names: without the :data:`RETIRED` names, with the :data:`ADDED` ones at their
    values when absent."""
    return {**ADDED, **{k: v for k, v in values.items() if k not in RETIRED}}


class Bound(NamedTuple):
    """Search range of one metaparameter: [lo, hi] in its own units, searched on a "log" or "linear" scale."""

    lo: float
    hi: float
    scale: str
    unit: str


#: Search ranges for evolution (ours; see the module docstring). The authors' EA parameter numbers in comments.
BOUNDS: dict[str, Bound] = {
    "learn_rate": Bound(0.001, 0.2, "log", "1"),                   # p2
    "plast_ee_maxw": Bound(1.0, 20.0, "log", "x initial weight"),  # p3
    "plast_ei_maxw": Bound(1.0, 20.0, "log", "x initial weight"),  # p4
    "max_plast_t_ms": Bound(5.0, 200.0, "linear", "ms"),           # p5
    "max_elig_tr_dur_ms": Bound(10.0, 300.0, "linear", "ms"),      # p6
    "v_em_max": Bound(10.0, 1000.0, "log", "spikes"),              # p9
    "mcmd_spk_wd_ms": Bound(10.0, 200.0, "linear", "ms"),          # p10
    "rl_dt_ms": Bound(10.0, 200.0, "linear", "ms"),                # p11
    "random_muscle_dt_max_ms": Bound(100.0, 2000.0, "linear", "ms"),  # p12
    "em_noise_rate_train_hz": Bound(50.0, 500.0, "linear", "Hz"),  # p16
    "em_noise_rate_test_hz": Bound(10.0, 400.0, "linear", "Hz"),   # p20
    "syn_scaling_dt_ms": Bound(1000.0, 30000.0, "log", "ms"),      # p18
    "explore_tot": Bound(2.0, 32.0, "linear", "patterns x 2"),     # p19
    "code_weight_scale": Bound(0.25, 4.0, "log", "x spec weight"),
    "code_rate_scale": Bound(0.25, MAX_CODE_RATE_SCALE, "log", "x spec rate"),
    "code_density_scale": Bound(0.1, 1.0, "linear", "x spec density"),
}


def _check_table() -> None:
    assert tuple(BOUNDS) == NAMES, "BOUNDS and ORIGINAL must list the same fields in the same order"
    for name, b in BOUNDS.items():
        assert b.scale in ("log", "linear") and b.lo < b.hi and (b.scale == "linear" or b.lo > 0), name
        assert b.lo <= ORIGINAL[name] <= b.hi, name
    assert BOUNDS["learn_rate"].hi <= min(BOUNDS["plast_ee_maxw"].lo, BOUNDS["plast_ei_maxw"].lo)


_check_table()


@jax.jit
def to_unit(mp: MetaParams):
    """Map to the unit cube: (..., len(NAMES)) with 0 = lo, 1 = hi on each field's scale (values outside the
    bounds map outside [0, 1])."""
    cols = []
    for name in NAMES:
        b, v = BOUNDS[name], jnp.asarray(getattr(mp, name), jnp.float32)
        if b.scale == "log":
            cols.append((jnp.log(v) - math.log(b.lo)) / (math.log(b.hi) - math.log(b.lo)))
        else:
            cols.append((v - b.lo) / (b.hi - b.lo))
    return jnp.stack(cols, axis=-1)


@jax.jit
def from_unit(u) -> MetaParams:
    """Inverse of :func:`to_unit`; ``u`` (..., len(NAMES)) is clipped to [0, 1] first, so the result is always
    within :data:`BOUNDS`. Works under ``jit``/``vmap`` (evolution's ask -> MetaParams)."""
    u = jnp.clip(jnp.asarray(u, jnp.float32), 0.0, 1.0)
    fields = {}
    for i, name in enumerate(NAMES):
        b, x = BOUNDS[name], u[..., i]
        if b.scale == "log":
            fields[name] = jnp.exp(math.log(b.lo) + x * (math.log(b.hi) - math.log(b.lo)))
        else:
            fields[name] = b.lo + x * (b.hi - b.lo)
        fields[name] = jnp.clip(fields[name], b.lo, b.hi)   # exp/log round-off must not leave the box
    return MetaParams(**fields)


@jax.jit
def clip_to_bounds(mp: MetaParams) -> MetaParams:
    """Each field clipped to its :data:`BOUNDS` range."""
    return MetaParams(**{n: jnp.clip(jnp.asarray(getattr(mp, n), jnp.float32), BOUNDS[n].lo, BOUNDS[n].hi)
                         for n in NAMES})


def stack(sets) -> MetaParams:
    """Stack a sequence of MetaParams along a new leading axis (for ``vmap`` over metaparameter sets)."""
    return MetaParams(**{n: jnp.stack([jnp.asarray(getattr(s, n)) for s in sets]) for n in NAMES})
