"""Output folders: created on demand; an unwritable one is a user error (exit 2)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import UserError


def prepare_out_dir(path: str | os.PathLike[str]) -> Path:
    """Create ``path`` (and parents) if needed and check that files can be written in it.

    Raises
    ------
    UserError
        The path is a file, or the folder cannot be created or written.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: --out exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-check.", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise UserError(f"{out}: cannot write to the output folder ({exc.strerror or exc})") from None
    return out
