"""The ground floor: files robovib can trust and files that describe themselves.

Plumbing that every package above uses, apart from the file *formats* (recordings, FRFs) in
:mod:`robovib.io`:

- :mod:`~robovib.files.safe_read` — an input must be a regular file within a size limit;
  the inputs a command read are tracked so that no output overwrites one.
- :mod:`~robovib.files.safe_write` — atomic outputs (temporary file, then rename), figures.
- :mod:`~robovib.files.h5format` / :mod:`~robovib.files.h5safe` — self-describing HDF5
  headers (units, settings, robovib version) and reading that touches only the named file
  (checksums, no external links, external storage or virtual datasets).
- :mod:`~robovib.files.provenance`, :mod:`~robovib.files.json_safe`,
  :mod:`~robovib.files.json_units` — provenance and JSON with units.
- :mod:`~robovib.files.units` — unit conversion at the edges (SI inside).
- :mod:`~robovib.files.csv_table` — one sniffing CSV reader for every table.

Nothing here imports another robovib package (only ``robovib.__version__``).
"""
