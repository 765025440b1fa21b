"""Progress on stderr for long steps; ``quiet`` silences it. Stage timings for scene.json."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from collections.abc import Iterator


class Progress:
    """Reports stages on stderr and records their wall time.

    Examples
    --------
    >>> p = Progress(quiet=True)
    >>> with p.stage("lines"):
    ...     pass
    >>> sorted(p.timings)
    ['lines']
    """

    def __init__(self, quiet: bool = False, stream=None) -> None:
        self.quiet = quiet
        self.stream = stream if stream is not None else sys.stderr
        self.timings: dict[str, float] = {}
        self._t0 = time.perf_counter()

    def say(self, msg: str) -> None:
        if not self.quiet:
            print(msg, file=self.stream, flush=True)

    @contextmanager
    def stage(self, name: str, label: str | None = None) -> Iterator[None]:
        self.say(f"[{time.perf_counter() - self._t0:6.1f}s] {label or name} ...")
        t = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = round(time.perf_counter() - t, 4)

    def total(self) -> float:
        return round(time.perf_counter() - self._t0, 4)

    def bar(self, iterable, total: int | None = None, desc: str = ""):
        """Wrap an iterable in a tqdm bar on stderr (none when quiet)."""
        from tqdm import tqdm

        return tqdm(iterable, total=total, desc=desc, disable=self.quiet, file=self.stream, leave=False)
