"""usdface's Python API: every command of the `usdface` tool as a function of the same name.

``usdface import-capture`` is :func:`import_capture`, ``usdface landmarks train`` is
:func:`landmarks_train`, ``usdface plugin-path`` is :func:`plugin_path`; a processor another
package registers (:mod:`usdface.registry`) appears here too. Each function takes

- the command's inputs, positionally in the command's order or by name: where the command reads
  USD, a file path, an ``Sdf.Layer`` or a ``Usd.Stage`` (a DCC's open scene, or a stage composing
  the mesh, the capture and what earlier steps authored); a later USD input defaults to the first
  one (``api.transfer(stage)``: one stage holds mesh, capture, binding and analysis);
- ``options``: the command's options object (:mod:`usdface.options`, e.g. :class:`TransferOptions`),
  a dict of its fields, or an object sharing fields with it (a :class:`RunOptions`);
- its outputs by name (``output=`` a path, ``csv=``, ``preview=``...). A USD output may instead be
  authored in memory: ``into=`` an ``Sdf.Layer`` or a ``Usd.Stage`` (its edit target's layer);
  with neither, a new anonymous layer. Nothing touches the disk unless you pass a path.

and returns a :class:`Result`: ``.layers`` (the layers written: in-memory layers, or file paths),
``.files`` (other files), ``.summary`` (what ``usdface COMMAND --json`` prints), ``.text`` (what it
prints) and ``.exit_code``. A processor's opinions are merged into ``into`` only when it succeeds:
an error raises :class:`UsdFaceError` (naming the prim, marker, file or option at fault) and leaves
``into`` exactly as it was. A wrong type or an unknown option raises :class:`OptionError` naming it.

Example — the main job in memory, then on files (``out`` is a folder of your choice)::

    from usdface import api
    from usdface.options import CaptureOptions, DistanceOptions, RunOptions

    mesh = api.import_mesh("sample_assets/meshes/makehuman_hm08_face_cm.obj").layer
    capture = api.import_capture("sample_assets/capture/JawMoCap.ma",
                                 CaptureOptions(stabilize="auto", trim=(0, 300))).layer
    stage = api.new_stage(mesh)                  # in memory: the mesh's units, up axis, default prim
    api.bind(stage, capture, {"layout": "sample_assets/layouts/makehuman_hm08_face.layout.json"}, into=stage)
    api.distances(stage, options=DistanceOptions(method="hybrid"), into=stage)
    anim = api.transfer(stage, into=stage)       # points authored into the stage's edit target

    api.run("face.obj", "take.ma", RunOptions(layout="face.layout.json"), output=f"{out}/jaw")

Inside a DCC: usdface needs usd-core's ``pxr`` or a DCC's own USD build of a compatible version,
with usdface's schemas registered before the first stage is opened (``PXR_PLUGINPATH_NAME`` set
to ``usdface plugin-path``; see the README's DCC section for what works in Blender's Python).
"""
from __future__ import annotations

import inspect
import os
import warnings

from . import registry
from .errors import OptionError
from .options import (Options)
from .registry import Result

#: what this module exports besides one function per command (tested: ``__all__`` is these and
#: the commands, nothing else)
OTHER_EXPORTS = ("Result", "UsdFaceError", "OptionError", "new_stage", "evaluator", "CaptureOptions", "BindOptions",
                 "DistanceOptions", "TransferOptions", "SkelOptions", "SolveOptions", "RunOptions", "PlayblastOptions")

#: keywords of usdface 0.2's API functions that are options now: {function: {keyword: option field}}
_LEGACY_KEYWORDS = {
    "import_mesh": {"units": "units", "up_axis": "up_axis"},
    "bind": {"layout": "layout", "auto": "auto"},
    "transfer": {"method": "method", "head_motion": "head_motion"},
    "skel": {"method": "method", "head_motion": "head_motion", "transfer_options": None},
    "report": {"playblast": None},
}
#: keywords of usdface 0.2 renamed: {function: {old: new}}
_LEGACY_NAMES = {"run": {"out_dir": "output"}}
#: usdface 0.2 returned a dict (the summary) or a list (check's findings) from these
_LEGACY_RETURNS = ("run", "solve", "playblast", "report")  # (check sets its findings itself)


def new_stage(*layers):
    """An in-memory stage composing ``layers`` (strongest first, as sublayers) that carries the
    metadata usdface needs and a bare stage lacks (root-layer metadata is not inherited from
    sublayers): the first layer's units, up axis and default prim, and the rate and time range of
    the first layer that has them."""
    from .usd.layers import new_stage as make

    return make(layers)


def evaluator(source, *, mesh: str | None = None):
    """The animated face of any deliverable (file path, layer or stage): a
    :class:`usdface.usd.face_evaluator.FaceEvaluator` giving world- or mesh-space points at any time
    code, whatever moves the face (point caches, UsdSkel skinning and blend shapes, the head
    motion on /Face)::

        ev = api.evaluator("out/jaw/shot_skel.usda")
        points = ev.points(441)                   # (N, 3), world space, the stage's units
    """
    from .usd.face_evaluator import FaceEvaluator
    from .usd.layers import describe, open_stage

    return FaceEvaluator(open_stage(source, what="file"), mesh=mesh, source=describe(source))


# -- one function per command ----------------------------------------------------------------------

def _options(processor, value):
    cls = processor.options
    if value is None:
        return cls()
    if isinstance(value, dict):
        return cls.from_mapping(value, what=f"{processor.api_name} options")
    if isinstance(value, Options):
        return cls.from_other(value)
    raise OptionError(f"{processor.api_name}: options: expected a {cls.__name__} (usdface.options) or a dict of its "
                      f"fields; got {type(value).__name__}")


def _check_input(processor, name: str, value) -> None:
    from .usd.layers import is_in_memory

    i = processor.input(name)
    ok = isinstance(value, (str, os.PathLike)) or (i.kind == "usd" and is_in_memory(value)) or \
        (i.kind == "files" and isinstance(value, (list, tuple)) and all(isinstance(v, (str, os.PathLike))
                                                                        for v in value))
    if not ok:
        what = {"usd": "a file path, an Sdf.Layer or a Usd.Stage", "files": "a list of file paths"}.get(
            i.kind, "a file path")
        raise OptionError(f"{processor.api_name}: {name}: expected {what}; got {type(value).__name__}")


def _legacy(processor, args: list, kwargs: dict) -> tuple[list, dict]:
    """usdface 0.2's calls (options where an input goes now, old keywords): mapped, with a
    DeprecationWarning, for one minor version."""
    name = processor.api_name
    notes = []
    n_in = len(_positional(processor))
    for k, v in enumerate(args[:n_in]):
        if isinstance(v, (Options, dict)) and "options" not in kwargs:
            kwargs["options"] = v
            args = args[:k] + [None] * (n_in - k) + args[k + 1:n_in]
            notes.append("options as a positional argument after the first input")
            break
    if len(args) > n_in and not isinstance(args[n_in], (Options, dict, type(None))):
        path_outputs = [o.name for o in processor.outputs if o.required]
        if path_outputs:
            kwargs.setdefault(path_outputs[0], args.pop(n_in))
            notes.append(f"the output as a positional argument (give {path_outputs[0]}=)")
    for old, new in _LEGACY_NAMES.get(name, {}).items():
        if old in kwargs and old != new:
            kwargs[new] = kwargs.pop(old)
            notes.append(f"{old}= (now {new}=)")
    moved = {k: kwargs.pop(k) for k in list(kwargs) if k in _LEGACY_KEYWORDS.get(name, {})}
    if moved:
        notes.append(", ".join(f"{k}=" for k in moved) + " (now fields of the options)")
        opts = _options(processor, kwargs.pop("options", None) if "options" in kwargs else None)
        changes = {}
        for k, v in moved.items():
            field = _LEGACY_KEYWORDS[name][k]
            if field is not None:
                changes[field] = v
            elif k == "transfer_options" and v is not None:
                changes.update({f: getattr(v, f) for f in v.to_dict() if hasattr(opts, f)})
            elif k == "playblast":
                changes.update({"no_playblast": True} if v is False else {} if v is True else {"playblast": str(v)})
        kwargs["options"] = opts.replace(**changes)
    if notes:
        warnings.warn(f"usdface.api.{name}: " + "; ".join(notes) + " is deprecated since usdface 0.3 and goes in "
                      f"0.4; call {name}({', '.join(i.name for i in processor.inputs)}, options=..., "
                      f"{', '.join(o.name + '=...' for o in processor.outputs)})", DeprecationWarning, stacklevel=4)
    return args, kwargs


def _call(processor, args, kwargs) -> Result:
    """Bind, check and default the arguments, run the processor, return its Result."""
    from .usd.layers import is_in_memory, new_anonymous_layer, target_layer

    args, kwargs = _legacy(processor, list(args), dict(kwargs))
    names = _positional(processor)
    if len(args) > len(names) + 1:
        raise OptionError(f"{processor.api_name}: takes {len(names)} input(s) ({', '.join(names)}) and options; "
                          f"got {len(args)} positional arguments")
    values = dict(zip(names + ["options"], args))
    names = [i.name for i in processor.inputs]
    for k, v in kwargs.items():
        if k in values and values[k] is not None:
            raise OptionError(f"{processor.api_name}: {k} given twice")
        values[k] = v
    extra = {o.name for o in processor.outputs}
    if any(o.kind == "usd" for o in processor.outputs):
        extra.add("into")
    if processor.name == "run":
        extra.add("cache")  # usdface 0.2's api.run(..., cache=): a batch's content cache
    unknown = [k for k in values if k not in names and k != "options" and k not in extra]
    if unknown:
        fields = ", ".join(f.name for f in processor.options.__dataclass_fields__.values())
        raise OptionError(f"{processor.api_name}: unknown argument {unknown[0]!r}; options go in "
                          f"options={processor.options.__name__}(...)" + (f" ({fields})" if fields else ""))
    options = _options(processor, values.pop("options", None))
    inputs = []
    for i in processor.inputs:
        v = values.pop(i.name, None)
        if v is None and i.default_from is not None:
            v = dict(zip(names, inputs)).get(i.default_from)
        if v is None and i.required:
            raise OptionError(f"{processor.api_name}: {i.name}: missing (the {i.help})")
        if v is not None:
            _check_input(processor, i.name, v)
        inputs.append(v)
    into = values.pop("into", None)
    outputs = {k: v for k, v in values.items() if v is not None}
    usd_out = next((o for o in processor.outputs if o.kind == "usd"), None)
    if into is not None:
        if usd_out is None or not is_in_memory(into):
            raise OptionError(f"{processor.api_name}: into: expected an Sdf.Layer or a Usd.Stage to author into")
        if usd_out.name in outputs:
            raise OptionError(f"{processor.api_name}: give {usd_out.name}= (a file) or into= (in memory), not both")
        outputs[usd_out.name] = into
    elif usd_out is not None and usd_out.required and usd_out.name not in outputs:
        outputs[usd_out.name] = new_anonymous_layer(f"{usd_out.name}.usda")
    for o in processor.outputs:
        if o.required and o.name not in outputs:
            raise OptionError(f"{processor.api_name}: {o.name}: missing (the {o.help})")
    result = registry.call(processor.name, *inputs, options=options, **outputs)
    for name, value in list(result.layers.items()):
        if is_in_memory(value):
            result.layers[name] = target_layer(value)
    if processor.api_name in _LEGACY_RETURNS and result.legacy is None:
        result.legacy = result.summary
    return result


def _positional(processor) -> list[str]:
    """The inputs the API takes positionally, in order (then ``options``)."""
    return [i.name for i in processor.inputs if i.positional]


def _signature(processor) -> inspect.Signature:
    P = inspect.Parameter
    params, seen_default = [], False
    for i in processor.inputs:
        if not i.positional:
            continue
        optional = not i.required or i.default_from is not None
        seen_default = seen_default or optional
        params.append(P(i.name, P.POSITIONAL_OR_KEYWORD, default=None if seen_default else P.empty))
    params.append(P("options", P.POSITIONAL_OR_KEYWORD, default=None))
    params += [P(i.name, P.KEYWORD_ONLY, default=None) for i in processor.inputs if not i.positional]
    params += [P(o.name, P.KEYWORD_ONLY, default=None) for o in processor.outputs]
    if any(o.kind == "usd" for o in processor.outputs):
        params.append(P("into", P.KEYWORD_ONLY, default=None))
    return inspect.Signature(params, return_annotation="Result")


def _docstring(processor) -> str:
    lines = [f"{processor.summary[0].upper()}{processor.summary[1:]} (``usdface {processor.name}``).", "",
             processor.description, "", "Parameters", "----------"]
    for i in processor.inputs:
        kind = {"usd": "path, Sdf.Layer or Usd.Stage", "files": "list of paths"}.get(i.kind, "path")
        extra = f"; default: ``{i.default_from}``" if i.default_from else "" if i.required else ", optional"
        lines += [f"{i.name} : {kind}{extra}", f"    {i.help}"]
    lines += [f"options : usdface.options.{processor.options.__name__}, dict, optional",
              "    The command's options (its flags, by field name)."]
    for o in processor.outputs:
        kind = "path" if o.kind != "usd" else "path, optional (or ``into``)"
        lines += [f"{o.name} : {kind}", f"    {o.help}"]
    if any(o.kind == "usd" for o in processor.outputs):
        lines += ["into : Sdf.Layer or Usd.Stage, optional",
                  "    Author the output here, in memory (default: a new anonymous layer)."]
    lines += ["", "Returns", "-------", "Result"]
    return "\n".join(lines)


def _make(processor):
    def command(*args, **kwargs) -> Result:
        return _call(processor, args, kwargs)

    command.__name__ = command.__qualname__ = processor.api_name
    command.__module__ = __name__
    command.__signature__ = _signature(processor)
    command.__doc__ = _docstring(processor)
    command.processor = processor
    return command


def commands() -> list[str]:
    """The API's command functions: one per command of the registry."""
    return [p.api_name for p in registry.commands()]


_functions: dict = {}


def __getattr__(name: str):
    # looked up in the registry at each access (a processor registered later appears, one removed
    # goes); one function object per processor
    try:
        processor = registry.find(name)
    except OptionError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    if not processor.command or processor.api_name != name:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    fn = _functions.get(id(processor))
    if fn is None or fn.processor is not processor:
        fn = _functions[id(processor)] = _make(processor)
    return fn


def __dir__():
    return sorted(set(globals()) | set(commands()))


__all__ = list(OTHER_EXPORTS) + commands()