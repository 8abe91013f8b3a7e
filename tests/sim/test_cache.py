"""The per-maze caches' file format: what is written is read back, and a torn file is refused."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.cache import load_arrays, save_arrays


@pytest.mark.parametrize("compressed", [False, True])
def test_arrays_come_back_as_written_and_writable(tmp_path, compressed):
    path = tmp_path / "t.arrays"
    written = {
        "labels": np.arange(12, dtype=np.uint8).reshape(3, 4),
        "depth": np.linspace(0, 1, 7, dtype=np.float32),
        "empty": np.zeros((0, 3), np.int64),
        "flags": np.array([True, False]),
        "hash": np.array("0123456789abcdef"),
        "scalar": np.array(3.5),
    }
    save_arrays(path, compressed, **written)
    read = load_arrays(path)
    assert list(read) == list(written)
    for name, a in written.items():
        assert read[name].dtype == a.dtype and read[name].shape == a.shape
        np.testing.assert_array_equal(read[name], a)
    assert str(read["hash"]) == "0123456789abcdef"
    read["labels"][0, 0] = 9  # a cached table can be used as the one built would be


@pytest.mark.parametrize("compressed", [False, True])
def test_a_torn_or_foreign_file_is_refused_so_the_caller_builds_it_again(tmp_path, compressed):
    path = tmp_path / "t.arrays"
    save_arrays(path, compressed, a=np.arange(1000, dtype=np.int64))
    whole = path.read_bytes()
    for cut in (4, 20, len(whole) // 2, len(whole) - 1):
        path.write_bytes(whole[:cut])
        with pytest.raises(ValueError):
            load_arrays(path)
    path.write_bytes(b"PK\x03\x04 a zip file, as numpy's .npz was")
    with pytest.raises(ValueError):
        load_arrays(path)
    with pytest.raises(OSError):
        load_arrays(tmp_path / "none.arrays")


def test_python_objects_are_not_cached(tmp_path):
    with pytest.raises(ValueError, match="Python objects"):
        save_arrays(tmp_path / "t.arrays", a=np.array([{"x": 1}], dtype=object))
