"""Action encodings: a continuous box or a set of motion primitives, decoded to (V, omega).

Continuous actions ``a in [-1, 1]^2`` map linearly to ``V in [v_min, v_max]`` (m/s) and
``omega in [-omega_max, omega_max]`` (rad/s); values outside [-1, 1] are clipped, NaN or inf
is an error. Discrete actions index :data:`PRIMITIVES`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

#: motion primitives as (fraction of v_max, fraction of omega_max); the speed is then
#: clipped into [v_min, v_max]
PRIMITIVES: tuple[tuple[str, float, float], ...] = (
    ("stay", 0.0, 0.0),
    ("forward", 1.0, 0.0),
    ("forward_left", 1.0, 0.5),
    ("forward_right", 1.0, -0.5),
    ("turn_left", 0.0, 1.0),
    ("turn_right", 0.0, -1.0),
)
PRIMITIVE_NAMES = tuple(name for name, _, _ in PRIMITIVES)


@dataclass(frozen=True)
class ControlLimits:
    """How env actions become controls: what a planner needs to decode them.

    Attributes:
        action_type: ``"continuous"`` or ``"discrete"``.
        dt: time step (s).
        v_min, v_max: forward speed range (m/s).
        omega_max: turn rate range ``[-omega_max, omega_max]`` (rad/s).
    """

    action_type: str
    dt: float
    v_min: float
    v_max: float
    omega_max: float

    def primitives(self) -> NDArray[np.float64]:
        """``(len(PRIMITIVES), 2)`` physical controls of the discrete primitives."""
        return primitive_controls(self.v_min, self.v_max, self.omega_max)

    def decode(self, action: object) -> NDArray[np.float64]:
        """Physical control (V m/s, omega rad/s) of one env action, as the env decodes it."""
        if self.action_type == "discrete":
            return self.primitives()[int(action)]  # type: ignore[call-overload]
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0)
        v = self.v_min + 0.5 * (a[0] + 1.0) * (self.v_max - self.v_min)
        return np.array([v, a[1] * self.omega_max])

    def encode(self, controls: NDArray) -> NDArray[np.float64]:
        """Continuous action(s) that decode to ``controls`` ``(..., 2)``; float64 so that exact
        controls survive the round trip."""
        return controls_to_continuous(controls, self.v_min, self.v_max, self.omega_max)


def action_space(action_type: str) -> spaces.Space:
    """``Box(-1, 1, (2,), float32)`` or ``Discrete(len(PRIMITIVES))``."""
    if action_type == "continuous":
        return spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
    return spaces.Discrete(len(PRIMITIVES))


def primitive_controls(v_min: float, v_max: float, omega_max: float) -> NDArray[np.float64]:
    """``(len(PRIMITIVES), 2)`` physical controls (V m/s, omega rad/s) of the primitives."""
    table = np.array([(f_v * v_max, f_w * omega_max) for _, f_v, f_w in PRIMITIVES])
    table[:, 0] = np.clip(table[:, 0], v_min, v_max)
    return table


def controls_to_continuous(
    controls: NDArray, v_min: float, v_max: float, omega_max: float
) -> NDArray[np.float64]:
    """Inverse of the continuous decoding: (V, omega) ``(..., 2)`` -> actions in [-1, 1].

    Returns float64 so that an agent's exact controls survive the round trip.
    """
    controls = np.asarray(controls, dtype=np.float64)
    span = max(v_max - v_min, 1e-12)
    a_v = 2.0 * (controls[..., 0] - v_min) / span - 1.0
    a_w = controls[..., 1] / omega_max if omega_max > 0 else np.zeros_like(controls[..., 1])
    return np.stack([a_v, a_w], axis=-1)
