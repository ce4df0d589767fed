"""Packing of one appended chunk into a single BLOB, and unpacking of many into arrays.

A chunk's BLOB is the raw little-endian bytes of each column (``ndarray.tobytes``) one after
another in the stream's column order; ``n_rows`` and the dtype strings, kept beside it,
give every column's offset.  Loading preallocates each output array once and copies every
chunk's slice into place, so memory peaks at the output plus one chunk.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
import numpy.typing as npt


def encode_chunk(
    stream: str, dtypes: Mapping[str, np.dtype], columns: Mapping[str, npt.ArrayLike]
) -> tuple[int, str, bytes]:
    """Validate ``columns`` against the stream's ``dtypes`` (name -> storage dtype, in order)
    and return ``(n_rows, dtype string, blob)``.  Raises ValueError/TypeError naming the
    offending stream, column, shape, length or dtype."""
    given, declared = set(columns), set(dtypes)
    if given != declared:
        missing, unknown = sorted(declared - given), sorted(given - declared)
        raise ValueError(
            f"append to stream {stream!r}: columns must be exactly {list(dtypes)}; "
            f"missing {missing}, unknown {unknown}"
        )
    arrays: list[np.ndarray] = []
    n_rows: int | None = None
    for name, dtype in dtypes.items():
        array = np.asarray(columns[name])
        if array.ndim != 1:
            raise ValueError(
                f"append to stream {stream!r}: column {name!r} must be 1-D, got shape "
                f"{array.shape}"
            )
        if n_rows is None:
            n_rows = len(array)
        elif len(array) != n_rows:
            lengths = {k: np.shape(columns[k]) for k in dtypes}
            raise ValueError(
                f"append to stream {stream!r}: columns must have equal lengths, got {lengths}"
            )
        if array.dtype.kind not in "biuf":
            raise TypeError(
                f"append to stream {stream!r}: column {name!r} has dtype {array.dtype}; "
                f"only bool, integer and float data can be stored (declared {dtype})"
            )
        arrays.append(_lossless_cast(array, dtype, f"append to stream {stream!r}: column {name!r}"))
    assert n_rows is not None  # a stream has at least one column
    blob = b"".join(np.ascontiguousarray(a).tobytes() for a in arrays)
    return n_rows, ",".join(dt.str for dt in dtypes.values()), blob


def _lossless_cast(array: np.ndarray, dtype: np.dtype, where: str) -> np.ndarray:
    """``array`` as ``dtype`` if every value survives the cast (so ``[1, 2]`` fits an int32
    column and ``[0.5]`` does not fit an integer one); TypeError naming a lost value if not."""
    if np.can_cast(array.dtype, dtype, "safe"):
        return array.astype(dtype, copy=False)
    with np.errstate(all="ignore"):  # overflow and NaN -> int are caught by the comparison
        cast = array.astype(dtype)
        kept = cast.astype(array.dtype) == array
        if array.dtype.kind == "f":
            kept |= np.isnan(array) & np.isnan(cast.astype(np.float64))
        if dtype.kind in "iu" and array.dtype.kind in "iu":
            kept &= (cast < 0) == (array < 0)  # wraparound between signed and unsigned
    if not kept.all():
        index = int(np.argmin(kept))
        raise TypeError(
            f"{where} has dtype {array.dtype}; value {array[index]!r} at index {index} cannot be "
            f"stored exactly as the declared {dtype}"
        )
    return cast


def decode_chunks(
    dtypes: Mapping[str, np.dtype],
    total_rows: int,
    chunks: Iterable[tuple[int, str, bytes]],
) -> dict[str, np.ndarray]:
    """Concatenate ``chunks`` (``(n_rows, dtype string, blob)`` in order) into one native-
    endian array per column; ``total_rows`` must be their summed ``n_rows``."""
    names: Sequence[str] = list(dtypes)
    out = {name: np.empty(total_rows, dtype=dtypes[name].newbyteorder("=")) for name in names}
    position = 0
    for n_rows, dtype_text, blob in chunks:
        chunk_dtypes = [np.dtype(s) for s in dtype_text.split(",")]
        if len(chunk_dtypes) != len(names):
            raise ValueError(f"corrupt chunk: {len(chunk_dtypes)} dtypes for columns {names}")
        offset = 0
        for name, dt in zip(names, chunk_dtypes):
            # The stored dtype rules; assignment converts to the column's dtype if they differ.
            out[name][position : position + n_rows] = np.frombuffer(
                blob, dtype=dt, count=n_rows, offset=offset
            )
            offset += n_rows * dt.itemsize
        if offset != len(blob):
            raise ValueError(f"corrupt chunk: {len(blob)} bytes where {offset} were expected")
        position += n_rows
    if position != total_rows:
        raise ValueError(f"chunks hold {position} rows where {total_rows} were expected")
    return out
