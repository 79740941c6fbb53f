"""The stereo matchers and their default disparity count, the scan-surface methods and the landmark
model's augmentation default, named once (the options offer these; importing this module loads
nothing else)."""

#: disparity methods (:func:`usdface.scan.stereo.compute_disparity`)
STEREO_METHODS = ("sgbm", "sgbm-wls", "graphcut")
#: disparities searched when neither a disparity range nor a depth range is given
DEFAULT_NUM_DISPARITIES = 64
#: how a depth map becomes a scan mesh (:func:`usdface.scan.surface.scan_surface`)
SURFACES = ("grid", "poisson", "ball-pivoting")
#: jittered copies of the single image `landmarks train --landmarks` trains from, unless told
#: (:func:`usdface.scan.aam.augment_sample`)
SINGLE_IMAGE_COPIES = 40
