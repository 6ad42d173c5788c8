"""Values scheduled along a path, looked up for a planned run or live, step by step.

:class:`ScheduledTable` holds values designed at path distances; ``table.at(coords)`` gives the
rows of every command instant of a planned run, or, given a :class:`PathCursor`, a
:class:`LiveRows` that reads the row at the cursor's current distance (a run-time controller,
:class:`~robovib.control.runtime.RuntimeController`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LiveMap", "LiveRows", "PathCursor", "ScheduledTable", "map_rows", "n_commands"]


@dataclass(frozen=True)
class ScheduledTable:
    """Values designed at path distances ``s_m`` (n,), rows ``values`` (n, m); linear lookup.

    A single row (n = 1) is a constant. Outside ``s_m`` the end values are held.

    Attributes
    ----------
    s_m
        (n,) path distances [m].
    values
        (n, m) rows designed there.
    """

    s_m: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        s = np.atleast_1d(np.asarray(self.s_m, float))
        v = np.asarray(self.values, float)
        v = v.reshape(s.size, -1)
        if s.ndim != 1 or not np.all(np.isfinite(s)) or not np.all(np.isfinite(v)):
            raise ValueError("scheduled table needs finite 1-D s_m [m] and finite values")
        if s.size > 1 and np.any(np.diff(s) <= 0):
            raise ValueError("scheduled table s_m [m] must be strictly increasing")
        object.__setattr__(self, "s_m", s)
        object.__setattr__(self, "values", v)

    @classmethod
    def constant(cls, values) -> ScheduledTable:
        return cls(np.array([0.0]), np.atleast_2d(np.asarray(values, float)))

    def at(self, coords) -> np.ndarray:
        """Rows at the path distances ``coords`` (n,) [m] (first column of (n, 3) poses).

        Parameters
        ----------
        coords : array_like
            (n,) path distances [m] or (n, 3) poses (first column used).

        Returns
        -------
        numpy.ndarray
            (n, m) interpolated rows.
        """
        if isinstance(coords, PathCursor):
            return LiveRows(self, coords)
        c = np.asarray(coords, float)
        s = c if c.ndim == 1 else c[:, 0]
        if self.s_m.size == 1:
            return np.repeat(self.values, s.size, axis=0)
        return np.column_stack(
            [np.interp(s, self.s_m, self.values[:, j]) for j in range(self.values.shape[1])]
        )


class PathCursor:
    """The path distance of the current command instant, for a controller run one step at a time.

    A planned run gives ``reset`` the coordinates of every command instant; a run-time
    controller (:class:`~robovib.control.runtime.RuntimeController`) learns the path distance
    at each step. ``reset(cursor, ...)`` makes every :class:`ScheduledTable` lookup a
    :class:`LiveRows` that reads the row at the cursor's current distance.

    Parameters
    ----------
    capacity
        Most command instants of a run (buffers are sized for it at ``reset``).
    nominal_s_m
        The path distance used where a controller needs one value for the run [m].
    """

    def __init__(self, capacity: int, nominal_s_m: float):
        if int(capacity) < 1 or not math.isfinite(nominal_s_m):
            raise ValueError("a path cursor needs capacity >= 1 and a finite nominal_s_m [m]")
        self.capacity = int(capacity)
        self.nominal_s_m = float(nominal_s_m)
        self.s_m = float(nominal_s_m)
        self.version = 0

    def __len__(self) -> int:
        return self.capacity

    def move_to(self, s_m: float) -> None:
        """Set the path distance of the next command instant.

        Parameters
        ----------
        s_m : float
            Path distance [m].
        """
        self.s_m = float(s_m)
        self.version += 1


class LiveRows:
    """A :class:`ScheduledTable`'s row at a :class:`PathCursor`'s distance (``rows[k]`` of a run).

    ``rows[k]`` (any ``k``) is the linearly interpolated row at the cursor's distance (end
    values held), computed once per cursor move into a buffer; ``rows[k, j]`` one value;
    ``rows[:, j]`` a column view. ``shape`` is (capacity, columns).

    Parameters
    ----------
    table
        The table.
    cursor
        The cursor.
    cols
        Column selection (default all).
    """

    def __init__(self, table: ScheduledTable, cursor: PathCursor, cols=None):
        self.table = table
        self.cursor = cursor
        self._scalar = cols is not None and np.ndim(cols) == 0  # rows[:, j]: rows[k] a number
        self._cols = np.arange(table.values.shape[1]) if cols is None else np.atleast_1d(cols)
        self._values = np.ascontiguousarray(table.values[:, self._cols])
        self._s = table.s_m.tolist()
        self._buf = np.empty(self._values.shape[1])
        self._tmp = np.empty_like(self._buf)
        self._version = -1

    @property
    def shape(self) -> tuple[int, int]:
        return (self.cursor.capacity, self._values.shape[1])

    def row(self) -> np.ndarray:
        """The row at the cursor's distance.

        Returns
        -------
        numpy.ndarray
            (m,) row (a buffer overwritten on the next move).
        """
        if self._version != self.cursor.version:
            self._version = self.cursor.version
            v, s, x = self._values, self._s, self.cursor.s_m
            if len(s) == 1 or x <= s[0]:
                self._buf[:] = v[0]
            elif x >= s[-1]:
                self._buf[:] = v[-1]
            else:
                i = bisect.bisect_right(s, x) - 1
                t = (x - s[i]) / (s[i + 1] - s[i])
                np.multiply(v[i], 1.0 - t, out=self._buf)
                np.multiply(v[i + 1], t, out=self._tmp)
                self._buf += self._tmp
        return self._buf

    def __getitem__(self, key):
        if isinstance(key, tuple):
            k, j = key
            if isinstance(k, slice):
                return LiveRows(self.table, self.cursor, self._cols[j])
            return self.row()[j]
        return self.row()[0] if self._scalar else self.row()


class LiveMap:
    """``fn`` of a :class:`LiveRows`' row, recomputed once per cursor move (``[k]`` as a run's).

    Parameters
    ----------
    rows
        The live rows.
    fn
        Row (m,) -> derived array.
    """

    def __init__(self, rows, fn):
        self.rows = rows
        self.fn = fn
        self._version = -1
        self._value = None

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.rows.cursor.capacity, *np.shape(self[0]))

    def __getitem__(self, k):
        cursor = self.rows.cursor
        if self._version != cursor.version:
            self._version = cursor.version
            self._value = self.fn(self.rows.row())
        return self._value


def map_rows(rows, fn):
    """``fn`` of every row: ``fn(rows)`` for an array (n, m), a :class:`LiveMap` for live rows.

    ``fn`` takes (n, m) rows and returns (n, ...) values row by row (vectorised).

    Parameters
    ----------
    rows : numpy.ndarray or LiveRows or LiveMap
        The rows.
    fn : callable
        (n, m) -> (n, ...).

    Returns
    -------
    numpy.ndarray or LiveMap
        The derived rows.
    """
    if isinstance(rows, LiveRows):
        return LiveMap(rows, lambda r: fn(r[None, :])[0])
    if isinstance(rows, LiveMap):
        return LiveMap(rows.rows, lambda r, f0=rows.fn: fn(f0(r)[None, ...])[0])
    return fn(rows)


def n_commands(coords) -> int:
    """Command instants of a run: ``len(coords)``, or a :class:`PathCursor`'s capacity.

    Parameters
    ----------
    coords : array_like or PathCursor
        The run's coordinates.

    Returns
    -------
    int
        The number of command instants.
    """
    if isinstance(coords, PathCursor):
        return coords.capacity
    c = np.asarray(coords)
    return int(c.shape[0]) if c.ndim else 1
