"""apps: the ``pano2cad`` command line and the reference pipeline.

Composition only: reads and checks inputs, calls panogeom, detect, posecrf and
layout in the order of ARCHITECTURE.md, and writes the outputs (scene.json,
GLB/OBJ, floor plan, overlays, report) atomically. No algorithm lives here.
"""
