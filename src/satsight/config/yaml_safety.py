"""Reading YAML files that may be hostile: bounded size, nesting and aliases; no repeated keys.

PyYAML's safe loader builds plain values only (no Python objects), but left alone it lets a
few hundred bytes of anchors and aliases stand for billions of values (a "billion laughs"),
recurses once per level of nesting until Python's stack runs out, and lets a repeated key
silently replace the first. ``load_yaml_file`` reads a file within the limits below. Every
refusal is a one-line ``SatsightError`` naming the file and, where there is one, the line.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from satsight.errors import SatsightError

MAX_FILE_BYTES = 1 << 20
"""1 MiB. A hand-written scenario is a few kB; a larger file is the wrong file or an attack,
and reading it is refused before any of it is parsed."""

MAX_DEPTH = 64
"""Levels of nested lists and mappings, an alias counting as the value it stands for. A
scenario nests about four levels; 64 stays far below Python's recursion limit (1000), which
the YAML composer, the constructor and validation would each approach once per level."""

MAX_ALIASES = 100
"""Uses of ``*alias`` in one file. Reusing a frame or a camera takes a few; a bomb takes many."""

MAX_NODES = 100_000
"""Values (scalars, lists and mappings) in the document with every alias expanded: what
validation will walk. It is counted while composing, so a bomb is refused before it is
built. A scenario listing 10 000 frames by hand stays below it."""

_MERGE_TAG = "tag:yaml.org,2002:merge"


class _BoundedLoader(yaml.SafeLoader):
    """A safe loader that counts while it composes and refuses what goes past the limits."""

    def __init__(self, text: str, source: str) -> None:
        super().__init__(text)
        self._source = source
        self._depth = 0  # nesting level of the node being composed
        self._deepest = 0  # deepest level reached inside the node being composed
        self._nodes = 0  # values composed so far, aliases expanded
        self._aliases = 0
        self._expansions: dict[str, tuple[int, int]] = {}  # anchor -> (values, levels)

    def _refuse(self, mark: yaml.Mark | None, reason: str) -> SatsightError:
        line = "" if mark is None else f"line {mark.line + 1}: "
        return SatsightError(f"{self._source}: {line}{reason}")

    def _count(self, values: int, mark: yaml.Mark) -> None:
        self._nodes += values
        if self._nodes > MAX_NODES:
            raise self._refuse(
                mark,
                f"more than {MAX_NODES} values, aliases expanded; "
                "a scenario needs far fewer (is this an alias bomb?)",
            )

    def compose_node(self, parent: yaml.Node | None, index: object) -> yaml.Node:
        """Compose one value, counting it and its nesting level before going inside it."""
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            return self._compose_alias(parent, index, event)
        depth = self._depth + 1
        if depth > MAX_DEPTH:
            raise self._refuse(event.start_mark, f"nested more than {MAX_DEPTH} levels deep")
        before, deepest_outside = self._nodes, self._deepest
        self._count(1, event.start_mark)
        self._depth = self._deepest = depth
        node = super().compose_node(parent, index)
        self._depth = depth - 1
        if event.anchor is not None:
            self._expansions[event.anchor] = (self._nodes - before, self._deepest - depth + 1)
        self._deepest = max(self._deepest, deepest_outside)
        return node

    def _compose_alias(
        self, parent: yaml.Node | None, index: object, event: yaml.AliasEvent
    ) -> yaml.Node:
        """An alias counts as every value of its anchor, at the alias's own nesting level."""
        self._aliases += 1
        if self._aliases > MAX_ALIASES:
            raise self._refuse(
                event.start_mark, f"more than {MAX_ALIASES} aliases (*name); a scenario needs few"
            )
        expansion = self._expansions.get(event.anchor)
        if expansion is None and event.anchor in self.anchors:
            raise self._refuse(
                event.start_mark, f"alias *{event.anchor} is inside its own anchor (a loop)"
            )
        if expansion is not None:  # an undefined alias is left to PyYAML's own error
            values, levels = expansion
            if self._depth + levels > MAX_DEPTH:
                raise self._refuse(
                    event.start_mark,
                    f"alias *{event.anchor} nests more than {MAX_DEPTH} levels deep",
                )
            self._count(values, event.start_mark)
            self._deepest = max(self._deepest, self._depth + levels)
        return super().compose_node(parent, index)

    def construct_object(self, node: yaml.Node, deep: bool = False) -> object:
        """Build one value; a scalar Python cannot hold becomes a message with its line."""
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, OverflowError) as error:  # an impossible date, a 5000-digit int
            raise self._refuse(node.start_mark, f"cannot read this value: {error}") from None

    def construct_mapping(self, node: yaml.Node, deep: bool = False) -> dict:
        """Refuse a key given twice in one mapping (``<<`` merges may still override)."""
        if isinstance(node, yaml.MappingNode):
            seen: dict[tuple[type, object], int] = {}
            for key_node, _ in node.value:
                if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE_TAG:
                    continue
                key = self.construct_object(key_node)
                ident = (type(key), key)  # so that true and 1 stay different keys
                line = key_node.start_mark.line + 1
                try:
                    first = seen.get(ident)
                except TypeError:  # unhashable: PyYAML refuses it below
                    continue
                if first is not None:
                    where = f"line {line}" if first == line else f"lines {first} and {line}"
                    raise self._refuse(
                        None, f"key '{key_node.value}' given twice, on {where}; keep one"
                    )
                seen[ident] = line
        return super().construct_mapping(node, deep=deep)

    def refuse_tag(self, node: yaml.Node) -> object:
        """Refuse a tag that the safe loader has no constructor for (``!!python/object``...)."""
        raise self._refuse(
            node.start_mark, f"the tag {node.tag} is not allowed; a scenario holds plain values"
        )


_BoundedLoader.add_constructor(None, _BoundedLoader.refuse_tag)


def _parse(text: str, source: str) -> object:
    """The single YAML document in ``text``; ``source`` names it in messages."""
    loader = _BoundedLoader(text, source)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def load_yaml_file(path: Path) -> object:
    """The YAML document in the scenario file ``path``, read within the limits above.

    Raises ``SatsightError`` for a missing, unreadable, oversized, non-UTF-8 or invalid file.
    """
    if not path.is_file():
        if path.is_dir():
            raise SatsightError(f"{path}: is a folder; give the scenario's YAML file")
        if path.is_symlink():
            raise SatsightError(f"{path}: a symbolic link that leads to no file (or a loop)")
        if path.exists():
            raise SatsightError(f"{path}: not a regular file; give the scenario's YAML file")
        raise SatsightError(f"scenario file not found: {path}")
    try:
        with path.open("rb") as file:
            data = file.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        raise SatsightError(f"{path}: cannot read it: {error.strerror or error}") from None
    if len(data) > MAX_FILE_BYTES:
        raise SatsightError(
            f"{path}: larger than {MAX_FILE_BYTES // 1024} KiB; a scenario is a few kB of YAML"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise SatsightError(f"{path}: not a UTF-8 text file; save it as UTF-8 YAML") from None
    try:
        return _parse(text, str(path))
    except yaml.reader.ReaderError as error:  # a control character: binary data
        raise SatsightError(
            f"{path}: not a text file (character #x{error.character:04x} at position "
            f"{error.position}); save it as UTF-8 YAML"
        ) from None
    except yaml.YAMLError as error:
        raise SatsightError(f"{path}: not valid YAML: {error}") from None
    except RecursionError:  # not reached within MAX_DEPTH; kept as a fallback
        raise SatsightError(f"{path}: nested too deeply to read") from None
