"""layout: the room - surface labels, geometry, scene model and posterior.

Owns surface labelling (orientation map + geometric context), per-view point
clouds, Open3D alignment and greedy plane fitting, Manhattan floor polygons
(:mod:`layout.polygon`), the synthetic room generator (:mod:`layout.rooms`),
the context prior of Sec. 3.3 (:mod:`layout.context`), object placement
(:mod:`layout.placement`), the scene model, the likelihoods E_s and E_o, the
MAP sampler and layout metrics.

May import panogeom, open3d, scikit-image and torch; never detect or posecrf
(their results arrive as plain arrays).
"""
