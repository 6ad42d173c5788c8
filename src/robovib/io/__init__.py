"""File formats: hammer recordings (CSV, UFF 58) and FRF collections (HDF5, UFF 58).

Units and sensor sensitivities are converted to SI here, at the edge.
"""

from .frf_files import (
    read_frfs,
    read_frfs_hdf5,
    read_frfs_uff,
    write_frfs,
    write_frfs_hdf5,
    write_frfs_uff,
)
from .recording import (
    HammerRecording,
    Sensitivity,
    read_recording,
    read_recording_csv,
    read_recording_uff,
    write_recording_uff,
)
from .tables import (
    read_compliance_tests_csv,
    read_force_csv,
    read_milling_record_csv,
    read_path_modes_csv,
    write_path_modes_csv,
    write_recording,
    write_recording_csv,
)
from .units import apply_sensitivity, si_factor

__all__ = [
    "HammerRecording",
    "Sensitivity",
    "apply_sensitivity",
    "read_compliance_tests_csv",
    "read_force_csv",
    "read_frfs",
    "read_frfs_hdf5",
    "read_frfs_uff",
    "read_milling_record_csv",
    "read_path_modes_csv",
    "read_recording",
    "read_recording_csv",
    "read_recording_uff",
    "si_factor",
    "write_frfs",
    "write_frfs_hdf5",
    "write_frfs_uff",
    "write_path_modes_csv",
    "write_recording",
    "write_recording_csv",
    "write_recording_uff",
]
