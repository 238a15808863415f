"""When a surrogate spike derivative arrives: the tangent of a cell's spike (and of a near-threshold non-spike) must
reach the ring slots of that step plus each synapse's delay, as the spike itself does, never slots fixed by the
step counter's origin (the bug of issue 46: a cell that did not fire sent its derivative from step 0)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.config.network import NetworkConfig
from jaxarm.network.network import Network, NetworkParams
from jaxarm.network.populations import Populations
from jaxarm.network.wiring import AMPA, N_CHANNELS

START = 100        # the block runs steps 101..105 (a multiple of the block from the start of the run)
INPUT_STEP = 103   # the cell's one input arrives here; before it the cell rests far below threshold


def _setup(block_steps: int = 0):
    net = Network(NetworkConfig(kernel="xla", spike_gradient="fast_sigmoid", block_steps=block_steps))
    assert net.block_steps == (5 if block_steps == 0 else block_steps)
    wiring = net.make_wiring(jax.random.key(0))
    state = net.set_lengths(net.init(jax.random.key(1)), jnp.array([0.10, 0.12, 0.10, 0.14]))
    # no background events at all, so the cell's membrane follows only the input we put in
    state = state._replace(step=jnp.asarray(START, jnp.int32),
                           noise=state.noise._replace(events_left=jnp.zeros_like(state.noise.events_left)))
    cell = Populations(net.config).slice("EM").start + 7
    return net, wiring, state, cell


def _run(net, wiring, state, cell, amplitude, d_ampa):
    """One block from START with an AMPA input of ``amplitude`` (ring units) onto ``cell`` at INPUT_STEP and the
    cell's AMPA state moved by ``d_ampa`` (mV): (ring after the block's delivery, spikes (5, n_all))."""
    n = net.config.n_cells
    slot = (INPUT_STEP % net.n_slots) * N_CHANNELS * n + AMPA * n + cell
    state = state._replace(ring=state.ring.at[slot].set(amplitude),
                           cells=state.cells._replace(ampa=state.cells.ampa.at[cell].add(d_ampa)))
    out, spikes = net.run(wiring, state, NetworkParams.original(), 5)
    return out.ring, spikes


def _threshold_amplitude(net, wiring, state, cell):
    """The smallest input (to 1e-4) at INPUT_STEP that fires the cell there, by bisection on the forward spikes
    (an input far above it overshoots into depolarisation block, so the search starts from the first that fires)."""
    fires = jax.jit(lambda a: _run(net, wiring, state, cell, a, 0.0)[1][INPUT_STEP - START - 1, cell] > 0.5)
    lo, hi = 0.0, next(float(a) for a in np.arange(5.0, 200.0, 5.0) if bool(fires(float(a))))
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if bool(fires(mid)) else (mid, hi)
    return hi


def _tangent_slots(net, wiring, state, cell, amplitude):
    """Ring tangent of the block wrt the cell's AMPA state, as (slot, channel-major row) -> value, nonzero only."""
    _, tangent = jax.jit(lambda: jax.jvp(lambda x: _run(net, wiring, state, cell, amplitude, x)[0], (0.0,), (1.0,)))()
    t = np.asarray(tangent)[: net.n_slots * N_CHANNELS * net.config.n_cells].reshape(net.n_slots, -1)
    return {(int(s), int(r)): float(t[s, r]) for s, r in zip(*np.nonzero(t))}


def _expected(net, wiring, cell, step):
    """{(slot, row)} the cell's synapses reach from ``step``: AMPA row (target) and NMDA row (target + n_cells)."""
    pre, delay, target = (np.asarray(a) for a in (wiring.pre, wiring.delay_steps, wiring.target))
    mine = pre == cell
    assert mine.sum() > 10
    n = net.config.n_cells
    return {((step + d) % net.n_slots, int(r + k * n)) for d, r in zip(delay[mine], target[mine]) for k in (0, 1)}


@pytest.mark.parametrize("fires", [False, True], ids=["near-threshold non-spike", "spike"])
def test_surrogate_tangent_leaves_at_the_step_of_the_crossing(fires):
    net, wiring, state, cell = _setup()
    a_star = _threshold_amplitude(net, wiring, state, cell)
    amplitude = a_star * (1.2 if fires else 0.9)
    _, spikes = _run(net, wiring, state, cell, amplitude, 0.0)
    assert np.asarray(spikes[:, cell]).tolist() == [0, 0, float(fires), 0, 0]
    got = _tangent_slots(net, wiring, state, cell, amplitude)
    assert set(got) == _expected(net, wiring, cell, INPUT_STEP), sorted(set(got) ^ _expected(net, wiring, cell,
                                                                                             INPUT_STEP))
    assert all(v > 0 for (_, r), v in got.items()), "an excitatory cell's derivative wrt its own AMPA is positive"


def test_block_delivery_moves_a_derivative_only_in_time_against_per_step_delivery():
    # Per-step delivery (block_steps = 1) puts each step's derivative at its own step + delay: the block's tangent
    # summed over the block's five arrival slots of each synapse equals it (time moved, nothing lost or added), and
    # the largest share is the one from the step nearest threshold, where block delivery puts all of it.
    net5, wiring, state, cell = _setup()
    net1, _, _, _ = _setup(block_steps=1)
    amplitude = 0.9 * _threshold_amplitude(net5, wiring, state, cell)
    per_block = _tangent_slots(net5, wiring, state, cell, amplitude)
    per_step = _tangent_slots(net1, wiring, state, cell, amplitude)
    assert set(per_block) <= set(per_step) and len(per_step) > len(per_block)
    pre, delay, target = (np.asarray(a) for a in (wiring.pre, wiring.delay_steps, wiring.target))
    n = net5.config.n_cells
    for d, r in zip(delay[pre == cell], target[pre == cell]):
        for row in (int(r), int(r) + n):
            spread = [per_step.get(((START + k + d) % net5.n_slots, row), 0.0) for k in range(1, 6)]
            np.testing.assert_allclose(sum(spread), per_block[((INPUT_STEP + d) % net5.n_slots, row)], rtol=1e-5)
            assert int(np.argmax(spread)) == INPUT_STEP - START - 1
