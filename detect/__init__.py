"""Object detection in 360-degree panoramas (paper, Sec. 3.1 and 4).

- :mod:`detect.detection`: the :class:`Detection` record (class, score,
  seam-aware panorama box, optional mask) and the :class:`Detector` protocol.
- :mod:`detect.tiles`: perspective tiles -> detector -> boxes in the panorama
  -> NMS on the sphere -> tile-consensus scores (:func:`detect_panorama`).
- :mod:`detect.nms`: overlap and non-maximum suppression on the sphere.
- :mod:`detect.grabcut`: automatic grab-cut masks of detected objects.
- :mod:`detect.backends`: detectors by name or file (:func:`get_detector`):
  ONNX models, the Objectron TFLite SSD, annotation files.
- ``python -m detect.fetch_models``: fetch the TFLite model.

Convention: CONVENTIONS.md; panoramas are ``(H, W, 3) uint8`` RGB with W == 2*H.
"""

from .backends import ModelFileError, get_detector
from .detection import BatchDetector, Detection, Detector, ImageDetection, PanoramaDetector, TileBox
from .grabcut import ObjectCrop, grabcut_crop, segment_detections
from .nms import merge_sphere, nms_sphere, pano_box_iou, spherical_iou
from .tiles import PanoramaTiler, box_in_view, detect_panorama, tile_consensus, tile_detections, to_panorama

__all__ = [
    "Detection",
    "ImageDetection",
    "TileBox",
    "Detector",
    "BatchDetector",
    "PanoramaDetector",
    "detect_panorama",
    "tile_detections",
    "to_panorama",
    "box_in_view",
    "PanoramaTiler",
    "tile_consensus",
    "merge_sphere",
    "nms_sphere",
    "spherical_iou",
    "pano_box_iou",
    "ObjectCrop",
    "grabcut_crop",
    "segment_detections",
    "get_detector",
    "ModelFileError",
]
