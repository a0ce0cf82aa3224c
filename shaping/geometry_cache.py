"""What a job's geometry alone decides, computed once per geometry.

A study plans one job under many settings (accelerations, corner rules, frequency limits): every
copy of the parsed job (:func:`dataclasses.replace`, :meth:`Job.with_feed`) shares its moves'
ends, labels and stops as the same arrays. What depends on those arrays alone — the paths' direction-
change wavelengths, the corners and reversals the quality windows are chosen from — is kept here by
the arrays' identity (the arrays themselves kept alive with it, so no id is reused while cached)
and handed out as read-only arrays.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Callable, Sequence, TypeVar

import numpy as np

T = TypeVar("T")

#: geometries kept (a study has one job; a plate or a rewritten job adds a few)
MAX_ENTRIES = 32

_CACHE: OrderedDict = OrderedDict()


def by_geometry(name: str, arrays: Sequence[np.ndarray], extra: tuple, compute: Callable[[], T]) -> T:
    """``compute()`` for the geometry held by ``arrays`` (and the hashable ``extra`` arguments),
    once: later calls with the same array objects get the same result. Arrays in the result are
    made read-only, so no caller can change what another is handed."""
    key = (name, tuple(id(a) for a in arrays), extra)
    hit = _CACHE.get(key)
    if hit is not None and all(x is y for x, y in zip(hit[0], arrays)):
        _CACHE.move_to_end(key)
        return hit[1]
    value = compute()
    _freeze(value)
    _CACHE[key] = (tuple(arrays), value)
    while len(_CACHE) > MAX_ENTRIES:
        _CACHE.popitem(last=False)
    return value


def _freeze(value) -> None:
    """Make every array in ``value`` (an array or nested tuples of them) read-only."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif isinstance(value, tuple):
        for v in value:
            _freeze(v)
