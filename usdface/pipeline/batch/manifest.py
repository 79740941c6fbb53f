"""Shot manifests (TOML): defaults plus a list of shots, expanded and checked before any work.

::

    [batch]                      # optional: how the batch runs (command-line options override)
    cache = "cache"              # cache folder, or false for none (default: .usdface-cache)
    summary = "batch-summary.json"
    workers = 2                  # default LocalCluster size
    scheduler = "tcp://farm:8786"

    [defaults]                   # any shot key; every shot starts from these
    method = "hybrid"
    trim = [0, 200]
    output = "out/{mesh}/{capture}"

    [[shots]]                    # one entry per character (globs make many shots)
    mesh = "../meshes/makehuman_hm08_face_cm.obj"
    capture = "../capture/*MoCap.ma"
    layout = "../layouts/makehuman_hm08_face.layout.json"

Shot keys are the long options of ``usdface run`` in snake_case (``--pin-border`` is
``pin_border``; flags are booleans; ``stabilize = false`` is ``--no-stabilize``) plus
``processors`` (default ``["run"]``; ``"check"`` also validates the shot; ``"track"`` tracks a
video capture first). ``mesh``, ``capture`` and ``layout`` may be glob patterns; a shot entry
expands to every mesh x capture pair, and ``output``/``layout`` may name the pair with
``{mesh}`` and ``{capture}`` (file names without suffix). Relative paths are relative to the
manifest's folder (outputs and the cache to ``--out-root`` when given). Values are checked by
the same parser as the command line, so a manifest shot means what the command would.
"""
from __future__ import annotations

import dataclasses
import glob
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ...errors import FormatError, InputError, OptionError

def shot_steps() -> tuple:
    """The processors a shot may list: ``run`` (always runs), ``track`` (accepted: `run` tracks a
    video capture itself) and every batch step of the registry (``check``, a studio's own)."""
    from ...registry import batch_steps

    return ("track", "run") + batch_steps()

BATCH_KEYS = {"cache": (str, bool), "summary": (str,), "workers": (int,), "scheduler": (str,)}
_SHOT_ONLY = {"mesh", "capture", "output", "processors"}


@dataclass
class Shot:
    """One shot of a batch: everything needed to run it, in plain types (it travels to workers)."""

    name: str
    mesh: str
    capture: str
    output: str
    options: dict                      # run() keyword arguments (CLI-parsed)
    processors: tuple = ("run",)
    layout: str | None = None
    entry: int = 0                     # index of its [[shots]] entry
    line: int | None = None

    @property
    def is_video(self) -> bool:
        from ...io.video import is_video

        return is_video(self.capture)


@dataclass
class Manifest:
    path: Path
    shots: list
    cache: str | None
    summary: str
    workers: int | None = None
    scheduler: str | None = None
    problems: list = field(default_factory=list)


def shot_keys() -> dict:
    """{manifest key: option field} for every `usdface run` option a manifest takes (the fields of
    :class:`usdface.options.RunOptions`: a manifest key is the option's name)."""
    from ...options import RunOptions, option_fields

    return {f.name: f for f in option_fields(RunOptions)}


def key_line(text: str, table: str, index: int | None, key: str) -> int | None:
    """1-based line of ``key`` in ``[table]`` (or the ``index``-th ``[[table]]``); tomllib gives none."""
    current, count = None, -1
    pattern = re.compile(r'^\s*(?:"([^"]+)"|\'([^\']+)\'|([A-Za-z0-9_\-.]+))\s*=')
    for n, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        m = re.match(r"^\[\[\s*([^\]]+?)\s*\]\]", s)
        if m:
            current = m.group(1)
            if current == table:
                count += 1
            continue
        m = re.match(r"^\[\s*([^\]]+?)\s*\]", s)
        if m:
            current = m.group(1)
            continue
        if table is None and current is not None:
            continue
        if table is not None and current != table:
            continue
        if index is not None and count != index:
            continue
        m = pattern.match(line)
        if m and (m.group(1) or m.group(2) or m.group(3)).split(".")[0] == key:
            return n
    return None


def _header_line(text: str, table: str, index: int) -> int | None:
    count = -1
    for n, line in enumerate(text.splitlines(), 1):
        if re.match(rf"^\s*\[\[\s*{re.escape(table)}\s*\]\]", line):
            count += 1
            if count == index:
                return n
    return None


def load_manifest(path, *, out_root=None, check_files: bool = True) -> Manifest:
    """Read, validate and expand a manifest; every problem found is reported in one error.

    Raises
    ------
    FormatError
        Not TOML, unknown keys or tables (with their line), bad values.
    InputError
        Missing input files (all of them listed), unwritable output folders, clashing outputs.
    """
    from ...inputfiles import parse_toml, read_text_file

    path = Path(path)
    # a regular file (a named pipe blocked, a folder said "no such file"), bounded in size, UTF-8,
    # bounded in nesting (100000 nested [ raised RecursionError)
    text = read_text_file(path, label=f"manifest {path}", kind="TOML")
    data = parse_toml(text, where=f"manifest {path}")
    base = path.resolve().parent
    where = lambda table, index, key: _where(path, text, table, index, key)  # noqa: E731
    batch, defaults, entries = _tables(path, data, where)
    ctx = _Context(path=path, text=text, where=where, base=base, out_root=out_root,
                   out_base=Path(out_root).resolve() if out_root is not None else base)
    shots = []
    for i, entry in enumerate(entries):
        shots += _entry_shots(ctx, i, {**defaults, **entry}, entry)
    cache = batch.get("cache", ".usdface-cache")
    cache_path = None if cache is False else str(_output_path(cache, ctx.out_base))
    summary_path = str(_output_path(batch.get("summary", "usdface-batch-summary.json"), ctx.out_base))
    for key, value in (("cache", cache_path), ("summary", summary_path)):
        problem = _outside(value, out_root, ctx.out_base, f"{where('batch', None, key)}: {key} = {batch.get(key)!r}")
        if value is not None and problem:
            ctx.problems.append(problem)
    _raise_problems(ctx, check_files)
    shots = _unique_names(shots, ctx.out_base)
    _check_outputs(path, shots, cache_path, summary_path)
    return Manifest(path=path, shots=shots, cache=cache_path, summary=summary_path,
                    workers=batch.get("workers"), scheduler=batch.get("scheduler"))


@dataclass
class _Context:
    """What expanding a manifest's entries needs, and the problems found so far."""

    path: Path
    text: str
    where: object
    base: Path
    out_root: object
    out_base: Path
    problems: list = field(default_factory=list)
    missing: list = field(default_factory=list)


def _tables(path: Path, data: dict, where) -> tuple[dict, dict, list]:
    """([batch], [defaults], [[shots]]), their keys checked (FormatError naming every bad one)."""
    problems = []
    for key in data:
        if key not in ("batch", "defaults", "shots"):
            problems.append(f"{where(None, None, key)}: unknown key or table {key!r}; a manifest has [batch], "
                            "[defaults] and [[shots]]")
    batch = data.get("batch", {})
    defaults = data.get("defaults", {})
    entries = data.get("shots", [])
    if not isinstance(batch, dict) or not isinstance(defaults, dict):
        raise FormatError(f"manifest {path}: [batch] and [defaults] must be tables")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise FormatError(f"manifest {path}: expected at least one [[shots]] table")
    for key, value in batch.items():
        if key not in BATCH_KEYS:
            problems.append(f"{where('batch', None, key)}: unknown key {key!r} in [batch]; expected "
                            f"{', '.join(BATCH_KEYS)}")
        elif not isinstance(value, BATCH_KEYS[key]) or (key == "cache" and value is True):
            problems.append(f"{where('batch', None, key)}: {key} = {value!r} has the wrong type")
    valid_keys = set(shot_keys()) | _SHOT_ONLY
    hint = "; expected the long options of `usdface run` in snake_case: " + ", ".join(sorted(valid_keys))
    for key in defaults:
        if key not in valid_keys:
            problems.append(f"{where('defaults', None, key)}: unknown key {key!r}{_suggest(key, valid_keys)}{hint}")
    for i, entry in enumerate(entries):
        for key in entry:
            if key not in valid_keys:
                problems.append(f"{where('shots', i, key)}: unknown key {key!r} in shot entry {i + 1}"
                                f"{_suggest(key, valid_keys)}{hint}")
    if problems:
        raise FormatError("\n".join(problems))
    return batch, defaults, entries


def _entry_shots(ctx: _Context, i: int, merged: dict, entry: dict) -> list:
    """The shots of ``[[shots]]`` entry ``i`` (every mesh x capture its globs match); problems and
    missing files go to ``ctx``."""
    path, where = ctx.path, ctx.where
    line = _header_line(ctx.text, "shots", i)
    label = f"manifest {path} line {line}" if line else f"manifest {path} shot entry {i + 1}"
    for req in ("mesh", "capture", "output"):
        if req not in merged:
            ctx.problems.append(f"{label}: shot entry {i + 1} has no {req!r}")
    if "layout" not in merged and not merged.get("auto"):
        ctx.problems.append(f"{label}: shot entry {i + 1} needs a layout or auto = true")
    if ctx.problems:
        return []
    processors = merged.get("processors", ["run"])
    if isinstance(processors, str):
        processors = [processors]
    known = shot_steps()
    bad = [p for p in processors if p not in known]
    if bad or "run" not in processors:
        ctx.problems.append(f"{where('shots', i, 'processors') if 'processors' in entry else label}: processors "
                            f"{processors!r}: expected a list of {', '.join(known)} including 'run'")
        return []
    shots = []
    meshes = _expand(merged["mesh"], ctx.base, "mesh", label, ctx.missing)
    captures = _expand(merged["capture"], ctx.base, "capture", label, ctx.missing)
    for mesh in meshes:
        for capture in captures:
            shot = _shot(ctx, i, merged, entry, (mesh, capture, label, line))
            if shot is not None:
                shots.append(dataclasses.replace(shot, processors=tuple(p for p in known if p in processors)))
    return shots


def _shot(ctx: _Context, i: int, merged: dict, entry: dict, what: tuple) -> Shot | None:
    """One mesh x capture pair of entry ``i`` as a Shot (None, with the problem in ``ctx``)."""
    mesh, capture, label, line = what
    names = {"mesh": Path(mesh).stem, "capture": Path(capture).stem}
    try:
        output = str(_output_path(str(merged["output"]).format(**names), ctx.out_base))
        layout = None
        if merged.get("layout") is not None:
            found = _expand(str(merged["layout"]).format(**names), ctx.base, "layout", label, ctx.missing)
            layout = found[0] if found else None
    except (KeyError, IndexError, ValueError) as exc:
        ctx.problems.append(f"{label}: bad placeholder {exc} (use {{mesh}} and {{capture}})")
        return None
    options = _parse_options(merged, shot_keys(), mesh, capture, layout, output, ctx.where, i, entry, ctx.problems)
    if options is None:
        return None
    if isinstance(options.get("stiffness"), str):  # a JSON file of widths
        st = _resolve(options["stiffness"], ctx.base)
        if not st.is_file():
            ctx.missing.append(f"{label}: stiffness {st}")
        options["stiffness"] = str(st)
    if options.get("seeds"):  # a video's seed points, relative to the manifest like the rest
        sd = _resolve(options["seeds"], ctx.base)
        if not sd.is_file():
            ctx.missing.append(f"{label}: seeds {sd}")
        options["seeds"] = str(sd)
    loc = ctx.where(*(("shots", i) if "output" in entry else ("defaults", None)), "output")
    problem = _outside(output, ctx.out_root, ctx.out_base, f"{loc}: output = {merged['output']!r}")
    if problem:
        ctx.problems.append(problem)
        return None
    return Shot(name=f"{names['mesh']}/{names['capture']}", mesh=mesh, capture=capture, output=output,
                options=options, layout=layout, entry=i, line=line)


def _raise_problems(ctx: _Context, check_files: bool) -> None:
    """One InputError listing every problem (missing files first)."""
    missing = list(dict.fromkeys(ctx.missing))
    problems = list(dict.fromkeys(ctx.problems))  # a shot entry expands to many shots: report once
    if missing and check_files:
        problems.insert(0, f"{len(missing)} input file(s) not found:\n  " + "\n  ".join(missing))
    if problems:
        raise InputError(f"manifest {ctx.path}:\n" + "\n".join(problems) if len(problems) > 1 or missing
                         else problems[0])


def _check_outputs(path: Path, shots: list, cache_path, summary_path) -> None:
    """Outputs that clash, overwrite an input, or cannot be written: an InputError before any work."""
    clashes = _clashes(shots, cache_path, summary_path)
    if clashes:
        raise InputError(f"manifest {path}: shots share an output folder (name outputs with {{mesh}} and "
                         "{capture}):\n  " + "\n  ".join(clashes))
    overwrites = _inputs_overwritten(shots, path)
    if overwrites:
        raise InputError(f"manifest {path}: a shot would overwrite its own inputs:\n  " + "\n  ".join(overwrites))
    # the summary and the cache never replace what any shot (or the batch) reads
    check_batch_outputs(path, shots, {"summary": summary_path, "cache": cache_path})
    unwritable = _unwritable([s.output for s in shots])
    if cache_path:
        unwritable += _unwritable([cache_path], what="cache folder")
    if unwritable:
        raise InputError(f"manifest {path}: cannot write:\n  " + "\n  ".join(unwritable))


def _parse_options(merged, allowed, mesh, capture, layout, output, where, i, entry, problems) -> dict | None:
    """The shot's :class:`RunOptions` as a plain dict (it travels to workers), checked by the
    options object itself, as the command line's values are."""
    from ...options import RunOptions

    values = {k: v for k, v in merged.items() if k not in _SHOT_ONLY}
    values["layout"] = layout
    try:
        options = RunOptions.from_mapping(values, what="shot")
    except OptionError as exc:
        culprit = _culprit(str(exc), merged)
        loc = where(*(("shots", i) if culprit in entry else ("defaults", None)), culprit) if culprit else \
            f"shot entry {i + 1}"
        problems.append(f"{loc}: {exc}")
        return None
    return options.to_dict()


def _culprit(message: str, merged: dict) -> str | None:
    """The manifest key an option error is about (the error names the command-line flag)."""
    m = re.search(r"(--[a-z][a-z0-9-]*)", message)
    if m:
        flags = {f.metadata["flag"]: name for name, f in shot_keys().items()}
        flags.update({f.metadata["negate"]: name for name, f in shot_keys().items() if f.metadata["negate"]})
        key = flags.get(m.group(1))
        return key if key in merged else None
    return None


def _where(path, text, table, index, key) -> str:
    n = key_line(text, table, index, key)
    return f"manifest {path} line {n}" if n else f"manifest {path}"


def _suggest(key, valid) -> str:
    import difflib

    close = difflib.get_close_matches(key, sorted(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _is_number(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


def _resolve(p, base: Path) -> Path:
    p = Path(os.path.expanduser(str(p)))
    return Path(os.path.normpath(p if p.is_absolute() else base / p))


def _output_path(p, base: Path) -> Path:
    """Where an output really goes: absolute, ``..`` folded, symbolic links followed, so one folder
    has one name (``x/../same`` is ``same``)."""
    return Path(os.path.realpath(_resolve(p, base)))


def _outside(path, out_root, out_base: Path, what: str) -> str | None:
    """The problem when ``--out-root`` is given and ``path`` resolves outside it (else None)."""
    if out_root is None or path is None:
        return None
    root = Path(os.path.realpath(out_base))
    p = Path(path)
    if p == root or root in p.parents:
        return None
    return (f"{what} resolves to {p}, outside --out-root {root}; with --out-root, outputs, the cache and the "
            "summary stay inside it")


def _unique_names(shots: list, out_base: Path) -> list:
    """Shots of one mesh and capture (windows of a take, two methods) are told apart by their output
    folder: ``mesh/capture (out/mesh/capture_w0040)``. A shot's name keys its record in the summary."""
    from collections import Counter

    count = Counter(s.name for s in shots)
    # shots that also share their folder clash; the clash names their captures instead (_clashes)
    same_folder = Counter((s.name, s.output) for s in shots)
    return [dataclasses.replace(s, name=f"{s.name} ({os.path.relpath(s.output, out_base)})")
            if count[s.name] > 1 and same_folder[s.name, s.output] == 1 else s for s in shots]


def _clashes(shots, cache_path, summary_path) -> list[str]:
    """Shots writing one folder, or a shot folder that holds (or is inside) the cache or the summary."""
    clashes, seen = [], {}
    for s in shots:
        if s.output in seen:
            other = seen[s.output]
            # shots named alike (jaw200.csv and jaw200.trc): say which files they are
            a, b = (s.name, other.name) if s.name != other.name else \
                (f"{s.name} ({Path(s.capture).name})", f"{other.name} ({Path(other.capture).name})")
            clashes.append(f"{a} and {b} both write {s.output}")
        seen[s.output] = s
    for s in shots:
        out = Path(s.output)
        if cache_path and (Path(cache_path) == out or out in Path(cache_path).parents or Path(cache_path) in out.parents):
            clashes.append(f"{s.name} writes {out}, which overlaps the cache folder {cache_path}")
        if Path(summary_path).parent == out:
            clashes.append(f"{s.name} writes {out}, the folder of the batch summary {summary_path}")
    return clashes


def shot_inputs(shot: Shot) -> dict:
    """{label: path} of the files a shot reads (mesh, capture, layout, seeds, a stiffness JSON)."""
    stiffness = shot.options.get("stiffness")
    return {"mesh": shot.mesh, "capture": shot.capture, "layout": shot.layout, "seeds": shot.options.get("seeds"),
            "stiffness": stiffness if isinstance(stiffness, str) and os.path.isfile(stiffness) else None}


def _inputs_overwritten(shots, manifest_path) -> list[str]:
    """Shots whose output files (what `usdface run` writes into their folder) are an input of any
    shot of the batch, or the manifest."""
    from ...fileutil import same_file_problems
    from ...io.video import is_video
    from ...options import RunOptions
    from ..run import output_files

    inputs = batch_inputs(manifest_path, shots)
    found = []
    for s in shots:
        files = output_files(s.options.get("output_kind") or ("points",), video=is_video(s.capture),
                             options=RunOptions.from_mapping(s.options))
        outputs = [("output", Path(s.output))] + [("output", Path(s.output) / f) for f in files]
        found += [f"{s.name}: {p}" for p in same_file_problems(outputs, inputs)]
    return found


def batch_inputs(manifest_path, shots) -> dict:
    """Every file a batch reads: the manifest itself and each shot's inputs, with the files its USD
    inputs compose; ``{label: [paths]}``."""
    from ...usd.layers import composed_files

    inputs: dict = {"the manifest": [str(manifest_path)]}
    for s in shots:
        for role, path in shot_inputs(s).items():
            if path is None:
                continue
            label = f"{role} of shot {s.name}"
            inputs.setdefault(label, []).append(path)
            for dep in composed_files(path):
                inputs.setdefault(f"a file composed by {label}", []).append(dep)
    return inputs


def check_batch_outputs(manifest_path, shots, outputs: dict) -> None:
    """Refuse (InputError, before any work) a batch file (summary, report, cache folder) that is
    any input of any shot or the manifest itself: the batch would replace what its shots read.

    ``outputs``: ``{label: path}`` (``None`` skipped), e.g. ``{"summary": ..., "report": ...}``.
    """
    from ...fileutil import same_file_problems

    problems = same_file_problems({k: v for k, v in outputs.items() if v is not None},
                                  batch_inputs(manifest_path, shots))
    if problems:
        raise InputError(f"manifest {manifest_path}: " + "; ".join(problems))


def _expand(pattern, base: Path, what: str, label: str, missing: list) -> list[str]:
    full = _resolve(pattern, base)
    if glob.has_magic(str(pattern)):
        found = sorted(glob.glob(str(full)))
        if not found:
            missing.append(f"{label}: {what} pattern {full} matches no file")
        return found
    if not full.is_file():
        missing.append(f"{label}: {what} {full}")
    return [str(full)]


def _unwritable(paths, what="output folder") -> list[str]:
    """Folders that cannot be created or written (the nearest existing ancestor is probed)."""
    bad = []
    for p in dict.fromkeys(paths):
        q = Path(p)
        while not q.exists():
            q = q.parent
        if not q.is_dir():
            bad.append(f"{what} {p}: {q} is not a folder")
        elif not _writable(q):
            bad.append(f"{what} {p}: {q} is read-only")
    return bad


def _writable(folder: Path) -> bool:
    if not os.access(folder, os.W_OK):
        return False
    try:  # root passes os.access everywhere; a read-only file system does not take a file
        fd, name = __import__("tempfile").mkstemp(prefix=".usdface-probe-", dir=folder)
    except OSError:
        return False
    os.close(fd)
    os.unlink(name)
    return True
