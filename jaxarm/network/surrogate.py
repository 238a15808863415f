"""Surrogate spike derivatives: spikes exactly as the ordinary kernel fires them on the forward pass, a smooth
pseudo-derivative of the threshold on the backward pass (``NetworkConfig.spike_gradient``).

A spike is a step function of the margin ``x = Vm - VTHC`` (mV), whose derivative is zero almost everywhere, so
no gradient reaches a weight through a spike. The surrogate keeps the forward value (0 or 1, bit for bit the
spike the cell step decided, depolarisation block and refractoriness included) and replaces d spike / d x on the
backward pass by the fast-sigmoid ("SuperSpike", Zenke & Ganguli 2018, Neural Comput. 30:1514) density

    d spike / d x = g / (2 w (1 + |x| / w)^2)       (per mV; it integrates to g over x)

of width ``w = NetworkConfig.surrogate_width_mv`` and dampening ``g = NetworkConfig.surrogate_scale``, outside
the absolute refractory period only (a refractory cell cannot fire whatever its margin). The dampening (Bellec
et al. 2018, NeurIPS, use 0.3) matters here: the surrogate is taken at every 0.25 ms step, and a cell's margin
stays raised for hundreds of ms (NMDA, tau 300 ms), so the recurrent ES/EM loops multiply it. Measured
(``experiments/surrogate_gradient.py``, docs/gradients.md): at w = 2 mV, the gradient of the noise-averaged EM
spike count in 200 ms is finite and steady up to g = 0.05 (sd 8 % of the mean over noise streams), spreads at
g = 0.1 (sd 29 %) and explodes at g = 0.2; it is 0.14-0.65 of the finite-difference slope at g = 0.01-0.1, so it
points the right way but underestimates. The resets after a spike (AHP, dynamic
threshold) are not differentiated through the spike, the usual choice (Zenke & Vogels 2021, Neural Comput.
33:899).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

def fast_sigmoid(margin_mv, width_mv: float):
    """The antiderivative of the fast-sigmoid density: ``x / (2 (w + |x|))`` in (-1/2, 1/2), dimensionless."""
    return margin_mv / (2.0 * (width_mv + jnp.abs(margin_mv)))


def spike_value(spiked, margin_mv, eligible, width_mv: float, scale: float = 1.0):
    """float32 spikes: forward exactly ``spiked`` (0.0 or 1.0); backward ``scale`` times the fast-sigmoid
    density of ``margin_mv`` (Vm - VTHC, mV) where ``eligible`` (not refractory), else 0."""
    smooth = jnp.where(eligible, scale * fast_sigmoid(margin_mv, width_mv), 0.0)
    # s + (f - stop_gradient(f)): f - f is exactly 0.0 for any finite f, so the forward value is the spike itself
    return jnp.asarray(spiked).astype(jnp.float32) + (smooth - jax.lax.stop_gradient(smooth))
