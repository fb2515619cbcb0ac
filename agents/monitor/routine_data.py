"""Routine operating data from CSV files as process historians export them (seed 004).

Seed 004's method needs only "routine operating data from an existing simple feedback control
loop and knowledge of the process delays"; on a real plant those come from a historian export,
e.g.::

    time;SP;PV;OP;T2
    2024-03-01 00:00:00;50,0;49,87;31,2;120,4
    ...

:func:`load_routine_csv` reads the requested columns as floats and refuses, with a message naming
the column and the row (1-based data row; the file line is given too), data the analysis cannot
use: a missing column, a missing value (empty cell, ``NA``, ``NaN``, ``#N/A``, ``null``, a short
row), a non-numeric or infinite cell, a constant column (unless listed in ``constant_ok``, e.g. a
set point that never moved), and fewer rows than the model needs. Columns not requested (e.g. a
text time stamp) are not parsed. Blank lines are skipped.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.monitor.errors import DataError

__all__ = ["RoutineData", "load_routine_csv", "MISSING_TOKENS"]

MISSING_TOKENS = frozenset(
    {"", "na", "n/a", "nan", "null", "none", "#n/a", "#na", "-", "?", "missing", "#value!"}
)
"""Cell contents (case-insensitive, stripped) read as a missing value."""


@dataclass(frozen=True)
class RoutineData:
    """Requested columns of a routine-data file, as float arrays of equal length."""

    columns: dict[str, NDArray[np.float64]]
    path: str
    header: tuple[str, ...]

    @property
    def n_rows(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        return self.columns[name]

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def keys(self) -> Iterable[str]:
        return self.columns.keys()


def load_routine_csv(
    path: str | Path,
    columns: Sequence[str],
    sep: str = ";",
    *,
    decimal: str = ".",
    min_rows: int = 0,
    constant_ok: Iterable[str] = (),
    encoding: str = "utf-8-sig",
) -> RoutineData:
    """Read the ``columns`` of a routine-data CSV file.

    Parameters
    ----------
    path : str or Path
        The file; the first non-blank line is the header.
    columns : sequence of str
        Column names to read (e.g. ``["SP", "PV", "T2"]``), matched after stripping blanks.
    sep : str
        Field separator, e.g. ``";"`` (European historian exports) or ``","``.
    decimal : str
        Decimal mark, ``"."`` or ``","`` (with ``sep=";"``).
    min_rows : int
        Fewest data rows accepted (the model's need, see :func:`agents.monitor.assess.rows_needed`).
    constant_ok : iterable of str
        Requested columns allowed to be constant (typically the set point).
    encoding : str
        File encoding (the default also strips a UTF-8 byte-order mark).

    Raises
    ------
    DataError
        Naming the column (:attr:`DataError.column`) and 1-based data row (:attr:`DataError.row`).
    """
    path = Path(path)
    if len(sep) != 1:
        raise DataError(f"separator must be one character, got {sep!r}")
    if decimal not in (".", ","):
        raise DataError(f"decimal mark must be '.' or ',', got {decimal!r}")
    if decimal == sep:
        raise DataError(f"decimal mark and separator are both {sep!r}")
    columns = list(columns)
    if not columns:
        raise DataError("no columns requested")
    dup = {c for c in columns if columns.count(c) > 1}
    if dup:
        raise DataError(f"columns requested twice: {sorted(dup)}", column=sorted(dup)[0])
    try:
        fh = path.open(newline="", encoding=encoding)
    except OSError as exc:
        raise DataError(f"cannot read {str(path)!r}: {exc.strerror or exc}") from None
    try:
        with fh:
            reader = csv.reader(fh, delimiter=sep)
            header: list[str] | None = None
            for row in reader:
                if any(cell.strip() for cell in row):
                    header = [cell.strip() for cell in row]
                    break
            if header is None:
                raise DataError(f"{str(path)!r} is empty (no header line)")
            idx: dict[str, int] = {}
            for c in columns:
                hits = [i for i, h in enumerate(header) if h == c]
                if not hits:
                    hint = ""
                    if len(header) == 1 and any(s in header[0] for s in ";,\t|"):
                        hint = (
                            f" (the header is one field {header[0]!r}: is the separator {sep!r}?)"
                        )
                    raise DataError(
                        f"column {c!r} not found in {str(path)!r}; columns are {header}{hint}",
                        column=c,
                    )
                if len(hits) > 1:
                    raise DataError(
                        f"column {c!r} appears {len(hits)} times in the header", column=c
                    )
                idx[c] = hits[0]
            values: dict[str, list[float]] = {c: [] for c in columns}
            n = 0
            for row in reader:
                if not any(cell.strip() for cell in row):
                    continue
                n += 1
                line = reader.line_num
                for c in columns:
                    i = idx[c]
                    where = f"column {c!r}, row {n} (line {line})"
                    if i >= len(row):
                        raise DataError(
                            f"{where}: missing value (the row has {len(row)} of "
                            f"{len(header)} fields)",
                            column=c,
                            row=n,
                        )
                    cell = row[i].strip().strip('"').strip()
                    if cell.lower() in MISSING_TOKENS:
                        raise DataError(f"{where}: missing value ({row[i]!r})", column=c, row=n)
                    text = cell.replace(decimal, ".") if decimal == "," else cell
                    try:
                        v = float(text)
                    except ValueError:
                        raise DataError(
                            f"{where}: non-numeric value {row[i]!r}"
                            + (" (decimal comma? pass decimal=',')" if "," in cell else ""),
                            column=c,
                            row=n,
                        ) from None
                    if not math.isfinite(v):
                        raise DataError(f"{where}: non-finite value {row[i]!r}", column=c, row=n)
                    values[c].append(v)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"{str(path)!r} is not a readable {encoding} CSV file: {exc}") from None
    if n < max(min_rows, 1):
        raise DataError(
            f"{str(path)!r} has {n} data rows; the model needs at least {max(min_rows, 1)}",
            row=n,
        )
    ok = set(constant_ok)
    out: dict[str, NDArray[np.float64]] = {}
    for c in columns:
        arr = np.asarray(values[c], dtype=float)
        if c not in ok and np.ptp(arr) == 0.0:
            raise DataError(
                f"column {c!r} is constant ({arr[0]:g} in all {n} rows, rows 1-{n}): no "
                "variability to analyse",
                column=c,
                row=1,
            )
        out[c] = arr
    return RoutineData(columns=out, path=str(path), header=tuple(header))
