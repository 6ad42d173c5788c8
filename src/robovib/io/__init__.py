"""File formats: hammer recordings (CSV, UFF 58) and FRF collections (HDF5, UFF 58).

Every CSV (recordings, manifests, pose tables, path modes...) is read by :func:`read_table`:
spreadsheet and DAQ exports (BOM, ``;`` with decimal commas, tabs, quotes, ``Force [kN]``
headers) are sniffed and the choice reported; errors name the file line.

Units and sensor sensitivities are converted to SI here, at the edge.

Names are imported on first use (PEP 562): ``robovib.files.provenance``, which every CLI
command's JSON uses, must not pull in SciPy's signal processing through the FRF readers.
"""

from importlib import import_module

#: Public name -> (submodule, name in it).
_WHERE = {
    "CsvTable": ("..files.csv_table", "CsvTable"),
    "FRF_CSV_UNITS": (".frf_csv", "FRF_CSV_UNITS"),
    "HammerRecording": (".recording", "HammerRecording"),
    "InputFileError": ("..files.safe_read", "InputFileError"),
    "MeasuredCuts": (".cuts", "MeasuredCuts"),
    "OutputPathError": ("..files.safe_write", "OutputPathError"),
    "ReadReport": (".recording", "ReadReport"),
    "Record58": (".uff58", "Record58"),
    "Sensitivity": (".recording", "Sensitivity"),
    "apply_sensitivity": ("..files.units", "apply_sensitivity"),
    "atomic_output": ("..files.safe_write", "atomic_output"),
    "check_input_file": ("..files.safe_read", "check_input_file"),
    "check_output_path": ("..files.safe_write", "check_output_path"),
    "from_si": ("..files.units", "from_si"),
    "json_dumps": ("..files.json_safe", "dumps"),
    "json_safe": ("..files.json_safe", "json_safe"),
    "read_compliance_tests_csv": (".tables", "read_compliance_tests_csv"),
    "read_cuts_csv": (".cuts", "read_cuts_csv"),
    "read_force_csv": (".tables", "read_force_csv"),
    "read_frf_csv": (".frf_csv", "read_frf_csv"),
    "read_frfs": (".frf_files", "read_frfs"),
    "read_frfs_csv": (".frf_csv", "read_frf_csv"),  # former name of read_frf_csv
    "read_frfs_hdf5": (".frf_files", "read_frfs_hdf5"),
    "read_frfs_uff": (".frf_files", "read_frfs_uff"),
    "read_milling_record_csv": (".tables", "read_milling_record_csv"),
    "read_path_modes_csv": (".tables", "read_path_modes_csv"),
    "read_pose_array": (".poses", "read_pose_array"),
    "read_pose_table": (".poses", "read_pose_table"),
    "normalise_column_name": ("..files.csv_table", "normalise_column_name"),
    "read_recording": (".recording", "read_recording"),
    "read_recording_channels": (".recording", "read_recording_channels"),
    "read_recording_csv": (".recording", "read_recording_csv"),
    "read_recording_uff": (".recording", "read_recording_uff"),
    "read_table": ("..files.csv_table", "read_table"),
    "sample_rate_from_time": (".recording", "sample_rate_from_time"),
    "save_figure": ("..files.safe_write", "save_figure"),
    "select_channel": (".recording", "select_channel"),
    "si_factor": ("..files.units", "si_factor"),
    "to_si": ("..files.units", "to_si"),
    "write_frf_csv": (".frf_csv", "write_frf_csv"),
    "write_frfs": (".frf_files", "write_frfs"),
    "write_frfs_hdf5": (".frf_files", "write_frfs_hdf5"),
    "write_frfs_uff": (".frf_files", "write_frfs_uff"),
    "write_path_modes_csv": (".tables", "write_path_modes_csv"),
    "write_recording": (".recording", "write_recording"),
    "write_recording_csv": (".recording", "write_recording_csv"),
    "write_recording_uff": (".recording", "write_recording_uff"),
    "write_uff58": (".uff58", "write_uff58"),
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        module, attr = _WHERE[name]
        value = getattr(import_module(module, __name__), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
