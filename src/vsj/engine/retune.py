"""Runs that differ only in parameters the compiled model carries unchanged.

Building, assembling and compiling the wrist (`vsj.engine.compile_model`) costs a
few milliseconds, a sizeable part of a 10 s run. Many studies vary quantities
that reach the compiled arrays untouched: a friction element's stiction level or
viscous coefficient is stored as it is in its row of ``par``. `find_passthrough`
finds, for each such parameter, the entries of the arrays that hold it, by
compiling the model at other values of it; `retune` writes a run's values there.
The value written is the number the compiler would have stored, so a retuned
model equals the one compiled from scratch bit for bit.

A parameter counts as pass-through only if, at every value tried, the entries
that change hold exactly that value (and held the base value before), the same
entries each time, in the per-run arrays only (`RETUNABLE`), and everything else
compiled stays bit for bit as it was. Anything else (a product with another
parameter, a ratio, a change of the mass matrix or the kinematics) is compiled
in full for each run. With several parameters varied at once, `find_passthrough`
also compiles them changed together and drops a parameter whose entries do not
then predict the result.

Arrays are compared as bit patterns (so ``-0.0`` differs from ``0.0``, and a NaN
from another NaN's payload), because what is checked is identity, not closeness.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

#: The arrays that may differ between the runs of one batch (`vsj.engine.plan.run_batch`).
RETUNABLE = ("mass", "Minv", "par")

Arrays = Mapping[str, np.ndarray]
#: Where a parameter lands: (array name, flat indices) pairs.
Slots = tuple[tuple[str, np.ndarray], ...]


def _bits(a) -> np.ndarray:
    """The bit patterns of a float64 array, flat."""
    return np.ascontiguousarray(a, dtype=np.float64).reshape(-1).view(np.int64)


def _bit(value: float) -> np.int64:
    return np.array([value], dtype=np.float64).view(np.int64)[0]


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _landing(ref: Arrays, changed: Arrays, before: float, value: float,
             fields: Sequence[str]) -> Slots | None:
    """Entries where ``changed`` differs from ``ref``, if all hold ``value`` (and held
    ``before``) and lie in ``fields``; None if the change is anything else."""
    if set(changed) != set(ref):
        return None
    slots = []
    for name in sorted(ref):
        a, b = np.asarray(ref[name]), np.asarray(changed[name])
        if _same(a, b):
            continue
        if name not in fields or a.shape != b.shape or a.dtype != np.float64 \
                or b.dtype != np.float64:
            return None
        old, new = _bits(a), _bits(b)
        where = np.flatnonzero(old != new)
        if np.any(new[where] != _bit(value)) or np.any(old[where] != _bit(before)):
            return None
        slots.append((name, where))
    return tuple(slots)


def _equal_slots(a: Slots, b: Slots) -> bool:
    return (len(a) == len(b) and all(na == nb and np.array_equal(ia, ib)
                                     for (na, ia), (nb, ib) in zip(a, b)))


def find_passthrough(build: Callable[[Mapping[str, float]], Arrays | None],
                     base: Mapping[str, float], probes: Mapping[str, Sequence[float]],
                     joint: Sequence[Mapping[str, float]] = (),
                     fields: Sequence[str] = RETUNABLE) -> dict[str, Slots]:
    """The keys of ``probes`` that pass through to the compiled arrays, with where.

    ``build(values)`` compiles the model with ``values`` (one per key of ``base``)
    and returns its arrays by name, or None where those values cannot be built.
    Each key is tried at its ``probes`` (the others at ``base``); it needs two
    values that differ from its base value, every one of them built. ``joint``
    holds further points with every key changed at once: there the keys found are
    retuned on the model built with them at their base values (the others as in
    the point), and must give the model built at the point.
    """
    ref = build(dict(base))
    if ref is None:
        return {}
    found: dict[str, Slots] = {}
    for key, values in probes.items():
        slots, tried = None, 0
        for value in values:
            if _bit(value) == _bit(base[key]):
                continue
            changed = build({**base, key: value})
            landing = None if changed is None else _landing(ref, changed, base[key], value,
                                                            fields)
            if landing is None or (slots is not None and not _equal_slots(slots, landing)):
                slots = None
                break
            slots, tried = landing, tried + 1
        if slots is not None and tried >= 2:
            found[key] = slots
    for point in joint:
        while found:
            start = build({k: base[k] if k in found else v for k, v in point.items()})
            target = build(dict(point))
            if start is None or target is None:
                break
            predicted = retune(start, found, point)
            wrong = {name: np.flatnonzero(_bits(predicted[name]) != _bits(target[name]))
                     for name in target if not _same(predicted[name], target[name])}
            if not wrong:
                break
            culprits = [k for k, slots in found.items()
                        if any(name in wrong and np.intersect1d(idx, wrong[name]).size
                               for name, idx in slots)]
            for key in culprits or list(found):
                del found[key]
    return found


def retune(arrays: Arrays, found: Mapping[str, Slots], values: Mapping[str, float]
           ) -> dict[str, np.ndarray]:
    """``arrays`` with each pass-through key's entries set to its value in ``values``
    (copies of the arrays written; the others shared)."""
    out = dict(arrays)
    for key, slots in found.items():
        for name, where in slots:
            if out[name] is arrays[name]:
                out[name] = np.array(arrays[name], dtype=np.float64, order="C")
            out[name].reshape(-1)[where] = values[key]
    return out


__all__ = ["RETUNABLE", "find_passthrough", "retune"]
