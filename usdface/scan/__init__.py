"""Face acquisition (seed 001, sections 2-4): stereo depth, face and feature detection, and the
registration of a generic face onto a scan.

- :mod:`~usdface.scan.calibration`: calibration files, rectification;
- :mod:`~usdface.scan.stereo`: disparity maps (SGBM + WLS, graph cuts, plain SGBM), bad-pixel rate;
- :mod:`~usdface.scan.graphcut`: the KZ1-style energy and alpha-expansion;
- :mod:`~usdface.scan.surface`: depth map -> points -> scan mesh;
- :mod:`~usdface.scan.detect`: Haar face, eye and mouth detection;
- :mod:`~usdface.scan.aam`: active appearance model (train, fit);
- :mod:`~usdface.scan.landmarks`: landmark files, the standard 20 landmarks;
- :mod:`~usdface.scan.image_landmarks`: image landmarks lifted onto a scan through its camera;
- :mod:`~usdface.scan.warp`, :mod:`~usdface.scan.register`: thin-plate RBF warp, registration (its
  stages; :mod:`~usdface.scan.similarity`, :mod:`~usdface.scan.mesh_operators` and
  :mod:`~usdface.scan.closest_points` hold the similarity fit, the mesh operators and the
  closest-point searches it uses);
- :mod:`~usdface.scan.render`, :mod:`~usdface.scan.synthetic`: renderer and synthetic test data
  with exact ground truth.

cv2 is imported by these modules (and io/, tracking/, preview/) only.
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "StereoCalibration": "calibration", "read_calibration": "calibration", "rectify_pair": "calibration",
    "FACE_LANDMARKS": "landmarks", "Landmarks": "landmarks", "read_landmarks": "landmarks",
    "write_landmarks": "landmarks", "GenericRegistration": "register", "RegistrationParameters": "register",
    "RegistrationResult": "register", "register_generic": "register", "similarity_fit": "similarity",
    "METHODS": "stereo", "MatchingParameters": "stereo", "DisparityResult": "stereo", "bad_pixel_rate": "stereo",
    "compute_disparity": "stereo", "lift_image_landmarks": "image_landmarks",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = ["StereoCalibration", "read_calibration", "rectify_pair", "FACE_LANDMARKS", "Landmarks",
           "read_landmarks", "write_landmarks", "GenericRegistration", "RegistrationParameters", "RegistrationResult",
           "register_generic", "similarity_fit", "METHODS", "MatchingParameters", "DisparityResult", "bad_pixel_rate",
           "compute_disparity", "lift_image_landmarks"]
