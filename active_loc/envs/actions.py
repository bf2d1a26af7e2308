"""Action encodings: a continuous box or a set of motion primitives, decoded to (V, omega).

Continuous actions ``a in [-1, 1]^2`` map linearly to ``V in [v_min, v_max]`` (m/s) and
``omega in [-omega_max, omega_max]`` (rad/s); values outside [-1, 1] are clipped, NaN or inf
is an error. Discrete actions index :data:`PRIMITIVES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

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


def check_action(action: Any, space: spaces.Space, name: str = "action") -> Any:
    """One action checked against its space before anything moves: for a ``Discrete`` space
    an integer index in range (an int, a numpy integer or a 0-d integer array; no bool), for
    a ``Box`` real numbers of the space's shape, finite. Array-likes (lists, torch tensors on
    the CPU) are converted. Returns the index as an int, or the action as an array.

    Raises:
        ValueError: naming ``name`` and what is allowed.
    """
    if isinstance(space, spaces.Discrete):
        if isinstance(action, (bool, np.bool_)):
            index = None
        elif isinstance(action, (int, np.integer)):
            index = int(action)
        else:
            array = _as_array(action)
            ok = array is not None and array.ndim == 0 and array.dtype.kind in "iu"
            index = int(array) if ok else None  # type: ignore[arg-type]
        if index is None:
            raise ValueError(f"{name} must be an integer index, got {action!r}")
        low, high = int(space.start), int(space.start + space.n)
        if not low <= index < high:
            raise ValueError(f"{name} must be an integer in [{low}, {high}), got {index}")
        return index
    array = _as_array(action)
    if array is None or array.shape != space.shape:
        shape = None if array is None else array.shape
        raise ValueError(f"{name} must have shape {space.shape}, got {shape}")
    if array.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be real numbers, got dtype {array.dtype}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf: {action!r}")
    return array


def check_actions(
    actions: Any, space: spaces.Space, active: NDArray[np.bool_], check_finite: bool = True
) -> NDArray:
    """A batch of actions ``(n, *space.shape)``, one per sub-env, checked as
    :func:`check_action` checks one, before any sub-env moves; only the ``active`` ``(n,)``
    sub-envs' values are checked (with ``check_finite``, also for NaN and inf). Raises
    ``ValueError`` naming the first bad sub-env."""
    n = active.shape[0]
    array = _as_array(actions)
    if array is None:
        raise ValueError(f"expected {n} actions (one per sub-env), got {actions!r}")
    if isinstance(space, spaces.Discrete):
        if array.shape != (n,) or array.dtype.kind not in "iu":
            raise ValueError(f"actions must be integers of shape ({n},) for a discrete action "
                             f"space, got {array.dtype} {array.shape}")
        low, high = int(space.start), int(space.start + space.n)
        bad = active & ((array < low) | (array >= high))
        if bad.any():
            b = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"the action of sub-env {b} must be in [{low}, {high}), got {array[b]}"
            )
    elif isinstance(space, spaces.Box):
        shape = (n, *space.shape)
        if array.shape != shape or array.dtype.kind not in "fiu":
            raise ValueError(f"actions must be real numbers of shape {shape}, got {array.dtype} "
                             f"{array.shape}")
        if check_finite:
            finite = np.isfinite(array.reshape(n, -1)).all(axis=1) | ~active
            if not finite.all():
                b = int(np.flatnonzero(~finite)[0])
                raise ValueError(f"the action of sub-env {b} contains NaN or inf: {array[b]!r}")
    elif len(array) != n:
        raise ValueError(f"expected {n} actions (one per sub-env), got {len(array)}")
    return array


def _as_array(value: Any) -> NDArray | None:
    """``value`` as a numpy array (torch tensors included), or None when it is not one."""
    if isinstance(value, np.ndarray):
        return value
    detach = getattr(value, "detach", None)  # a torch tensor: to the CPU, then numpy
    if detach is not None:
        tensor = detach().cpu()
        if tensor.is_floating_point() and tensor.element_size() == 2:
            tensor = tensor.float()  # numpy has no bfloat16; float16 widens exactly too
        value = tensor.numpy()
    try:
        return np.asarray(value)
    except (TypeError, ValueError):
        return None
