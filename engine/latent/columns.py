"""Per-row metadata of a latent bank held as columns (numpy only: the app's map preview reads it)."""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, overload

import numpy as np

KEYS = "meta_keys"  # the file's array of column names; each column is meta/<key>/values and meta/<key>/index


class MetaColumns(Sequence[dict[str, Any]]):
    """N rows of metadata as columns: per key its distinct values and an (N,) int32 index into them (-1
    where the row lacks the key); ``columns[i]`` is row i as a new dict, so a million rows cost 4 bytes
    per key each, not a dict each."""

    def __init__(self, n: int, columns: Mapping[str, tuple[Sequence[Any], np.ndarray]]) -> None:
        self._n = int(n)
        self._columns: dict[str, tuple[list[Any], np.ndarray]] = {}
        for key in sorted(columns):
            values, index = columns[key]
            index = np.asarray(index)
            if index.shape != (self._n,) or index.dtype.kind not in "iu":
                raise ValueError(f"meta column {key!r} must index {self._n} rows, got {index.shape}")
            if self._n and (index.min() < -1 or index.max() >= len(values)):
                raise ValueError(f"meta column {key!r} indexes past its {len(values)} values")
            self._columns[str(key)] = (list(values), index.astype(np.int32))

    @classmethod
    def from_table(
        cls,
        table: Sequence[Mapping[str, Any]],
        owners: np.ndarray,
        extra: Mapping[str, np.ndarray] | None = None,
    ) -> MetaColumns:
        """Rows ``table[owners[i]]`` (e.g. one dict per clip and each window's clip), with row i of each
        ``extra`` (N,) column set on top; values as JSON keeps them (a tuple reads back as a list)."""
        owners = np.asarray(owners, dtype=np.int64)
        columns: dict[str, tuple[list[Any], np.ndarray]] = {}
        for key in sorted({str(k) for entry in table for k in entry}):
            texts = [json.dumps(entry[key], sort_keys=True) if key in entry else None for entry in table]
            distinct = sorted({t for t in texts if t is not None})
            place = {t: i for i, t in enumerate(distinct)}
            per_entry = np.array([-1 if t is None else place[t] for t in texts], dtype=np.int32)
            columns[key] = ([json.loads(t) for t in distinct], per_entry[owners])
        for key, column in (extra or {}).items():
            distinct, index = np.unique(np.asarray(column), return_inverse=True)
            values = [json.loads(json.dumps(v.item())) for v in distinct]
            columns[str(key)] = (values, index.astype(np.int32).reshape(len(owners)))
        return cls(len(owners), columns)

    @classmethod
    def from_dicts(cls, rows: Sequence[Mapping[str, Any]]) -> MetaColumns:
        """Columns of one dict per row."""
        return rows if isinstance(rows, MetaColumns) else cls.from_table(rows, np.arange(len(rows)))

    def __len__(self) -> int:
        """Number of rows."""
        return self._n

    @overload
    def __getitem__(self, i: int) -> dict[str, Any]: ...
    @overload
    def __getitem__(self, i: slice) -> list[dict[str, Any]]: ...
    def __getitem__(self, i: int | slice) -> dict[str, Any] | list[dict[str, Any]]:
        """Row ``i`` as a dict of the keys it has (a list of them for a slice)."""
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(self._n))]
        k = int(i) + self._n if int(i) < 0 else int(i)
        if not 0 <= k < self._n:
            raise IndexError(f"meta row {i} of {self._n}")
        return {key: values[index[k]] for key, (values, index) in self._columns.items() if index[k] >= 0}

    def __iter__(self) -> Iterator[dict[str, Any]]:
        """The rows as dicts, in order."""
        columns = [(key, values, index.tolist()) for key, (values, index) in self._columns.items()]
        for k in range(self._n):
            yield {key: values[index[k]] for key, values, index in columns if index[k] >= 0}

    def __eq__(self, other: object) -> bool:
        """Row-by-row equality with any sequence of dicts."""
        if not isinstance(other, Sequence) or len(other) != self._n:
            return False
        return all(a == b for a, b in zip(self, other, strict=True))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        """Row count and keys."""
        return f"MetaColumns({self._n} rows, keys {list(self._columns)})"

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The columns as plain arrays for a bank file: the key list, each key's values as JSON strings and
        its (N,) int32 index."""
        arrays = {KEYS: np.asarray(list(self._columns), dtype=np.str_)}
        for key, (values, index) in self._columns.items():
            texts = [json.dumps(v, sort_keys=True) for v in values]
            arrays[f"meta/{key}/values"] = np.asarray(texts, dtype=np.str_)
            arrays[f"meta/{key}/index"] = index
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], n: int) -> MetaColumns:
        """Columns of N rows read back from :meth:`to_arrays`; KeyError, ValueError or JSONDecodeError when
        they are damaged."""
        columns = {}
        for key in arrays[KEYS].tolist():
            values = [json.loads(str(v)) for v in arrays[f"meta/{key}/values"]]
            columns[str(key)] = (values, arrays[f"meta/{key}/index"])
        return cls(n, columns)
