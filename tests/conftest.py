"""Shared test helpers."""

import math

import numpy as np
import pytest

from scenarios import servo


class LibmNumpy:
    """NumPy with ``arcsin`` and ``cos`` from the C library, as the compiled kernels use.

    NumPy evaluates arcsin/cos with its own SIMD routines on CPUs that have them (x86
    AVX-512), which differ from the C library in the last bit for some arguments; with the
    same library functions both implementations do the same arithmetic, operation for
    operation, so their results must be bit-identical."""

    def __getattr__(self, name):
        return getattr(np, name)

    arcsin = staticmethod(np.vectorize(math.asin, otypes=[float]))
    cos = staticmethod(np.vectorize(math.cos, otypes=[float]))


@pytest.fixture
def libm_numpy(monkeypatch):
    """The NumPy plant functions of :mod:`scenarios.servo` on the C library's arcsin/cos."""
    monkeypatch.setattr(servo, "np", LibmNumpy())
