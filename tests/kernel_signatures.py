"""How many compiled signatures sensorgym's numba kernels hold in this process: a test that
counts before and after knows whether a kernel was compiled (or loaded from the disk cache)
for new argument types, which costs up to a minute on a fresh install."""

from __future__ import annotations

import sys


def kernel_signatures() -> int:
    """The number of signatures of every numba dispatcher in a loaded ``sensorgym`` module."""
    from numba.core.dispatcher import Dispatcher

    return sum(
        len(obj.signatures)
        for name, module in list(sys.modules.items())
        if name.startswith("sensorgym.")
        for obj in vars(module).values()
        if isinstance(obj, Dispatcher)
    )
