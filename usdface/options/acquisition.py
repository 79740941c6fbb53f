"""Options of face acquisition (seed 001): stereo depth (`stereo`), detection (`detect`), landmark
models (`landmarks train`), registering the generic face onto a scan (`register`), and carrying a
generic blend-shape rig onto a face (`shapes transfer`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..blendshape.parameters import DEFAULT_RIG_TRANSFER, RIG_TRANSFER_METHODS
from ..errors import OptionError
from ..scan.methods import DEFAULT_NUM_DISPARITIES, SINGLE_IMAGE_COPIES, STEREO_METHODS, SURFACES
from .fields import Options, option
from .values import boolean, integer, pair, path, positive_int, shown
from .video import MESH_UNITS, real


def depth_range_value(value, flag):
    """--depth-range NEAR FAR: two numbers (0 < NEAR < FAR is checked where the depths become
    disparities, :func:`usdface.scan.stereo.disparity_range`)."""
    return pair(real, "NEAR FAR in calibration units")(value, flag)


def nonnegative_int(value, flag):
    n = integer(value, flag)
    if n < 0:
        raise OptionError(f"{flag} {shown(value)}: expected a whole number >= 0")
    return n


@dataclass(frozen=True)
class StereoOptions(Options):
    """Stereo depth to a metric scan (`stereo`)."""

    calib: str | None = option(None, flag="--calib", coerce=path, group="stereo",
                               help="calibration JSON (needed for -o)")
    method: str = option("sgbm", flag="--method", choices=STEREO_METHODS, group="stereo",
                         help="sgbm: semi-global matching with consistency checks (fast, default); sgbm-wls: with the "
                              "WLS edge-aware filter; graphcut: KZ1-style alpha-expansion (best, about 100x slower)")
    fill: str = option("background", flag="--fill", choices=("background", "none"), group="stereo",
                       help="pixels of the disparity map that the checks reject: the background disparity of their "
                            "row (default) or NaN; the scan uses accepted pixels only")
    ground_truth: str | None = option(None, flag="--ground-truth", coerce=path, metavar="GT", group="stereo",
                                      help="ground-truth disparity (.npz .pfm .exr .npy .tif; inf/NaN where unknown): "
                                           "print the bad-pixel rate of the map (missing pixels count as bad)")
    bad_threshold: float = option(2.0, flag="--bad-threshold", coerce=real, type=float, metavar="PX",
                                  group="stereo", help="--ground-truth: a pixel is bad when |d - gt| exceeds this")
    min_disparity: int | None = option(None, flag="--min-disparity", coerce=integer, type=int, group="stereo",
                                       help="smallest disparity searched (px)")
    num_disparities: int | None = option(None, flag="--num-disparities", coerce=integer, type=int,
                                         group="stereo",
                                         help=f"number of disparities searched (default {DEFAULT_NUM_DISPARITIES})")
    depth_range: tuple | None = option(None, flag="--depth-range", coerce=depth_range_value, type=float,
                                       nargs=2, metavar=("NEAR", "FAR"), group="stereo",
                                       help="depth range in calibration units; sets the disparity range")
    vertical: bool | None = option(None, flag="--vertical", coerce=boolean, action="store_true", group="stereo",
                                   help="vertical rig (second camera below the first) when there is no calibration")
    surface: str = option("grid", flag="--surface", choices=SURFACES, group="stereo",
                          help="how the scan mesh is made from the depth map")
    step: int = option(2, flag="--step", coerce=integer, type=int, group="stereo",
                       help="pixel subsampling of the scan mesh")
    max_cycles: int = option(3, flag="--max-cycles", coerce=integer, type=int, group="stereo",
                             help="graph cut: expansion cycles")
    time_limit: float | None = option(None, flag="--time-limit", coerce=real, type=float, group="stereo",
                                      help="graph cut: seconds after which no new expansion starts")

    def matching(self, *, min_disparity: int, num_disparities: int, vertical: bool):
        """The matcher's parameters (:class:`usdface.scan.stereo.MatchingParameters`) for the
        disparity range and arrangement resolved from these options and the calibration."""
        from ..scan.graphcut import GraphCutParameters
        from ..scan.stereo import MatchingParameters

        return MatchingParameters(method=self.method, min_disparity=min_disparity, num_disparities=num_disparities,
                                  vertical=vertical,
                                  graphcut=GraphCutParameters(max_cycles=self.max_cycles, time_limit=self.time_limit))


@dataclass(frozen=True)
class DetectOptions(Options):
    """Haar face detection and AAM landmarks (`detect`)."""

    aam: str | None = option(None, flag="--aam", coerce=path, group="detection",
                             help="AAM model (.npz, from `usdface landmarks train`)")
    min_size: int | None = option(None, flag="--min-size", coerce=integer, type=int, group="detection",
                                  help="smallest face side in pixels")


@dataclass(frozen=True)
class LandmarksTrainOptions(Options):
    """Training an active appearance model (`landmarks train`)."""

    landmarks: str | None = option(None, flag="--landmarks", coerce=path, group="training",
                                   help="landmarks JSON of a single IMAGE")
    points_dir: str | None = option(None, flag="--points-dir", coerce=path, group="training",
                                    help="folder of the point files (default: beside each image)")
    augment: int | None = option(None, flag="--augment", coerce=nonnegative_int, type=int, group="training",
                                 help=f"jittered copies per image (default {SINGLE_IMAGE_COPIES} with --landmarks, "
                                      "else 0)")


@dataclass(frozen=True)
class RegisterOptions(Options):
    """Registering the generic face onto a scan (`register`)."""

    landmarks: str | None = option(None, flag="--landmarks", coerce=path, group="registration",
                                   help="scan landmarks JSON (image or scan points) or a detect features file")
    generic_landmarks: str | None = option(None, flag="--generic-landmarks", coerce=path, group="registration",
                                           help="the generic's landmarks (marker layout; default "
                                                "GENERIC_STEM.landmarks.layout.json beside the generic)")
    layout: str | None = option(None, flag="--layout", coerce=path, group="registration",
                                help="the generic's marker layout, carried over")
    image: str | None = option(None, flag="--image", coerce=path, group="registration",
                               help="without --landmarks: the first stereo image to detect the landmarks on")
    aam: str | None = option(None, flag="--aam", coerce=path, group="registration",
                             help="without --landmarks: AAM model for --image")
    iterations: int = option(20, flag="--iterations", coerce=integer, type=int, group="registration",
                             help="closest-point iterations")
    border: bool = option(False, flag="--border", coerce=boolean, group="registration",
                          help="also match the generic's outer border to the scan's (for scans cropped like the "
                               "generic)")
    field: int = option(0, flag="--field", coerce=integer, type=int, metavar="N", group="registration",
                        help="iterations of the smooth-field stage before the projection (8 with --border for scans "
                             "cropped like the generic)")

    def registration(self):
        """The registration's parameters (:class:`usdface.scan.register.RegistrationParameters`)."""
        from ..scan.register import RegistrationParameters

        return RegistrationParameters(iterations=self.iterations, border_weight=1.0 if self.border else 0.0,
                                      field_iterations=self.field)


@dataclass(frozen=True)
class ShapesTransferOptions(Options):
    """Carrying a generic blend-shape rig onto a face (`shapes transfer`)."""

    generic: str | None = option(None, flag="--generic", coerce=path, group="registration",
                                 help="generic rig: a USD mesh with blend shapes, or a neutral mesh with "
                                      "--generic-shapes (default: the MakeHuman rig shipped with usdface)")
    generic_shapes: str | None = option(None, flag="--generic-shapes", coerce=path, metavar="DIR|NPZ|RIG.usd",
                                        group="registration", help="the generic neutral's shapes")
    generic_landmarks: str | None = option(None, flag="--generic-landmarks", coerce=path, group="registration",
                                           help="the generic's landmarks (marker layout)")
    method: str = option(DEFAULT_RIG_TRANSFER, flag="--method", choices=RIG_TRANSFER_METHODS, group="registration",
                         help="offsets rotated and scaled with the face (default), or deformation transfer "
                              "(Sumner & Popovic 2004) following the target's local shape")
    border: bool = option(True, flag="--no-border", coerce=boolean, group="registration",
                          help="do not match the outer borders (for targets not cropped like the generic)")
    field: int = option(8, flag="--field", coerce=integer, type=int, metavar="N", group="registration",
                        help="registration smooth-field iterations")
    iterations: int = option(20, flag="--iterations", coerce=positive_int, type=int, group="registration",
                             help="registration closest-point iterations")
    mesh_units: str | None = option(None, flag="--mesh-units", choices=MESH_UNITS, group="mesh",
                                    help="units of mesh files")

    def registration(self):
        """The registration's parameters (:class:`usdface.scan.register.RegistrationParameters`), as
        `usdface register` takes them."""
        from ..scan.register import RegistrationParameters

        return RegistrationParameters(iterations=self.iterations, border_weight=1.0 if self.border else 0.0,
                                      field_iterations=self.field)
