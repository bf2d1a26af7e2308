"""A pool of N seeded generated maps, each built once with what the simulators derive from it.

With ``map_pool=N`` an episode draws one of N maps (the index from the episode's Generator)
instead of generating a new one. Map ``i`` is generated from its own seed
``(MAP_POOL_SEED, i)``, so the pool is the same for every env with the same configuration
(like Procgen's ``num_levels``), and the distance field, likelihood table, range table,
free-space sampler and scan lattice of a map are built the first time an episode draws it.
The sub-envs of a vector env share one pool (:func:`shared_pool`), so each map is built once
per process.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

import numpy as np

#: the first word of every pool map's seed (the second is its index)
MAP_POOL_SEED = 20180
#: the largest pool: each map holds up to a few MB of derived tables
MAX_MAP_POOL = 100_000
#: pools kept alive per process (least recently used first out)
_MAX_POOLS = 8

T = TypeVar("T")


def pool_map_rng(index: int) -> np.random.Generator:
    """The Generator that generates map ``index`` of every pool."""
    return np.random.default_rng((MAP_POOL_SEED, index))


class MapPool(Generic[T]):
    """``size`` entries built on first use by ``build(index)`` (thread-safe)."""

    def __init__(self, size: int, build: Callable[[int], T]) -> None:
        self.size = int(size)
        self._build = build
        self._entries: dict[int, T] = {}
        self._lock = threading.Lock()

    def entry(self, index: int) -> T:
        """Entry ``index`` (built now if it is the first time)."""
        entry = self._entries.get(index)
        if entry is None:
            with self._lock:
                entry = self._entries.get(index)
                if entry is None:
                    entry = self._entries[index] = self._build(index)
        return entry

    def draw(self, rng: np.random.Generator) -> T:
        """The entry of an index drawn uniformly with ``rng`` (one draw)."""
        return self.entry(int(rng.integers(self.size)))

    def __len__(self) -> int:
        return self.size


_pools: OrderedDict[Hashable, MapPool] = OrderedDict()
_pools_lock = threading.Lock()


def shared_pool(key: Hashable, size: int, build: Callable[[int], T]) -> MapPool[T]:
    """The process's pool for ``key`` (a configuration), made with ``size`` and ``build`` the
    first time; the last few pools used stay alive."""
    with _pools_lock:
        pool = _pools.get(key)
        if pool is None:
            pool = _pools[key] = MapPool(size, build)
            while len(_pools) > _MAX_POOLS:
                _pools.popitem(last=False)
        else:
            _pools.move_to_end(key)
        return pool
