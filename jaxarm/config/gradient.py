"""Static settings of gradient learning (:mod:`jaxarm.learning.gradient`), the alternative to R-STDP."""
from __future__ import annotations

from dataclasses import dataclass

from jaxarm.config.validate import check_choice, check_range


@dataclass(frozen=True)
class GradientConfig:
    """How the gains are trained by gradient descent through the closed loop.

    Attributes:
        learning_rate: Adam's step size, in units of a gain (every gain starts at 1).
        reach_s: length of one training reach (one gradient step), s.
        params: "plastic" (the synapses R-STDP trains) or "all" (every synapse's gain but P->ES).
        width_mv, scale: width (mV) and dampening of the surrogate spike derivative
            (``NetworkConfig.surrogate_width_mv``, ``surrogate_scale``).
    """

    learning_rate: float = 0.05
    reach_s: float = 1.0
    params: str = "plastic"
    width_mv: float = 2.0
    scale: float = 0.05

    def __post_init__(self):
        check_range(self, "learning_rate", 0.0, 10.0, lo_open=True)
        check_range(self, "reach_s", 0.0, 60.0, lo_open=True)
        check_choice(self, "params", ("plastic", "all"))
        check_range(self, "width_mv", 0.01, 100.0)
        check_range(self, "scale", 0.0, 1.0, lo_open=True)
