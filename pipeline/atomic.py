"""Atomic output: a file appears complete or not at all.

Every output of the pipeline is first written to a temporary name in the same
folder and renamed into place only when complete, so an interrupted run never
leaves a truncated file behind (``os.replace`` is atomic on one file system).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path, *, suffix: str | None = None):
    """Yield a temporary path beside ``path``; move it onto ``path`` on success.

    Parameters
    ----------
    path : str or Path
        Final destination. Its folder must exist.
    suffix : str, optional
        Suffix of the temporary file (default: that of ``path``), for writers
        such as OpenCV that choose the format from the file name.
    """
    path = Path(path)
    suffix = path.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".part{suffix}", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        # mkstemp makes owner-only files; give the result the usual permissions
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


@contextlib.contextmanager
def atomic_dir(path):
    """Yield a temporary folder beside ``path``; rename it to ``path`` on success.

    An existing folder at ``path`` is replaced only once the new one is complete.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        for child in tmp.rglob("*"):
            os.chmod(child, (0o777 if child.is_dir() else 0o666) & ~_umask())
        if path.exists():
            old = path.with_name(f".{path.name}.old")
            if old.exists():
                _rmtree(old)
            os.replace(path, old)
            os.replace(tmp, path)
            _rmtree(old)
        else:
            os.replace(tmp, path)
    finally:
        if tmp.exists():
            _rmtree(tmp)


def _rmtree(path: Path):
    import shutil

    shutil.rmtree(path, ignore_errors=True)


def write_csv(frame, path, *, float_format: str | None = None) -> Path:
    """Write a DataFrame to CSV atomically, without its index.

    Parameters
    ----------
    frame : pandas.DataFrame
    path : str or Path
    float_format : str, optional
        A ``%`` format for the floats (e.g. ``"%.4g"``); by default each float is
        written as the shortest text that reads back as the same number.

    Notes
    -----
    A table of numbers only, with no ``float_format``, is written by pyarrow's
    CSV writer: pandas formats every float in Python, which took a sixth of a
    whole tracking run on a 100-frame video's 330 000 centreline values, and
    pyarrow does it ten times faster with the same text. Tables with text in them
    stay with pandas, because pyarrow quotes every string.
    """
    with atomic_path(path) as tmp:
        if float_format is None and _all_numeric(frame):
            _write_numeric_csv(frame, tmp)
        else:
            frame.to_csv(tmp, index=False, float_format=float_format)
    return Path(path)


def _all_numeric(frame) -> bool:
    import pandas as pd

    return len(frame.columns) > 0 and all(
        pd.api.types.is_integer_dtype(t) or pd.api.types.is_float_dtype(t)
        for t in frame.dtypes)


def _write_numeric_csv(frame, path):
    import pyarrow as pa
    import pyarrow.csv as pacsv

    table = pa.Table.from_pandas(frame, preserve_index=False)
    pacsv.write_csv(table, path, pacsv.WriteOptions(quoting_header="none"))


def write_json(obj, path) -> Path:
    """Write a JSON document atomically (indented, NaN refused)."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return Path(path)


def write_text(text: str, path) -> Path:
    """Write a text file atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
