"""The pipeline's mesh outlines, kept in the model-library cache folder between runs."""

from __future__ import annotations

import numpy as np

from posecrf.cache import CACHE_ENV


def test_outline_is_stored_reloaded_and_recomputed_when_damaged(tmp_path, monkeypatch):
    import apps.pipeline as pipeline
    from layout.sampler import mesh_outline
    from posecrf.library import builtin_library

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    model = builtin_library()["table-01"]
    fresh = pipeline._stored_outline(model)
    assert np.array_equal(fresh, mesh_outline(model.vertices, model.faces, max_points=400))
    (stored,) = (tmp_path / "outlines").glob("table-01-*.npy")
    assert np.array_equal(np.load(stored), fresh)

    marker = fresh + 1.0  # a stored outline is read, not computed again
    np.save(stored, marker)
    assert np.array_equal(pipeline._stored_outline(model), marker)

    stored.write_bytes(b"not an array")  # a damaged file is computed again and replaced
    assert np.array_equal(pipeline._stored_outline(model), fresh)
    assert np.array_equal(np.load(stored), fresh)


def test_outline_without_a_writable_cache_folder(tmp_path, monkeypatch):
    import apps.pipeline as pipeline
    from posecrf.library import builtin_library

    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should be")
    monkeypatch.setenv(CACHE_ENV, str(blocker))
    model = builtin_library()["tv-01"]
    pts = pipeline._stored_outline(model)
    assert pts.ndim == 2 and pts.shape[1] == 3 and len(pts) > 4
