"""posecrf: object pose and model retrieval by a pairwise CRF.

Owns a generic pairwise MRF with a TRW-S solver (:mod:`posecrf.mrf`,
:mod:`posecrf.trws`), HOG descriptors (:mod:`posecrf.hog`), the 3D model
library of procedural furniture and user model folders
(:mod:`posecrf.library`), pose renders of the library with their on-disk
cache, k-NN retrieval, and the pose CRF of the paper (Sec. 3.2).

May import panogeom; never detect or layout. pyrender, trimesh, pymeshlab and
libigl are imported lazily.
"""
