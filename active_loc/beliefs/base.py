"""The interface every pose belief offers, whatever its filter."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray


@runtime_checkable
class Belief(Protocol):
    """A batch of B pose beliefs.

    ``predict`` applies controls ``(B, 2)`` (V m/s, omega rad/s); ``update`` applies one scan;
    ``entropy`` is in nats as :mod:`active_loc.beliefs.entropy` defines it; ``copy`` is deep, so
    a planner may simulate on it without touching the env's belief.
    """

    @property
    def batch_size(self) -> int: ...

    def predict(self, controls: ArrayLike) -> None: ...

    def update(self, z: ArrayLike, visible: ArrayLike, landmarks: ArrayLike) -> None: ...

    def entropy(self) -> NDArray[np.float64]: ...

    def copy(self) -> Belief: ...
