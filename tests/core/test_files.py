"""``write_npz``: what ``np.load`` reads back, bit for bit, and compressed."""

from __future__ import annotations

import zipfile

import numpy as np

from mmstab.core.files import write_npz


def test_written_arrays_load_back_bit_for_bit(tmp_path):
    rng = np.random.default_rng(7)
    arrays = {
        "float": rng.normal(size=(50, 3)),
        "nan_inf": np.array([np.nan, -np.inf, np.inf, -0.0]),
        "ints": rng.integers(-(2**40), 2**40, 100),
        "flags": rng.random(17) < 0.5,
        "text": np.array(["a", "bc", "ünï"]),
        "scalar": np.float64(3.25),
        "empty": np.zeros((0, 4)),
        "fortran": np.asfortranarray(rng.normal(size=(4, 5))),
    }
    path = write_npz(tmp_path / "a.npz", **arrays)
    with np.load(path) as got:
        assert sorted(got.files) == sorted(arrays)
        for name, want in arrays.items():
            assert got[name].dtype == np.asarray(want).dtype, name
            assert got[name].shape == np.shape(want), name
            assert got[name].tobytes() == np.ascontiguousarray(want).tobytes(), name
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]  # atomically: no temp file left


def test_the_file_is_deflated(tmp_path):
    big = np.repeat(np.arange(1000.0), 100)  # 800 kB, very compressible
    path = write_npz(tmp_path / "b.npz", big=big)
    with zipfile.ZipFile(path) as z:
        (info,) = z.infolist()
        assert info.compress_type == zipfile.ZIP_DEFLATED
        assert info.file_size > big.nbytes and info.compress_size < big.nbytes / 10
