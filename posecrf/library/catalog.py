"""`ModelLibrary`: an immutable catalogue of `Model3D` by id and by class.

Convention:
    Every model in a library is in the canonical model frame (metres, z up,
    bbox centre at x = y = 0, min z = 0, front facing +x); ids are unique.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from functools import lru_cache

from .model import Model3D


class ModelLibrary:
    """Models looked up by id and by class, in a fixed order.

    The library is immutable (a tuple of frozen models with read-only
    arrays); combine libraries with `merged`, narrow with `subset`.

    Parameters
    ----------
    models : iterable of Model3D
        Models with unique ids.

    Examples
    --------
    >>> lib = builtin_library()
    >>> lib["bed-03"].cls, len(lib.by_class("chair")), "tv-06" in lib
    ('bed', 16, True)
    >>> lib.counts()["plant"]
    4
    """

    __slots__ = ("_models", "_by_id")

    def __init__(self, models: Iterable[Model3D] = ()) -> None:
        ms = tuple(models)
        by_id: dict[str, Model3D] = {}
        for m in ms:
            if not isinstance(m, Model3D):
                raise ValueError(f"expected Model3D objects, got {type(m).__name__}")
            if m.id in by_id:
                raise ValueError(f"expected unique model ids, got {m.id!r} twice")
            by_id[m.id] = m
        self._models = ms
        self._by_id = by_id

    def __len__(self) -> int:
        return len(self._models)

    def __iter__(self) -> Iterator[Model3D]:
        return iter(self._models)

    def __contains__(self, model_id: object) -> bool:
        return model_id in self._by_id

    def __getitem__(self, model_id: str) -> Model3D:
        try:
            return self._by_id[model_id]
        except KeyError:
            raise KeyError(f"no model {model_id!r} in the library (it has {len(self)} models: {self._id_preview()})") from None

    def __repr__(self) -> str:
        return f"ModelLibrary({len(self)} models: {self.counts()})"

    def _id_preview(self) -> str:
        ids = list(self._by_id)
        return ", ".join(ids[:8]) + (", ..." if len(ids) > 8 else "")

    def get(self, model_id: str, default: Model3D | None = None) -> Model3D | None:
        """The model with `model_id`, or `default`."""
        return self._by_id.get(model_id, default)

    @property
    def models(self) -> tuple[Model3D, ...]:
        """All models in library order."""
        return self._models

    @property
    def ids(self) -> tuple[str, ...]:
        """All model ids in library order."""
        return tuple(self._by_id)

    @property
    def classes(self) -> tuple[str, ...]:
        """Class names present, in order of first appearance."""
        return tuple(dict.fromkeys(m.cls for m in self._models))

    def by_class(self, cls: str) -> tuple[Model3D, ...]:
        """Models of class `cls` (empty if none).

        Examples
        --------
        >>> [m.id for m in builtin_library().by_class("tv")][:2]
        ['tv-01', 'tv-02']
        """
        if not isinstance(cls, str):
            raise ValueError(f"expected a class name string, got {type(cls).__name__}")
        return tuple(m for m in self._models if m.cls == cls)

    def counts(self) -> dict[str, int]:
        """Number of models per class, in order of first appearance."""
        out: dict[str, int] = {}
        for m in self._models:
            out[m.cls] = out.get(m.cls, 0) + 1
        return out

    def subset(self, classes: Iterable[str]) -> "ModelLibrary":
        """A library with the models of the given classes only."""
        wanted = set(classes)
        return ModelLibrary(m for m in self._models if m.cls in wanted)

    def merged(self, other: "ModelLibrary | Iterable[Model3D]") -> "ModelLibrary":
        """This library followed by `other`'s models (ids must stay unique)."""
        return ModelLibrary((*self._models, *other))

    def content_hashes(self) -> dict[str, str]:
        """Model id -> `Model3D.content_hash`."""
        return {m.id: m.content_hash() for m in self._models}


@lru_cache(maxsize=1)
def builtin_library() -> ModelLibrary:
    """The procedural built-in library (built once, then cached).

    9 beds, 16 chairs, 6 TVs and 4 plants (the counts of the paper's
    3D Warehouse set) plus clutter classes sofa, table, nightstand and
    wardrobe. The cached models are immutable: their arrays are read-only
    and `Model3D.mesh` returns a copy.

    Convention:
        Canonical model frame: metres, z up, bbox centre x = y = 0,
        min z = 0, front facing +x.

    Examples
    --------
    >>> lib = builtin_library()
    >>> lib is builtin_library(), lib.classes
    (True, ('bed', 'chair', 'tv', 'plant', 'sofa', 'table', 'nightstand', 'wardrobe'))
    """
    from .procedural import build_all

    return ModelLibrary(build_all())
