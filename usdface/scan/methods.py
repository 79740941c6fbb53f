"""The stereo matchers and scan-surface methods, named once (the options offer these)."""

#: disparity methods (:func:`usdface.scan.stereo.compute_disparity`)
STEREO_METHODS = ("sgbm", "sgbm-wls", "graphcut")
#: how a depth map becomes a scan mesh (:func:`usdface.scan.surface.scan_surface`)
SURFACES = ("grid", "poisson", "ball-pivoting")
