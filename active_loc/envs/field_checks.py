"""Checks of configuration fields, shared by every config class.

Each check raises ``ValueError`` naming the field and what it allows, so that a bad keyword
of ``gymnasium.make`` is refused before any work is done. :func:`check_memory` refuses a
config whose largest arrays would exceed :data:`MEMORY_BOUND_BYTES` before they are
allocated.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

#: smallest and largest noise standard deviation (m or rad): below, variances underflow and
#: entropies reach -inf; above, squares overflow
MIN_STD = 1e-6
MAX_STD = 1e6
#: the memory one env's configuration may ask for (bytes), checked before allocating
MEMORY_BOUND_BYTES = 8 * 2**30


def check_choice(name: str, value: object, allowed: tuple[str, ...]) -> None:
    """``value`` is one of the names ``allowed``."""
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name}={value!r} is not one of {allowed}")


def check_bool(name: str, value: object) -> None:
    """``value`` is a bool (not a string or a number read by its truthiness)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")


def is_number(value: object) -> bool:
    """Whether ``value`` is a real number (a bool is not)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def is_finite_number(value: object) -> bool:
    """Whether ``value`` is a finite real number."""
    return is_number(value) and math.isfinite(float(value))  # type: ignore[arg-type]


def check_number(name: str, value: object) -> None:
    """``value`` is a real number (inf and NaN pass; the range checks refuse them)."""
    if not is_number(value):
        raise ValueError(f"{name} must be a number, got {value!r}")


def check_positive(name: str, value: object, allow_zero: bool = False) -> None:
    """``value`` is a finite number > 0 (>= 0 with ``allow_zero``)."""
    check_number(name, value)
    v = float(value)  # type: ignore[arg-type]
    if not (math.isfinite(v) and (v >= 0 if allow_zero else v > 0)):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")


def check_integer(name: str, value: object, minimum: int, maximum: int | None = None) -> None:
    """``value`` is an integer in ``[minimum, maximum]``."""
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    if ok and value >= minimum and (maximum is None or value <= maximum):  # type: ignore[operator]
        return
    allowed = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
    raise ValueError(f"{name} must be an integer {allowed}, got {value!r}")


def check_std(name: str, value: object, allow_zero: bool = False) -> None:
    """``value`` is a noise standard deviation in ``[MIN_STD, MAX_STD]`` (or 0 with
    ``allow_zero``)."""
    check_positive(name, value, allow_zero=allow_zero)
    v = float(value)  # type: ignore[arg-type]
    if (v != 0.0 or not allow_zero) and not MIN_STD <= v <= MAX_STD:
        zero = "0 or " if allow_zero else ""
        raise ValueError(f"{name} must be {zero}in [{MIN_STD:g}, {MAX_STD:g}], got {value!r}")


def numbers(name: str, values: object, count: int) -> tuple[float, ...]:
    """``values`` as ``count`` finite numbers: a tuple, list or 1-D array of them."""
    if isinstance(values, (str, bytes)) or not isinstance(values, (tuple, list, np.ndarray)):
        raise ValueError(f"{name} must be {count} finite numbers, got {values!r}")
    items = list(np.asarray(values).ravel()) if isinstance(values, np.ndarray) else list(values)
    if len(items) != count or not all(is_finite_number(v) for v in items):
        raise ValueError(f"{name} must be {count} finite numbers, got {values!r}")
    return tuple(float(v) for v in items)


def integers(name: str, values: object, count: int) -> tuple[int, ...]:
    """``values`` as ``count`` integers: a tuple, list or 1-D array of them."""
    if isinstance(values, (str, bytes)) or not isinstance(values, (tuple, list, np.ndarray)):
        raise ValueError(f"{name} must be {count} integers, got {values!r}")
    items = list(np.asarray(values).ravel()) if isinstance(values, np.ndarray) else list(values)
    if len(items) != count or not all(
        isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) for v in items
    ):
        raise ValueError(f"{name} must be {count} integers, got {values!r}")
    return tuple(int(v) for v in items)


def check_stds(name: str, values: object, allow_zero: bool) -> None:
    """``values`` are 3 standard deviations (x m, y m, theta rad), each as :func:`check_std`."""
    for v in numbers(f"{name} (x m, y m, theta rad)", values, 3):
        check_std(name, v, allow_zero=allow_zero)


def check_bool_fields(config: object, names: tuple[str, ...]) -> None:
    """Every field of ``names`` of ``config`` is a bool."""
    for name in names:
        check_bool(name, getattr(config, name))


def check_memory(parts: Mapping[str, float]) -> None:
    """Refuse a configuration whose arrays, ``parts`` (what -> bytes), would together exceed
    :data:`MEMORY_BOUND_BYTES`, naming the largest."""
    total = float(sum(parts.values()))
    if total > MEMORY_BOUND_BYTES:
        largest = max(parts, key=lambda k: parts[k])
        raise ValueError(
            f"this configuration needs about {_gib(total)} of arrays (the largest: {largest}, "
            f"{_gib(parts[largest])}), over the bound of {_gib(MEMORY_BOUND_BYTES)}"
        )


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:.3g} GiB"

