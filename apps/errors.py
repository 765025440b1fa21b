"""Errors of the command line: a user mistake is a :class:`UserError` (exit 2, one line, no traceback)."""

from __future__ import annotations

EXIT_OK = 0
EXIT_INTERNAL = 1
EXIT_USAGE = 2


class UserError(Exception):
    """Bad input or usage. The CLI prints ``pano2cad: error: <message>`` and exits 2.

    The message names the file and the problem, e.g.
    ``"pano.jpg: expected an equirectangular panorama with width == 2*height, got 3000x2000"``.
    """
