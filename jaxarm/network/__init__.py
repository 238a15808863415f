"""The cortical spiking network of Dura-Bernal et al. 2015 ([model: equations](../model.md#equations)), clock-driven and
vectorised, built from a :class:`~jaxarm.config.spec.NetworkSpec` (the network as data; the paper's by default).

Modules: :mod:`populations` (sizes, ids, muscle groups), :mod:`wiring` (fixed in-degree wiring in per-post-cell
layout), :mod:`cell` (the INTF6 port), :mod:`noise` (background Poisson input), :mod:`synapses` (ring-buffer spike
delivery), :mod:`proprio` (P population code), :mod:`readout` (EM motor readout), :mod:`network` (State, init,
step, run), :mod:`native` (the compiled CPU chunk kernel). Units: ms and mV; muscle lengths in m.
"""
from jaxarm.config.network import NetworkConfig
from jaxarm.config.spec import CellType, NetworkSpec, Pathway, Population, SynapsePhysics
from jaxarm.network.network import MAX_PLAST_T_MS, Network, NetworkParams, State
from jaxarm.network.populations import Populations
from jaxarm.network.wiring import Wiring, WiringLayout, in_degree_table, make_wiring

__all__ = ["NetworkConfig", "NetworkSpec", "Population", "Pathway", "CellType", "SynapsePhysics", "Network",
           "NetworkParams", "State", "MAX_PLAST_T_MS", "Populations", "Wiring", "WiringLayout", "in_degree_table", "make_wiring"]
