"""posecrf's 3D model library: procedural furniture, user model folders, export.

The paper renders 3D Warehouse models (9 beds, 16 chairs, 6 TVs, 4 plants) in
many poses and retrieves pose and model by HOG nearest neighbours. This
subpackage provides the models those renders are made from:

- `builtin_library()`: 47 procedural models (the paper's counts plus the
  clutter classes sofa, table, nightstand, wardrobe), cached and immutable;
- `load_model_folder()`: a user's OBJ / GLB / PLY files with JSON metadata,
  cleaned with pymeshlab and normalised into the canonical frame;
- `export_model()` / `export_scene()`: colour-preserving GLB / OBJ files,
  written atomically.

Convention:
    Canonical model frame (shared/CONVENTIONS.md): metres, z up, base centred
    at the origin (bbox centre x = y = 0, min z = 0), front facing +x;
    ``size`` = extents along (x, y, z). Symmetry "two" means 180-degree
    symmetric about z, "full" means any yaw looks the same.

Examples
--------
>>> from posecrf.library import builtin_library
>>> lib = builtin_library()
>>> len(lib), lib.counts()["chair"], lib["tv-03"].symmetry
(47, 16, 'none')
"""

from .catalog import ModelLibrary, builtin_library
from .export import export_model, export_scene, scene_of
from .model import MATERIAL_NAMES, MATERIALS, Material, Model3D, Symmetry, material_index
from .parts import Part, assemble_model, canonicalize_vertices
from .userfolder import (
    ModelFileError,
    ModelFolderResult,
    ModelLoadIssue,
    ModelMetadata,
    axes_rotation,
    load_model_file,
    load_model_folder,
    parse_metadata,
)

__all__ = [
    "MATERIALS",
    "MATERIAL_NAMES",
    "Material",
    "Model3D",
    "ModelFileError",
    "ModelFolderResult",
    "ModelLibrary",
    "ModelLoadIssue",
    "ModelMetadata",
    "Part",
    "Symmetry",
    "assemble_model",
    "axes_rotation",
    "builtin_library",
    "canonicalize_vertices",
    "export_model",
    "export_scene",
    "load_model_file",
    "load_model_folder",
    "material_index",
    "parse_metadata",
    "scene_of",
]
