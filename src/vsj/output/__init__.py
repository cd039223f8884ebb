"""Results on disk, in two parts:

- `vsj.output.files`: how every file is written (`atomic_write`), the checks of an
  output path before any work (`check_output_file`, `OutputError`), result sets
  written as one with their manifest (`ResultSet`, `verify`), run metadata JSON;
- `vsj.output.trajectory`: the samples of runs as netCDF and CSV, written at once
  or streamed block by block (`TrajectoryFile`).
"""

from .files import (MANIFEST, OUTPUTS, PROBE, SMALL_OUTPUT_BYTES, OutputError, ResultSet,
                    _jsonable, atomic_write, check_output_file, clear_staging, file_record,
                    read_manifest, recorded_file_problems, regular_file, verify,
                    write_errors, write_meta, written_by_vsj)
from .trajectory import (PLOT_BYTES, TrajectoryFile, cases_dataset, column_name,
                         parameters_record, read_trajectory, signals_bound, trajectory_bytes,
                         trajectory_table, write_cases, write_dataset, write_trajectory,
                         write_trajectory_csv)

__all__ = ["MANIFEST", "OUTPUTS", "PROBE", "SMALL_OUTPUT_BYTES", "OutputError", "ResultSet",
           "atomic_write", "check_output_file", "clear_staging", "file_record",
           "read_manifest", "recorded_file_problems", "regular_file", "verify", "write_errors",
           "write_meta", "written_by_vsj",
           "PLOT_BYTES", "TrajectoryFile", "cases_dataset", "column_name",
           "parameters_record", "read_trajectory", "signals_bound", "trajectory_bytes",
           "trajectory_table", "write_cases", "write_dataset", "write_trajectory",
           "write_trajectory_csv"]
