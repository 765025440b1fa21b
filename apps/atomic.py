"""Atomic file output: write to a temporary file in the target folder, then rename.

An interrupted run never leaves a half-written file behind (CONVENTIONS.md, CLI).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success rename it onto ``path``.

    On an exception the temporary file is removed and ``path`` is untouched.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(d / "a.txt") as tmp:
    ...     _ = tmp.write_text("hello")
    >>> (d / "a.txt").read_text()
    'hello'
    """
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp" + target.suffix, dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp creates 0600; give the file the permissions a plain open() would.
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically and return the path."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | os.PathLike[str], obj: Any) -> Path:
    """Write ``obj`` as indented JSON atomically (NaN/inf are refused: unknowns are ``null``)."""
    return write_text(path, json.dumps(obj, indent=1, allow_nan=False) + "\n")


def write_image(path: str | os.PathLike[str], image: Any) -> Path:
    """Write a uint8/uint16 image array (H, W[, 3|4]) as PNG or JPEG atomically (by the file suffix)."""
    import numpy as np
    from PIL import Image

    arr = np.asarray(image)
    target = Path(path)
    fmt = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}.get(target.suffix.lower())
    if fmt is None:
        raise ValueError(f"{target}: expected a .png or .jpg file name")
    if arr.dtype == np.uint16 and arr.ndim == 2:
        img = Image.fromarray(arr)
    else:
        img = Image.fromarray(np.ascontiguousarray(arr))
    with atomic_path(target) as tmp:
        img.save(tmp, format=fmt)
    return target
