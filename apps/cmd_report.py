"""``pano2cad report DIR``: (re)build DIR/report.html from the files of a run's output folder."""

from __future__ import annotations

from pathlib import Path

from .errors import UserError


def run(args) -> int:
    from .report import write_report

    out = Path(args.dir)
    if not out.is_dir():
        got = "a file" if out.exists() else "nothing"
        raise UserError(f"{out}: expected an output folder of `pano2cad run`, got {got}")
    try:
        path = write_report(out)
    except PermissionError as exc:
        raise UserError(f"{out}: cannot write report.html ({exc.strerror or exc})") from None
    if not (out / "scene.json").is_file() and not args.quiet:
        import sys

        print(f"{out}: no scene.json; the report says what is missing", file=sys.stderr)
    print(path)
    return 0
