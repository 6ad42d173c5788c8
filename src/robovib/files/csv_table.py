"""The one CSV table reader: files as labs and spreadsheets write them, errors naming the line.

Every CSV that robovib reads (recordings, manifests, pose tables, path modes, forces...) goes
through :func:`read_table`. It accepts what Excel and DAQ software write and says what it chose:

* **encoding**: UTF-8 with or without a byte-order mark (Excel's "CSV UTF-8"), UTF-16 with a
  byte-order mark (Excel's "Unicode text"), else Windows-1252;
* **delimiter**: sniffed among ``,`` ``;`` tab and ``|`` — the one that splits the header into
  two or more cells and every sampled data line into as many (else the one splitting the header
  most, so that the odd line is named; a single-column table is comma-separated);
* **decimal mark**: a comma when the delimiter is not a comma and numbers are written ``1,5``
  (also ``1.234,5`` with a thousands dot); such cells are returned with a decimal point;
* **quotes**: ``"1,5"`` and ``"12.5"`` are cells like any other (csv-module quoting);
* **header units in brackets**: ``Time [s]``, ``Force (kN)``, ``Acceleration X [m/s²]`` become
  ``time_s``, ``force_kn``, ``acceleration_x_m_per_s2`` (names lower-cased, spaces and ``/`` as in
  robovib's column names);
* trailing empty columns (a delimiter at the end of every line) are dropped; blank lines skipped.

A line with another number of cells, or a cell that is not a number where one is needed, is an
error naming the file line and what was expected.
"""

from __future__ import annotations

import codecs
import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["CsvTable", "normalise_column_name", "read_table"]

_DELIMITERS = (",", ";", "\t", "|")
_DELIM_NAME = {",": "','", ";": "';'", "\t": "tab", "|": "'|'"}
_SAMPLE_LINES = 200
_COMMA_NUMBER = re.compile(r"^[+-]?(\d{1,3}(\.\d{3})+|\d+),\d*([eE][+-]?\d+)?$")
_DOT_NUMBER = re.compile(r"^[+-]?(\d+\.\d*|\.\d+)([eE][+-]?\d+)?$")
_UNIT_IN_BRACKETS = re.compile(r"^(.*?)[\s_]*[\[(]\s*([^\])]*?)\s*[\])]\s*$")


def normalise_column_name(name: str) -> str:
    """A header cell as a robovib column name: ``"Force X [kN]"`` -> ``"force_x_kn"``.

    Parameters
    ----------
    name
        The header cell as written.

    Returns
    -------
    str
        Lower case, spaces and dashes as ``_``, a unit in brackets appended as ``_<unit>`` with
        ``/`` as ``_per_``, squares as ``2`` and ``µ`` as ``u``.
    """
    text = name.strip().lstrip("\ufeff").strip()
    m = _UNIT_IN_BRACKETS.match(text)
    unit = ""
    if m:
        text, unit = m.group(1), m.group(2)
    base = re.sub(r"[\s\-]+", "_", text.strip().lower())
    if not unit:
        return base
    u = unit.strip().lower().replace("µ", "u").replace("μ", "u").replace("²", "2")
    u = u.replace("^2", "2").replace("**2", "2").replace(" ", "")
    u = u.replace("/", "_per_").replace("*", "_")
    return f"{base}_{u}" if base else u


@dataclass(frozen=True)
class CsvTable:
    """A CSV table as read: header, string cells and the file line of every row.

    Attributes
    ----------
    path
        The file.
    header
        Column names (normalised, :func:`normalise_column_name`).
    raw_header
        Header cells as written.
    rows
        Data rows (tuples of stripped strings; decimal commas already turned into points).
    lines
        File line number of each row (the header line is ``header_line``).
    delimiter, decimal, encoding
        What was sniffed.
    header_line
        File line number of the header.
    ends_with_newline
        False when the file's last line has no line end (a file cut short, often).
    """

    path: str
    header: tuple[str, ...]
    raw_header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]
    delimiter: str
    decimal: str
    encoding: str
    header_line: int = 1
    ends_with_newline: bool = True

    @property
    def dialect(self) -> str:
        """How the file was read, in words (reported with the result)."""
        return (
            f"delimiter {_DELIM_NAME.get(self.delimiter, repr(self.delimiter))}, "
            f"decimal {self.decimal!r}, encoding {self.encoding}"
        )

    def index(self, name: str) -> int:
        """Position of column ``name``; ValueError naming the columns the file has.

        Parameters
        ----------
        name : str
            Column name (normalised).

        Returns
        -------
        int
            Its position in the header.
        """
        try:
            return self.header.index(name)
        except ValueError:
            raise ValueError(
                f"{self.path}: no column {name!r} (has {', '.join(self.header)})"
            ) from None

    def column(self, name: str) -> list[str]:
        """The cells of column ``name`` (strings).

        Parameters
        ----------
        name : str
            Column name (normalised).

        Returns
        -------
        list of str
            The cells, one per row.
        """
        i = self.index(name)
        return [r[i] for r in self.rows]

    def numbers(self, name: str, *, allow_empty: bool = False) -> np.ndarray:
        """Column ``name`` as floats; an empty or non-numeric cell is an error naming its line.

        Parameters
        ----------
        name
            Column.
        allow_empty
            Empty cells become NaN instead of an error.

        Returns
        -------
        numpy.ndarray
            (n_rows,) values.
        """
        i = self.index(name)
        out = np.empty(len(self.rows))
        for k, r in enumerate(self.rows):
            cell = r[i]
            if not cell and allow_empty:
                out[k] = np.nan
                continue
            try:
                out[k] = float(cell)
            except ValueError:
                raise ValueError(
                    f"{self.path} line {self.lines[k]}: {name} = {cell!r} is not a number "
                    f"(expected a number with decimal {self.decimal!r}; {self.dialect})"
                ) from None
        return out

    def matrix(self, names) -> np.ndarray:
        """Columns ``names`` as a (n_rows, n_names) float array (errors name the line).

        Parameters
        ----------
        names : sequence of str
            Column names (normalised).

        Returns
        -------
        numpy.ndarray
            (n_rows, n_names) floats.
        """
        idx = [self.index(n) for n in names]
        try:
            return np.array([[r[i] for i in idx] for r in self.rows], dtype=float)
        except ValueError:
            for n in names:
                self.numbers(n)  # raises with the line
            raise

    def to_frame(self):
        """A :class:`pandas.DataFrame`: numeric columns as floats (empty cells NaN), others
        as strings.

        Returns
        -------
        pandas.DataFrame
            One column per header name.
        """
        import pandas as pd

        data = {}
        for j, name in enumerate(self.header):
            cells = [r[j] for r in self.rows]
            try:
                data[name] = np.array([float(c) if c else np.nan for c in cells], float)
            except ValueError:
                data[name] = cells
        return pd.DataFrame(data, columns=list(self.header))


def _decode(raw: bytes) -> tuple[str, str]:
    if raw.startswith(codecs.BOM_UTF8):
        return raw[len(codecs.BOM_UTF8) :].decode("utf-8"), "UTF-8 with byte-order mark"
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return raw.decode("utf-16").lstrip("\ufeff"), "UTF-16"
    try:
        return raw.decode("utf-8"), "UTF-8"
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace"), "Windows-1252"


def _split(lines: list[str], delimiter: str) -> list[list[str]]:
    return list(csv.reader(lines, delimiter=delimiter, skipinitialspace=True))


def _sniff_delimiter(text: str) -> str:
    sample = [ln for ln in text.splitlines()[: _SAMPLE_LINES + 1] if ln.strip()]
    if not sample:
        return ","
    best, best_cols = ",", 1
    widest, widest_cols = ",", 1  # if no delimiter splits every line alike: the header's
    for d in _DELIMITERS:
        try:
            rows = _split(sample, d)
        except csv.Error:
            continue
        n = len(rows[0])
        # Trailing empty cells (a delimiter at each line end) do not count.
        while n > 1 and not rows[0][n - 1].strip():
            n -= 1
        if n < 2:
            continue
        if n > widest_cols:
            widest, widest_cols = d, n
        ok = all(
            len(r) == len(rows[0]) or (len(r) >= n and not any(c.strip() for c in r[n:]))
            for r in rows[1:-1]  # the last sampled line may be cut short
        )
        if ok and n > best_cols:
            best, best_cols = d, n
    # No consistent delimiter: take the one that splits the header, so that the cell-count
    # check names the first odd line.
    return best if best_cols > 1 else widest


def read_table(path: str | Path, *, what: str = "table", comment: str | None = None) -> CsvTable:
    """Read a CSV table written by hand, a spreadsheet or a DAQ (see the module docstring).

    Parameters
    ----------
    path
        The file.
    what
        What the table is, for messages (``"manifest"``, ``"pose table"``...).
    comment
        Lines starting with this text (after blanks) are skipped, e.g. ``"#"``; line numbers
        still count them. None: no comment lines.

    Returns
    -------
    CsvTable
        Header, rows and the sniffed delimiter, decimal mark and encoding.

    Raises
    ------
    ValueError
        No such file, an empty file, no data rows, a duplicated column, a line with another
        number of cells than the header (line and counts named).
    """
    from .safe_read import read_bytes_checked

    path = Path(path)
    raw = read_bytes_checked(path, f"{what} file")  # a regular file below the size limit
    text, encoding = _decode(raw)
    if comment:  # blank them out: the line numbers stay those of the file
        text = "".join(
            ("\n" if ln.endswith(("\n", "\r")) else "") if ln.lstrip().startswith(comment) else ln
            for ln in text.splitlines(keepends=True)
        )
    if not text.strip():
        raise ValueError(f"{path}: empty {what} file")
    ends_nl = text.endswith(("\n", "\r"))
    delimiter = _sniff_delimiter(text)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter, skipinitialspace=True)
    header_cells = None
    rows, lines = [], []
    try:
        for cells in reader:
            if not cells or all(not c.strip() for c in cells):
                continue
            cells = [c.strip() for c in cells]
            if header_cells is None:
                header_cells, header_line = cells, reader.line_num
                continue
            rows.append(cells)
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise ValueError(f"{path} line {reader.line_num}: not readable as CSV ({exc})") from None
    if header_cells is None:
        raise ValueError(f"{path}: empty {what} file")
    width = len(header_cells)
    while width > 1 and not header_cells[width - 1]:
        width -= 1
    header_cells = header_cells[:width]
    dname = _DELIM_NAME[delimiter]
    for k, r in enumerate(rows):
        if len(r) > width and not any(r[width:]):
            r = rows[k] = r[:width]
        if len(r) != width:
            cut = "" if (k < len(rows) - 1 or ends_nl) else " (the file ends there: cut short?)"
            raise ValueError(
                f"{path} line {lines[k]}: {len(r)} cells, expected {width} like the header "
                f"(delimiter {dname}){cut}"
            )
    if not rows:
        raise ValueError(f"{path}: {what} has a header but no data rows")
    header = tuple(normalise_column_name(h) for h in header_cells)
    if any(not h for h in header):
        raise ValueError(f"{path} line {header_line}: empty column name in the header")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise ValueError(f"{path} line {header_line}: duplicate column(s) {', '.join(dup)}")
    decimal = "."
    if delimiter != ",":
        commas = dots = 0
        for r in rows[:_SAMPLE_LINES]:
            for c in r:
                commas += bool(_COMMA_NUMBER.match(c))
                dots += bool(_DOT_NUMBER.match(c))
        if commas and commas >= dots:
            decimal = ","
    if decimal == ",":
        rows = [
            [c.replace(".", "").replace(",", ".") if _COMMA_NUMBER.match(c) else c for c in r]
            for r in rows
        ]
    return CsvTable(
        str(path), header, tuple(header_cells), tuple(tuple(r) for r in rows), tuple(lines),
        delimiter, decimal, encoding, header_line, ends_nl,
    )  # fmt: skip
