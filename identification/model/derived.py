"""What follows from a machine's model alone (its axes' travel, its joints' geometry), computed once per machine.

A :class:`~kinid.identification.model.machine.Machine` is frozen and its Pinocchio model is not changed after loading,
so a value derived from them is kept on the machine, under a key, the first time it is asked for.
"""
from __future__ import annotations

__all__ = ["derived"]


def derived(machine, key, make):
    """The value ``make()`` derives from ``machine``'s model, made on the first call with ``key`` and kept."""
    store = machine.__dict__.setdefault("_derived", {})
    if key not in store:
        store[key] = make()
    return store[key]
