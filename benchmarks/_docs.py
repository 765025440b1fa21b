"""Writing a benchmark's own section into docs/BENCHMARKS.md or docs/EVALUATION.md.

One helper for every script: the section starts at its ``## `` heading and runs to
the next ``## `` heading; other sections are left untouched, the file is re-read
just before writing and replaced atomically (others may write their sections too).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS_MD = ROOT / "docs" / "BENCHMARKS.md"
EVALUATION_MD = ROOT / "docs" / "EVALUATION.md"


def replace_section(path: str | os.PathLike[str], text: str, heading: str | None = None) -> Path:
    """Replace (or append) the section ``heading`` (default: the first line of ``text``) of a Markdown file.

    ``text`` is the whole section, heading line included.
    """
    p = Path(path)
    body = text.strip("\n") + "\n"
    head = (heading or body.splitlines()[0]).strip()
    if not head.startswith("## "):
        raise ValueError(f"section heading: expected a '## ' line, got {head!r}")
    title = "# Evaluation" if p.name.upper().startswith("EVALUATION") else "# Benchmarks"
    old = p.read_text(encoding="utf-8") if p.is_file() else title + "\n"
    lines = old.splitlines()
    starts = [i for i, line in enumerate(lines) if line.strip() == head]
    if starts:
        s = starts[0]
        e = next((i for i in range(s + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
        new_lines = lines[:s] + body.rstrip("\n").splitlines() + ([""] + lines[e:] if e < len(lines) else [])
        new = "\n".join(new_lines).rstrip("\n") + "\n"
    else:
        new = old.rstrip("\n") + "\n\n" + body
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(new)
    os.replace(tmp, p)
    return p


def publish(lines: list[str], update_docs: bool, path: str | os.PathLike[str], heading: str) -> str:
    """Print a benchmark's section (``lines`` joined) and, with ``update_docs``, write it into ``path``."""
    text = "\n".join(lines) + "\n"
    print(text)
    if update_docs:
        replace_section(path, text, heading)
    return text
