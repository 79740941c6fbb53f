"""Maya ASCII statements: a scene of nodes (with their static attributes and key blocks), parents
and connections, parsed in one regex pass; what :mod:`usdface.io.maya_ascii` reads marker motion
from."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..errors import FormatError, list_names

__all__ = ["Node", "Scene", "parse_statements", "split_plug", "DAG_XFORM_TYPES", "XFORM_ATTRS"]


# A statement starts at a line start with a command word. Maya indents continuation lines, and
# their only possible leading words are boolean values, which are excluded.
_STATEMENT_START = re.compile(r"\n[ \t]*(?!(?:yes|no|on|off|true|false)\b)([A-Za-z_]\w*)")


_QUOTED = re.compile(r'"((?:[^"\\\n]|\\.)*)"')


_NODE_TYPE = re.compile(r"\s*(\w+)")


_NAME_FLAG = re.compile(r'-n(?:ame)?\s+"([^"]*)"')


_PARENT_FLAG = re.compile(r'-p(?:arent)?\s+"([^"]*)"')


_SIZE_FLAG = re.compile(r"-s(?:ize)?\s+(\d+)")


_SELECT_NAME = re.compile(r'-ne\s+"?([^";\s]+)"?')


_INDEX = re.compile(r"\[(\d+)(?::(\d+))?\]$")


_TYPE_FLAG = re.compile(r'^\s*-type\s+"[^"]*"')


_LINEAR_FLAG = re.compile(r"-l(?:inear)?\s+\"?(\w+)")


_ANGLE_FLAG = re.compile(r"-a(?:ngle)?\s+\"?(\w+)")


_TIME_FLAG = re.compile(r"-t(?:ime)?\s+\"?([\w.]+)")


_KEY_ATTRS = (".ktv", ".keyTimeValue")


# attribute spellings -> canonical short name, for the transform attributes that place a point
XFORM_ATTRS = {}


DAG_XFORM_TYPES = ("transform", "joint")


@dataclass
class Node:
    kind: str
    name: str
    path: str
    pos: int                                          # text position of its createNode
    parent: "Node | None" = None
    static: dict = field(default_factory=dict)       # canonical attr -> list of floats
    key_blocks: list = field(default_factory=list)   # (first, last, value_start, value_end, line)
    declared_keys: int | None = None


@dataclass
class Scene:
    """What the reader keeps from a Maya ASCII file."""

    source: str
    text: str
    nodes: list = field(default_factory=list)
    by_name: dict = field(default_factory=dict)      # short name -> [nodes]
    by_path: dict = field(default_factory=dict)      # DAG path -> node
    connections: list = field(default_factory=list)  # (src, dst, line)
    linear_unit: str = "centimeter"
    angle_unit: str = "degree"
    time_unit: str = "film"
    drivers: dict | None = None                      # built by _driver_index

    def line_of(self, pos: int) -> int:
        return self.text.count("\n", 0, pos) + 1

    def error(self, line: int | None, message: str) -> FormatError:
        where = f"{self.source}, line {line}" if line else self.source
        return FormatError(f"{where}: {message}")

    def find(self, name: str, pos: int) -> Node | None:
        """Resolve a node name as Maya writes it: short name, partial or full DAG path.
        ``pos`` (text position of the statement) is only used for the error message."""
        if name.startswith("|"):
            return self.by_path.get(name)
        short = name.rsplit("|", 1)[-1]
        candidates = self.by_name.get(short, [])
        if "|" in name:
            candidates = [n for n in candidates if n.path.endswith("|" + name)]
        if len(candidates) > 1:
            raise self.error(self.line_of(pos), f"node name {name!r} is ambiguous: {list_names(n.path for n in candidates)}")
        return candidates[0] if candidates else None


def parse_statements(text: str, source: str) -> Scene:
    """One pass over the statements, keeping nodes, static transform values, key block spans,
    connections and units. Key numbers are NOT converted here."""
    scene = Scene(source=source, text=text)
    if not text.startswith("//Maya ASCII"):
        raise scene.error(1, "not a Maya ASCII file (the first line must start with '//Maya ASCII')")
    starts = [(m.start() + 1, m.end(), m.group(1)) for m in _STATEMENT_START.finditer(text)]
    ends = [s for s, _, _ in starts[1:]] + [len(text)]
    current: Node | None = None
    for (stmt_start, args_start, command), end in zip(starts, ends):
        if not _is_terminated(text, args_start, end):
            line = scene.line_of(stmt_start)
            head = text[stmt_start:min(end, stmt_start + 60)].split("\n", 1)[0]
            raise scene.error(line, f"statement '{head.strip()}...' is not terminated by ';': "
                                    f"the file is truncated or malformed")
        if command == "setAttr":
            if current is not None:
                _set_attr(scene, current, args_start, end, stmt_start)
        elif command == "createNode":
            current = _create_node(scene, text[args_start:end], stmt_start)
        elif command == "connectAttr":
            names = _QUOTED.findall(text, args_start, end)
            if len(names) >= 2:
                scene.connections.append((names[0], names[1], stmt_start))
        elif command == "select":
            m = _SELECT_NAME.search(text, args_start, end)
            current = scene.find(m.group(1), stmt_start) if m else None
        elif command == "currentUnit":
            args = text[args_start:end]
            for regex, attr in ((_LINEAR_FLAG, "linear_unit"), (_ANGLE_FLAG, "angle_unit"), (_TIME_FLAG, "time_unit")):
                m = regex.search(args)
                if m:
                    setattr(scene, attr, m.group(1))
    _check_footer(scene)  # after the loop, so that a cut statement is reported as such
    return scene


def _check_footer(scene: Scene) -> None:
    tail = scene.text[-4096:].rstrip()
    last_line = tail.rsplit("\n", 1)[-1].strip()
    if not last_line.startswith("// End of"):
        raise scene.error(
            scene.line_of(len(scene.text.rstrip())),
            "the file does not end with Maya's '// End of <name>.ma' line: it is truncated "
            "(or was not written completely)",
        )


def _is_terminated(text: str, start: int, end: int) -> bool:
    """True if the statement text[start:end] ends with ';' (ignoring trailing comment lines)."""
    j = end
    while j > start and text[j - 1] in " \t\r\n":
        j -= 1
    if j > start and text[j - 1] == ";":
        return True
    lines = text[start:end].split("\n")
    while lines and (not lines[-1].strip() or lines[-1].lstrip().startswith("//")):
        lines.pop()
    return bool(lines) and lines[-1].rstrip().endswith(";")


def _create_node(scene: Scene, args: str, pos: int) -> Node:
    kind = _NODE_TYPE.match(args)
    name = _NAME_FLAG.search(args)
    if not kind or not name:
        raise scene.error(scene.line_of(pos), f"createNode without a type and -n name: {args.strip()[:60]!r}")
    parent_match = _PARENT_FLAG.search(args)
    parent = None
    if parent_match:
        parent = scene.find(parent_match.group(1), pos)
        if parent is None:
            raise scene.error(scene.line_of(pos), f"parent {parent_match.group(1)!r} of node {name.group(1)!r} is not defined before it")
        path = parent.path + "|" + name.group(1)
    else:
        path = "|" + name.group(1)
    node = Node(kind=kind.group(1), name=name.group(1), path=path, pos=pos, parent=parent)
    scene.nodes.append(node)
    scene.by_name.setdefault(node.name, []).append(node)
    if node.kind in DAG_XFORM_TYPES or parent is not None:
        scene.by_path[path] = node
    return node


def _set_attr(scene: Scene, node: Node, start: int, end: int, pos: int) -> None:
    text = scene.text
    q1 = text.find('"', start, end)
    q2 = text.find('"', q1 + 1, end) if q1 >= 0 else -1
    if q2 < 0:
        return  # setAttr without a quoted attribute: nothing usdface reads
    attr = text[q1 + 1:q2]
    if not attr.startswith("."):
        # "node.attr": an attribute of a named node rather than of the current one
        node_name, _, rest = attr.partition(".")
        node = scene.find(node_name, pos)
        if node is None:
            return
        attr = "." + rest
    if node.kind.startswith("animCurve") and attr.startswith(_KEY_ATTRS):
        size = _SIZE_FLAG.search(text, start, q1)
        if size:
            node.declared_keys = int(size.group(1))
        index = _INDEX.search(attr)
        if index is None:
            return
        first = int(index.group(1))
        last = int(index.group(2)) if index.group(2) is not None else first
        semi = text.find(";", q2 + 1, end)
        if last < first:
            raise scene.error(scene.line_of(pos), f"curve {node.name!r}: key range {attr} is empty")
        trailing = text[semi + 1:end].strip()
        if trailing and not trailing.startswith("//"):
            raise scene.error(scene.line_of(semi + 1), f"unexpected text after the key block of curve {node.name!r}: {trailing[:40]!r}")
        node.key_blocks.append((first, last, q2 + 1, semi, pos))
        return
    canonical = XFORM_ATTRS.get(attr[1:])
    if canonical is None or node.kind not in DAG_XFORM_TYPES:
        return
    semi = text.find(";", q2 + 1, end)
    value_text = _TYPE_FLAG.sub("", text[q2 + 1:semi])
    try:
        node.static[canonical] = [float(v) for v in value_text.split()]
    except ValueError:
        raise scene.error(scene.line_of(pos), f"node {node.name!r}: cannot read {attr} value {value_text.strip()[:60]!r}") from None


def split_plug(plug: str) -> tuple[str, str]:
    node, _, attr = plug.partition(".")
    return node, attr
