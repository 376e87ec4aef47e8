"""mmstab.core.clib's array argument types: the address of the array, the same refusals as
NumPy's ``ndpointer``."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from mmstab.core.clib import BYTES, DOUBLES, LONGS, array_pointer


def _memcpy(argtype):
    """libc's memcpy(dst, src, n), its arrays passed as ``argtype``."""
    f = ctypes.CDLL(None).memcpy
    f.argtypes, f.restype = [argtype, argtype, ctypes.c_size_t], ctypes.c_void_p
    return f


@pytest.mark.parametrize(
    ("argtype", "dtype"),
    [
        (DOUBLES, np.float64),
        (LONGS, np.int64),
        (BYTES, np.uint8),
        (array_pointer(np.uintp), np.uintp),
    ],
)
def test_array_pointer_passes_the_data_and_refuses_what_ndpointer_refuses(argtype, dtype):
    src = np.arange(1, 13).astype(dtype)
    dst = np.zeros(12, dtype=dtype)
    address = _memcpy(argtype)(dst, src, src.nbytes)
    assert address == dst.ctypes.data  # memcpy returns dst: the array's own data
    assert np.array_equal(dst, src)
    view = np.zeros(24, dtype=dtype)[5:17]  # an offset view: its own address
    _memcpy(argtype)(view, src, src.nbytes)
    assert np.array_equal(view, src)
    other = np.float32 if dtype != np.float32 else np.float64
    for bad in (src[::2], src.astype(other), list(src), None):  # strided, dtype, not arrays
        with pytest.raises(ctypes.ArgumentError):
            _memcpy(argtype)(dst, bad, 8)
        ref = np.ctypeslib.ndpointer(dtype=dtype, flags="C_CONTIGUOUS")
        with pytest.raises(ctypes.ArgumentError):
            _memcpy(ref)(dst, bad, 8)
