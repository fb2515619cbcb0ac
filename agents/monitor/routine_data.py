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

Multi-line headers (a title, tag descriptions, engineering units): without ``skip_rows`` the
header is the first line holding every requested column (the first line if none does, so that
the refusal lists its columns); lines right after it whose requested numeric cells are all text
(a units line such as ``s;degC;%``) are skipped, and counted in :attr:`RoutineData.skipped`.
With ``skip_rows`` the header is the first non-blank line after that many lines. ``labels`` are
columns read as text (a time stamp, a quality or mode column), never refused for their content.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.monitor.errors import DataError

__all__ = ["RoutineData", "load_routine_csv", "MISSING_TOKENS"]

MISSING_TOKENS = frozenset(
    {"", "na", "n/a", "nan", "null", "none", "#n/a", "#na", "-", "?", "missing", "#value!"}
)
"""Cell contents (case-insensitive, stripped) read as a missing value."""

_MAX_UNITS_LINES = 5


@dataclass(frozen=True)
class RoutineData:
    """Requested columns of a routine-data file, as float arrays of equal length."""

    columns: dict[str, NDArray[np.float64]]
    path: str
    header: tuple[str, ...]
    labels: dict[str, tuple[str, ...]] = field(default_factory=dict)
    header_line: int = 1
    skipped: int = 0

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
    labels: Sequence[str] = (),
    skip_rows: int | None = None,
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
    labels : sequence of str
        Columns read as text (stripped), e.g. a time stamp or a quality column.
    skip_rows : int, optional
        Lines before the header (default: found, module docstring).

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
    text_cols = [c for c in labels if c not in columns]
    if not columns:
        raise DataError("no columns requested")
    if skip_rows is not None and skip_rows < 0:
        raise DataError(f"skip_rows must be >= 0, got {skip_rows}")
    dup = {c for c in columns if columns.count(c) > 1}
    if dup:
        raise DataError(f"columns requested twice: {sorted(dup)}", column=sorted(dup)[0])
    try:
        fh = path.open(newline="", encoding=encoding)
    except OSError as exc:
        raise DataError(f"cannot read {str(path)!r}: {exc.strerror or exc}") from None
    try:
        with fh:
            lines = list(csv.reader(fh, delimiter=sep))
            header, at = _find_header(lines, [*columns, *text_cols], skip_rows)
            if header is None:
                raise DataError(f"{str(path)!r} is empty (no header line)")
            idx: dict[str, int] = {}
            for c in [*columns, *text_cols]:
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
            texts: dict[str, list[str]] = {c: [] for c in text_cols}
            n = 0
            skipped = 0
            num_idx = [idx[c] for c in columns]
            for k in range(at + 1, len(lines)):
                row = lines[k]
                if not any(cell.strip() for cell in row):
                    continue
                if n == 0 and skipped < _MAX_UNITS_LINES and _is_units_line(row, num_idx):
                    skipped += 1
                    continue
                n += 1
                line = k + 1
                for c in text_cols:
                    i = idx[c]
                    texts[c].append(row[i].strip().strip('"').strip() if i < len(row) else "")
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
    return RoutineData(
        columns=out,
        path=str(path),
        header=tuple(header),
        labels={c: tuple(v) for c, v in texts.items()},
        header_line=at + 1,
        skipped=skipped,
    )


def _find_header(
    lines: list[list[str]], wanted: list[str], skip_rows: int | None
) -> tuple[list[str] | None, int]:
    """The header's cells and its 0-based line index (module docstring)."""
    first: tuple[list[str], int] | None = None
    for k, row in enumerate(lines):
        if skip_rows is not None and k < skip_rows:
            continue
        if not any(cell.strip() for cell in row):
            continue
        cells = [cell.strip() for cell in row]
        if skip_rows is not None:
            return cells, k
        if first is None:
            first = (cells, k)
        if all(w in cells for w in wanted):
            return cells, k
    return first if first is not None else (None, -1)


def _is_units_line(row: list[str], cols: list[int]) -> bool:
    """Whether every requested numeric cell of ``row`` is non-empty text (a units line)."""
    for i in cols:
        if i >= len(row):
            return False
        cell = row[i].strip().strip('"').strip()
        if not cell or cell.lower() in MISSING_TOKENS:
            return False
        for text in {cell, cell.replace(",", ".")}:
            try:
                float(text)
            except ValueError:
                continue
            return False  # a number (perhaps with the other decimal mark): data, not units
    return True
