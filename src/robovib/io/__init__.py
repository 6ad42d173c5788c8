"""File formats: hammer recordings (CSV, UFF 58) and FRF collections (HDF5, UFF 58).

Units and sensor sensitivities are converted to SI here, at the edge.
"""

from .cuts import MeasuredCuts, read_cuts_csv
from .frf_csv import FRF_CSV_UNITS, read_frf_csv, write_frf_csv
from .frf_files import (
    read_frfs,
    read_frfs_csv,
    read_frfs_hdf5,
    read_frfs_uff,
    write_frfs,
    write_frfs_hdf5,
    write_frfs_uff,
)
from .json_safe import dumps as json_dumps
from .json_safe import json_safe
from .poses import read_pose_table
from .recording import (
    HammerRecording,
    ReadReport,
    Sensitivity,
    read_recording,
    read_recording_channels,
    read_recording_csv,
    read_recording_uff,
    sample_rate_from_time,
    select_channel,
    write_recording_uff,
)
from .safe_write import OutputPathError, atomic_output, check_output_path, save_figure
from .tables import (
    read_compliance_tests_csv,
    read_force_csv,
    read_milling_record_csv,
    read_path_modes_csv,
    write_path_modes_csv,
    write_recording,
    write_recording_csv,
)
from .uff58 import Record58, write_uff58
from .units import apply_sensitivity, si_factor

__all__ = [
    "FRF_CSV_UNITS",
    "HammerRecording",
    "MeasuredCuts",
    "OutputPathError",
    "ReadReport",
    "Record58",
    "Sensitivity",
    "apply_sensitivity",
    "atomic_output",
    "check_output_path",
    "json_dumps",
    "json_safe",
    "read_compliance_tests_csv",
    "read_cuts_csv",
    "read_force_csv",
    "read_frf_csv",
    "read_frfs",
    "read_frfs_csv",
    "read_frfs_hdf5",
    "read_frfs_uff",
    "read_milling_record_csv",
    "read_path_modes_csv",
    "read_pose_table",
    "read_recording",
    "read_recording_channels",
    "read_recording_csv",
    "read_recording_uff",
    "sample_rate_from_time",
    "save_figure",
    "select_channel",
    "si_factor",
    "write_frf_csv",
    "write_frfs",
    "write_frfs_hdf5",
    "write_frfs_uff",
    "write_path_modes_csv",
    "write_recording",
    "write_recording_csv",
    "write_recording_uff",
    "write_uff58",
]
