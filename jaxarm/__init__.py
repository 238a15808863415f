"""jaxarm: a spiking cortical network driving a musculoskeletal arm, in JAX (Dura-Bernal et al. 2015).

Units: SI (m, s, rad, N) for the arm; ms and mV for neurons. Each boundary says which.
"""
__version__ = "0.1.0"

from jaxarm import cpu_arithmetic, cpu_dispatch

cpu_arithmetic.pin()   # before anything starts JAX's CPU backend: see jaxarm.cpu_arithmetic
cpu_dispatch.unroll_threefry()   # the same random numbers in fewer XLA:CPU thunks: see jaxarm.cpu_dispatch
cpu_dispatch.pool_threads(1)     # one XLA:CPU pool thread per device (jaxarm.parallel.start: its device count)

from jaxarm.arm import make_arm  # noqa: E402

__all__ = ["make_arm", "__version__"]
