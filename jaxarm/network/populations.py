"""Populations, global cell ids, cell types and muscle groups, exactly as the original numbers them ([model:
network](../model.md#network-inputs-and-delays)).

Global ids follow the order of the spec's populations (:class:`jaxarm.config.spec.NetworkSpec`), which for the
paper's network is the order of creation in ``col.hoc``: ES 0-191, IS 192-235, ISL 236-255, EM 256-447, IM 448-491,
IML 492-511 (the 512 INTF6 "network" cells), then the proprioceptive generators P 512-703.

Muscle groups (0 shoulder extensors, 1 shoulder flexors, 2 elbow extensors, 3 elbow flexors): an EM cell's group is
its **global id** % 4 (msarm.hoc L266); a P cell's group is its index within P % 4 and its tuning index is
index // 4 (msarm.hoc assignDP). With the original sizes both rules equal global id % 4 (256 and 512 are multiples
of 4), so the 48 cells of a group are interleaved.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jaxarm.config.network import NetworkConfig

N_GROUPS = 4


@dataclass(frozen=True)
class Populations:
    """Id ranges of one configuration: ``start[pop]`` .. ``stop[pop]`` (exclusive), as Python ints."""

    config: NetworkConfig

    @property
    def start(self) -> dict[str, int]:
        starts, s = {}, 0
        for name, n in zip(self.config.populations, self.config.sizes):
            starts[name] = s
            s += n
        return starts

    @property
    def stop(self) -> dict[str, int]:
        return {name: self.start[name] + self.config.size(name) for name in self.config.populations}

    def ids(self, pop: str) -> np.ndarray:
        return np.arange(self.start[pop], self.stop[pop])

    def slice(self, pop: str) -> slice:
        return slice(self.start[pop], self.stop[pop])

    def population_of(self) -> np.ndarray:
        """(n_all,) int: index into ``config.populations`` of every global id."""
        return np.repeat(np.arange(len(self.config.populations)), self.config.sizes)

    def em_groups(self) -> np.ndarray:
        """(n_readout,) muscle group of each cell of the readout population (EM): global id % 4."""
        return self.ids(self.config.spec.readout) % N_GROUPS

    def p_groups(self) -> np.ndarray:
        """(n_P,) muscle group of each P cell: index % 4."""
        return np.arange(self.config.n_p) % N_GROUPS

    def target_groups(self, name: str) -> np.ndarray:
        """(size,) direction group of each cell of the target code ``name``: index % its ``groups``."""
        pop = self.config.spec.population(name)
        return np.arange(pop.size) % pop.groups

    def p_tuning_index(self) -> np.ndarray:
        """(n_P,) position of each P cell along its group's length axis: index // 4 (the original), or with
        ``NetworkConfig.p_positions``, (index // 4) * p_positions // (n_P / 4)."""
        per_group = self.config.n_p // N_GROUPS
        return (np.arange(self.config.n_p) // N_GROUPS) * self.config.p_positions_per_group // per_group

    def cell_type_of_network_cells(self) -> np.ndarray:
        """(n_cells,) str: the cell type name of each network cell (the paper's "E", "FS", "LTS")."""
        spec = self.config.spec
        return np.concatenate([[spec.population(p).cell_type] * self.config.size(p)
                               for p in spec.network_populations])

    def population_rates_hz(self, spike_counts, duration_ms: float) -> dict[str, float]:
        """Mean rate of every population, Hz, from per-cell spike counts ``(..., n_all)`` over ``duration_ms``
        (averaged over any leading axes, e.g. networks)."""
        counts = np.asarray(spike_counts, dtype=np.float64)
        counts = counts.reshape(-1, counts.shape[-1])
        return {p: float(counts[:, self.slice(p)].mean() * 1000.0 / duration_ms) for p in self.config.populations}
