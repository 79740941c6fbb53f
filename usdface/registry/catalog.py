"""usdface's own processors, each declared once (:class:`~usdface.registry.Processor`).

The order here is the order of ``usdface --help`` and of the README's command table. A new
processor is one module (its function) and one entry here; a new deliverable of `run` is also one
line of :data:`usdface.options.DELIVERABLES`.
"""
from __future__ import annotations

from ..options import (BatchOptions, BindOptions, CaptureOptions, DetectOptions, DistanceOptions, EvaluateOptions,
                       FitMusclesOptions, ImportMeshOptions, LandmarksTrainOptions, LiftOptions, MusclesOptions,
                       NoOptions, PlayblastOptions, PreviewOptions, RegisterOptions, ReportOptions, RunOptions,
                       ShapesTransferOptions, SimulateOptions, SkelLayerOptions, SolveOptions, StereoOptions,
                       TrackOptions, TransferOptions)
from .declarations import CommandGroup, Input, Output, Processor

__all__ = ["PROCESSORS", "GROUPS"]

_MESH = Input("mesh", "mesh layer", flag="--mesh")


def _layer(name: str, help: str, *, flag: str | None = None) -> Input:
    """A USD input that, in Python, defaults to the stage holding the mesh (one scene holds both)."""
    return Input(name, help, flag=flag or f"--{name}", default_from="mesh")


PROCESSORS = (
    Processor(
        "import-capture", "import marker capture (Maya ASCII, C3D, TRC, CSV) into a capture layer",
        "Import marker capture (.ma, .c3d, .trc, .csv) into a .usdc capture layer (/Capture/Markers), optionally "
        "stabilised, gap-filled, filtered, trimmed, resampled.",
        function="usdface.processors.import_capture:import_capture", options=CaptureOptions,
        inputs=(Input("source", "capture file", dest="input", metavar="TAKE"),),
        outputs=(Output("output", "capture layer to write (.usdc)", metavar="capture.usdc"),)),
    Processor(
        "import-mesh", "import a face mesh (OBJ, PLY, STL, OFF, USD) into a mesh layer",
        "Import a face mesh into a mesh layer (/Face/Geom), keeping polygons and UVs, with boundary loops found and "
        "holes stored as face regions.",
        function="usdface.processors.import_mesh:import_mesh", options=ImportMeshOptions,
        inputs=(Input("source", "mesh file", dest="input", metavar="MESH"),),
        outputs=(Output("output", "mesh layer to write (.usdc or .usda)", metavar="mesh.usdc"),)),
    Processor(
        "bind", "bind capture markers to points on the mesh surface",
        "Bind each capture marker to a point on the mesh surface, from a layout file or by automatic alignment of "
        "the neutral marker cloud.",
        function="usdface.processors.bind:bind", options=BindOptions,
        inputs=(Input("mesh", "mesh layer (from import-mesh)", flag="--mesh"),
                _layer("capture", "capture layer (from import-capture)")),
        outputs=(Output("output", "binding layer to write (.usda)", metavar="binding.usda"),),
        exclusive=((("layout", "auto"), True),)),
    Processor(
        "distances", "vertex-to-marker distance matrices (euclidean, geodesic, hybrid)",
        "Compute the N x M vertex-to-marker and M x M marker-to-marker distance matrices (plus pinned constraint "
        "vertices) and store them on the mesh in an analysis layer.",
        function="usdface.processors.distances:distances", options=DistanceOptions,
        inputs=(_MESH, _layer("binding", "binding layer")),
        outputs=(Output("output", "analysis layer to write (.usdc)", metavar="analysis.usdc"),)),
    Processor(
        "transfer", "RBF transfer of the capture onto the face -> animated points",
        "Transfer the capture's marker displacements to every vertex with radial basis functions over a "
        "precomputed distance matrix; write time-sampled points.",
        function="usdface.processors.transfer:transfer", options=TransferOptions,
        inputs=(_MESH, _layer("capture", "capture layer"), _layer("binding", "binding layer"),
                _layer("analysis", "analysis layer (from `usdface distances`)")),
        outputs=(Output("output", "animation layer to write (.usdc)", metavar="anim.usdc"),)),
    Processor(
        "skel", "skeletal keyframes (UsdSkel): a joint per marker, skinned like the transfer",
        "Write a UsdSkel layer: one SkelRoot (carrying the head motion), a Skeleton with a static root joint and one "
        "joint per marker at its bound point, a SkelAnimation with the joints' motion, and skin weights that "
        "reproduce `usdface transfer`'s point cache: by default non-negative, summing to one, K per vertex, with "
        "corrective blend shapes (DCC-safe); or the exact signed transfer matrix. The error against the point cache "
        "is reported.",
        function="usdface.processors.skel:skel", options=SkelLayerOptions,
        inputs=(_MESH, _layer("capture", "capture layer"), _layer("binding", "binding layer"),
                _layer("analysis", "analysis layer (from `usdface distances`)")),
        outputs=(Output("output", "skeleton layer to write (.usdc)", metavar="skel.usdc"),)),
    Processor(
        "blendshapes", "blend-shape weight curves of a take on the rig `run` delivers",
        "The blend-shape step of `usdface run --output-kind blendshapes`: the curves layer and the curves CSVs from "
        "the layers `run` wrote.",
        function="usdface.processors.blendshapes:blendshapes", options=SolveOptions, command=False,
        inputs=(Input("rig", "the rig: a mesh layer (with --shapes) or a USD mesh with blend shapes", flag="--rig"),
                Input("capture", "capture layer (conditioned)", flag="--capture", default_from="rig"),
                Input("binding", "binding layer", flag="--binding", default_from="rig")),
        outputs=(Output("output", "curves layer to write (.usdc)"),
                 Output("csv", "curves CSV to write", flags=("--csv",), kind="file"),
                 Output("livelink", "Live Link Face CSV to write", flags=("--livelink",), kind="file",
                        required=False))),
    Processor(
        "solve", "marker capture -> blend-shape weight curves on a rig (CURVES.usdc, CSV)",
        "Solve a capture's stabilised marker motion as blend-shape weights in [0, 1] for every frame of the take at "
        "once (smooth, sparse, left/right prior on mirrored pairs); write one layer with the mesh, its BlendShape "
        "prims and a UsdSkel animation that imports alone in DCCs. --apply plays curves on another rig.",
        function="usdface.pipeline.solve:solve", options=SolveOptions,
        inputs=(Input("mesh", "a USD mesh with UsdSkel blend shapes, or a neutral mesh (OBJ, USD...) given with "
                      "--shapes", flag="--mesh", metavar="RIG"),
                Input("capture", "capture (Maya ASCII, C3D, TRC, CSV or a capture layer)", flag="--capture",
                      required=False),
                Input("apply", "instead of solving: apply these curves to --mesh (shapes matched by name)",
                      flag="--apply", kind="file", required=False, metavar="CURVES.csv|CURVES.usdc",
                      positional=False)),
        outputs=(Output("output", "curves layer to write (.usdc)", metavar="CURVES.usdc"),
                 Output("csv", "also write the curves as CSV: frame,time,<shape names>", flags=("--csv",),
                        kind="file", required=False, metavar="CURVES.csv"),
                 Output("livelink", "also write the Live Link Face CSV layout (ARKit names)", flags=("--livelink",),
                        kind="file", required=False, metavar="FILE.csv", dest="livelink_csv"),
                 Output("corrective", "also write a points shot: the rig's pose plus the RBF transfer of the "
                        "residual (markers hit exactly); default name <output>_corrective.usdc",
                        flags=("--corrective",), required=False, metavar="POINTS.usdc", nargs="?", const=True))),
    Processor(
        "shapes transfer", "register a generic rig onto a face and transfer its shapes",
        "Register the generic face onto TARGET (similarity, thin-plate warp, closest-point projection, as "
        "`usdface register`; the target's topology is not used) and carry every blend shape over; writes a rig "
        "layer for `usdface solve --mesh RIG.usdc`.",
        function="usdface.processors.shapes_transfer:shapes_transfer", options=ShapesTransferOptions,
        inputs=(Input("target", "the face without a rig (OBJ, PLY, ... or a USD mesh layer)", flag="--target"),
                Input("landmarks", "the target's landmarks: a marker layout on it, or "
                      "{\"name\": {\"scan\": [x, y, z]}}", flag="--landmarks", kind="file")),
        outputs=(Output("output", "rig layer to write (.usdc)", metavar="RIG.usdc"),)),
    Processor(
        "track", "track coloured face markers in a video -> 2D track layer (+ CSV, preview)",
        "Track coloured dots on a face in a video (seed 002: YCbCr Mahalanobis colour segmentation, morphology, "
        "connected components, sub-pixel centroids, circular Hough transform) and keep their identities frame to "
        "frame; write a 2D track layer (pixels, y down), optionally CSV and a preview.",
        function="usdface.processors.track:track", options=TrackOptions, batch_step=False,
        inputs=(Input("video", "movie (.mp4, .avi, .mov) or image sequence (name.####.png|jpg|tif|exr|dpx)",
                      kind="file", metavar="VIDEO"),),
        outputs=(Output("output", "track layer to write", metavar="TRACKS.usdc"),
                 Output("csv", "also write the tracks as usdface CSV (2D, pixels)", flags=("--csv",), kind="file",
                        required=False, metavar="TRACKS.csv"),
                 Output("preview", "also write a PNG of a tracked frame", flags=("--preview",), kind="file",
                        required=False, metavar="OUT.png")),
        exclusive=((("seeds", "auto"), True),)),
    Processor(
        "lift", "lift 2D marker tracks (video) to a 3D capture layer on the mesh",
        "Map 2D image tracks of face markers to 3D motion on a character mesh: fit a weak-perspective camera to the "
        "neutral frame against the markers' bound points, map image displacements into the image plane in mesh "
        "units, and take the depth change from the face surface (tangent plane) or zero. Writes a capture layer "
        "(mesh units, same marker names) for bind/transfer/skel.",
        function="usdface.processors.lift:lift", options=LiftOptions,
        inputs=(Input("tracks", "2D track layer (.usd*) or 2D capture CSV (pixels)", metavar="TRACKS"),
                Input("mesh", "mesh layer, or a mesh file (OBJ, PLY, STL, OFF... as `run` takes)", flag="--mesh")),
        outputs=(Output("output", "capture layer to write (.usdc)", metavar="capture.usdc"),),
        exclusive=((("binding", "layout"), True),)),
    Processor(
        "stereo", "stereo pair -> disparity map and metric scan mesh layer",
        "Match a stereo pair (rectified, or calibrated and rectified here) into a disparity map and, with --calib, "
        "a metric scan mesh layer. Calibration JSON: {\"f\", \"cx\", \"cy\", \"baseline\", \"doffs\", \"vertical\", "
        "\"units\"} for a rectified pair or K1, D1, K2, D2, R, T.",
        function="usdface.processors.stereo:stereo", options=StereoOptions,
        inputs=(Input("left", "left (or top) image", kind="file", metavar="LEFT"),
                Input("right", "right (or bottom) image", kind="file", metavar="RIGHT")),
        outputs=(Output("output", "scan mesh layer to write (.usdc)", required=False, metavar="SCAN.usdc"),
                 Output("disparity", "disparity map to write (.exr, .tif, .pfm, .npy)", flags=("--disparity",),
                        kind="file", required=False, metavar="D.exr"))),
    Processor(
        "detect", "Haar face/eye/mouth detection and AAM landmarks -> features JSON",
        "Find faces (OpenCV Haar cascades: frontal face, eyes; the smile cascade for the mouth, since OpenCV ships no "
        "mouth cascade) and, with --aam, fit the facial landmarks of the largest face.",
        function="usdface.processors.detect:detect", options=DetectOptions,
        inputs=(Input("image", "image with a face", kind="file", metavar="IMAGE"),),
        outputs=(Output("output", "features JSON to write", kind="file", metavar="FEATURES.json"),
                 Output("preview", "PNG with the detections drawn", flags=("--preview",), kind="file",
                        required=False, metavar="P.png"))),
    Processor(
        "landmarks train", "train an AAM from annotated images",
        "Train an active appearance model. Each IMAGE needs a point file beside it (STEM.pts, STEM.landmarks.json or "
        "STEM.json), or give one IMAGE with --landmarks L.json (about 20 hand-placed points; the image is augmented).",
        function="usdface.processors.landmarks_train:landmarks_train", options=LandmarksTrainOptions,
        inputs=(Input("images", "annotated images", kind="files", metavar="IMAGE"),),
        outputs=(Output("output", "model to write (.npz)", kind="file", metavar="MODEL.npz"),)),
    Processor(
        "register", "warp the generic face onto a scan (RBF + closest points), keeping its topology",
        "Register a generic face mesh layer onto a scan: similarity and thin-plate RBF warp from landmark "
        "correspondences, then iterated closest-point projection with normal compatibility and a smoothness term, "
        "eye and mouth holes excluded. Regions and the marker layout carry over.",
        function="usdface.processors.register:register", options=RegisterOptions,
        inputs=(Input("generic", "generic mesh layer with regions", flag="--generic"),
                Input("scan", "scan mesh layer (from `usdface stereo`)", flag="--scan")),
        outputs=(Output("output", "registered mesh layer to write (.usdc)", metavar="REGISTERED.usdc"),
                 Output("layout_output", "where the carried layout goes (default OUTPUT_STEM.layout.json)",
                        flags=("--layout-output",), kind="file", required=False))),
    Processor(
        "evaluate", "transfer quality against ground-truth expression shapes (markdown table)",
        "For each ground-truth shape, transfer its displacements at the bound marker points back to the whole face "
        "with each distance method, RBF mode and pinned-border variant, and report the mean/max vertex error over the "
        "face and per region (mouth, eyes, rest), in cm and as % of the shape's mean displacement; plus the paper's "
        "claim (upper lip on jawOpen, lower lid on eyeBlink).",
        function="usdface.processors.evaluate:evaluate", options=EvaluateOptions,
        inputs=(Input("mesh", "face mesh (.obj, .ply, ... or a USD mesh layer)", flag="--mesh"),
                Input("shapes", "ground-truth shapes .npz: names (F,), deltas (F, N, 3) in mesh units, optional "
                      "neutral (N, 3)", flag="--shapes", kind="file", metavar="S.npz")),
        outputs=(Output("output", "write the markdown report to this file", kind="file", required=False,
                        metavar="REPORT.md"),),
        exclusive=((("layout", "binding"), True),)),
    Processor(
        "muscles", "place the default muscle rig on a face -> rig layer (.usda)",
        "Place a rig of named anatomical muscles (zygomaticMajor_L, frontalisInner_R, orbicularisOris, ...) on a face "
        "from its eye and mouth loops and surface, or from marker positions; or warp another face's rig onto it.",
        function="usdface.processors.muscles:muscles", options=MusclesOptions,
        inputs=(Input("mesh", "mesh layer (from import-mesh) or mesh file", flag="--mesh"),),
        outputs=(Output("output", "rig layer to write (.usda)", metavar="RIG.usda"),),
        exclusive=((("layout", "binding"), False),)),
    Processor(
        "simulate", "simulate an expression or contraction timeline -> animation layer (.usdc)",
        "Simulate the layered mass-spring tissue model driven by the rig's muscles: an expression preset ramped "
        "from 0 to 1, or a timeline JSON ({\"rate\": 24, \"keys\": {\"zygomaticMajor_L\": [[frame, contraction], "
        "...]}}).",
        function="usdface.processors.simulate:simulate", options=SimulateOptions,
        inputs=(Input("mesh", "mesh layer or mesh file", flag="--mesh"),
                _layer("rig", "rig layer (from `usdface muscles`)")),
        outputs=(Output("output", "animation layer to write (.usdc; stands alone); X_shot.usda is written beside it",
                        metavar="ANIM.usdc"),),
        exclusive=((("expression", "timeline"), True),)),
    Processor(
        "fit-muscles", "fit muscle contractions to captured markers -> animation layer (.usdc)",
        "Fit per-frame contractions in [0, 1] (and the jaw opening) that best reproduce the captured marker motion: "
        "bounded least squares on the model's linearised response, refined by simulation; write the simulated "
        "animation.",
        function="usdface.processors.fit_muscles:fit_muscles", options=FitMusclesOptions,
        inputs=(Input("mesh", "mesh layer or mesh file", flag="--mesh"), _layer("rig", "rig layer"),
                _layer("capture", "capture layer (from import-capture)"),
                _layer("binding", "binding layer (from bind) of this capture on this mesh")),
        outputs=(Output("output", "animation layer to write (.usdc; stands alone); X_shot.usda (with the markers) "
                        "is written beside it", metavar="ANIM.usdc"),
                 Output("report", "JSON file with the fitted contractions and error statistics", flags=("--report",),
                        kind="file", required=False))),
    Processor(
        "run", "the main job: mesh + capture -> OUTDIR/shot.usda",
        "Import the mesh and the capture (stabilised), bind the markers, compute the distances and transfer the "
        "motion; OUTDIR gets mesh.usdc capture.usdc binding.usda analysis.usdc anim.usdc shot.usda summary.json.",
        function="usdface.pipeline.run:run", options=RunOptions,
        inputs=(Input("mesh", "face mesh (OBJ, PLY, ... or USD)", flag="--mesh", kind="file"),
                Input("capture", "capture (Maya ASCII, C3D, TRC, CSV, a capture layer, or a video of painted dots)",
                      flag="--capture", kind="file")),
        outputs=(Output("output", "output folder (created if missing)", kind="folder", metavar="OUTDIR"),)),
    Processor(
        "batch", "run a shot manifest (TOML) in parallel with Dask: local cores or a farm",
        "Run every shot of a TOML manifest (mesh x capture pairs, globs allowed) through the same processors as "
        "`usdface run`, in parallel with dask.distributed: on an in-process LocalCluster by default, or on a running "
        "Dask scheduler. Expensive intermediates (imported captures, distance matrices) go to a content-addressed "
        "cache shared by shots and runs. Writes a JSON summary and prints a table; exits 1 if any shot failed.",
        function="usdface.pipeline.batch:batch", options=BatchOptions,
        inputs=(Input("manifest", "shot manifest (.toml)", kind="file", metavar="MANIFEST.toml"),),
        outputs=(Output("summary", "batch summary to write (default: the manifest's, else "
                        "usdface-batch-summary.json)", flags=("--summary",), kind="file", required=False,
                        metavar="FILE.json"),
                 Output("report", "also write an HTML report of the batch (table, thumbnails, each shot's plots; "
                        "needs the 'media' extra); default: beside the batch summary, .html", flags=("--report",),
                        kind="file", required=False, metavar="FILE.html", nargs="?", const=True))),
    Processor(
        "info", "what a layer holds: prims, markers, frames, rate, units, schemas",
        "Summarise a USD layer written by usdface (or any USD file).",
        function="usdface.processors.info:info", options=NoOptions,
        inputs=(Input("file", "a USD file", metavar="FILE"),)),
    Processor(
        "check", "validate a layer (USD's validators + usdface's rules); exit 1 on errors",
        "Run UsdValidation's validators and usdface's own schema rules on a file.",
        function="usdface.processors.check:check", options=NoOptions, batch_step=True,
        inputs=(Input("file", "a USD file", metavar="FILE"),)),
    Processor(
        "preview", "software-rendered PNG of a mesh/binding/animation layer (no GPU)",
        "Render a picture of the face with regions coloured and markers drawn.",
        function="usdface.processors.preview:preview", options=PreviewOptions,
        inputs=(Input("file", "a mesh, binding, analysis, animation or shot layer", metavar="FILE"),),
        outputs=(Output("output", "PNG to write", kind="file", metavar="IMAGE.png"),)),
    Processor(
        "playblast", "render a shot to an H.264 movie (browser-playable mp4), side by side or beside its video",
        "Render every frame of a shot (or --range) with the software renderer of `usdface preview` into an H.264 mp4 "
        "(yuv420p, faststart) at the shot's rate: one movie frame per time sample, with a burn-in of shot, method, "
        "frame and timecode. --compare puts a second shot on the right (e.g. euclidean vs hybrid); --video the "
        "shot's source clip (frame k + trim). Needs the 'media' extra (PyAV).",
        function="usdface.processors.playblast:playblast", options=PlayblastOptions,
        inputs=(Input("shot", "shot stage (OUTDIR/shot.usda) or any layer with a face mesh", kind="file",
                      metavar="SHOT"),),
        outputs=(Output("output", "movie to write (.mp4)", kind="file", metavar="MOVIE.mp4"),)),
    Processor(
        "report", "a self-contained HTML QC report of a run's output folder (plots, pictures, playblast)",
        "Write one HTML file that opens offline (plotly.js inlined once) with the shot's inputs and provenance, a "
        "contact sheet, the binding, a playblast (in a sibling folder <report>_media/), and plots of marker "
        "trajectories, validity and gaps filled, stabilisation before/after, binding residual per marker, per-frame "
        "displacement range, transfer amplification and regularisation, and a blend-shape solve's curves when the "
        "folder has one. Needs the 'media' extra (plotly, PyAV).",
        function="usdface.pipeline.report:report", options=ReportOptions,
        inputs=(Input("outdir", "output folder of `usdface run` (shot.usda, capture.usdc, summary.json ...)",
                      kind="folder", metavar="OUTDIR"),),
        outputs=(Output("output", "HTML file to write", kind="file", metavar="REPORT.html"),),
        exclusive=((("playblast", "no_playblast"), False),)),
    Processor(
        "plugin-path", "print the folder to put on PXR_PLUGINPATH_NAME (for DCCs)",
        "Print the folder holding usdface's plugInfo.json. DCCs import their own pxr before any plug-in: set "
        "PXR_PLUGINPATH_NAME to this folder before starting them.",
        function="usdface.processors.plugin_path:plugin_path", options=NoOptions),
)

GROUPS = (
    CommandGroup("landmarks", "facial landmark models (train an active appearance model)", "Facial landmark tools."),
    CommandGroup("shapes", "blend-shape rigs: transfer a generic rig onto a face without one",
                 "Blend-shape rig tools."),
)
