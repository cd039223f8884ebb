"""The slab writer of netCDF classic files (`vsj.netcdf.ClassicFile`): a block written at
an index lands there, as SciPy's reader sees it, and an index or a block that does not
fit the variable is refused."""

import numpy as np
import pytest
from scipy.io import netcdf_file

from vsj.netcdf import ClassicFile, Variable


def test_a_block_lands_at_its_index_and_a_wrong_one_is_refused(tmp_path):
    path = tmp_path / "slabs.nc"
    with open(path, "w+b") as handle:
        file = ClassicFile(handle, {"case": 3, "time": 7}, {},
                           [Variable("theta", ("case", "time"), "d", {}),
                            Variable("success", ("case",), "i", {})])
        file.write("theta", np.full((3, 7), np.nan))
        file.write("theta", [1.5, 2.5, 3.5], (1, 4))
        file.write("theta", [-1.0], (2,))  # the first sample of case 2
        file.write("success", np.array([1, 0, 1], dtype=np.int32))
        with pytest.raises(ValueError, match="more entries than the variable has"):
            file.write("success", [1], (0, 0))
        with pytest.raises(ValueError, match="overruns"):
            file.write("theta", np.zeros(4), (2, 4))
    with netcdf_file(path, "r", mmap=False) as read:
        theta = read.variables["theta"].data.copy()
        success = read.variables["success"].data.copy()
    expected = np.full((3, 7), np.nan)
    expected[1, 4:] = [1.5, 2.5, 3.5]
    expected[2, 0] = -1.0
    assert np.array_equal(theta, expected, equal_nan=True)
    assert success.tolist() == [1, 0, 1]
