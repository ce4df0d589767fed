"""The SCPI command tree: pattern compilation and header resolution.

Pattern notation (SCPI-1999 Vol. 1 §6.2): ``[SENSe:]VOLTage[:DC]:NPLCycles``.
Upper-case letters are the short form, the whole mnemonic the long form; ``[...]``
encloses optional nodes; ``#`` after a mnemonic allows a numeric suffix (default 1);
a trailing ``?`` is ignored (query-ness comes from the handler given). Common
commands are written ``*IDN``.

Each pattern is expanded into every combination of its optional groups and each
expansion is inserted into one trie of :class:`Node` objects, so an omitted optional
node and an explicitly given one lead to different trie nodes that carry the same
handler. A trie node is therefore a place in the *header as sent*, which is what the
path rules of IEEE 488.2 §A.1.1 work on (see :mod:`sim.scpi.engine`).

Registration rejects ambiguous trees (two siblings sharing a form, or one mnemonic
both with and without ``#``) with ``ValueError``: they could not be dispatched
faithfully.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable

__all__ = ["Node", "Entry", "compile_pattern", "resolve", "registered_patterns", "MAX_SUFFIX"]

#: Largest numeric header suffix accepted at all (handlers may set a lower max).
MAX_SUFFIX = 999_999_999

_MNEMONIC = re.compile(r"([A-Z][A-Z0-9]*)([a-z][a-z0-9]*)?(#)?")
_COMMON = re.compile(r"\*[A-Za-z]+")


class Entry:
    """A handler bound to one expansion of a pattern.

    ``slots`` gives, for each ``#`` of the pattern in order, the depth (0-based) of
    that node in this expansion, or ``None`` if the expansion omits it.
    """

    __slots__ = ("func", "slots", "max_suffix", "pattern")

    def __init__(self, func: Callable, slots: tuple, max_suffix: tuple, pattern: str):
        self.func = func
        self.slots = slots
        self.max_suffix = max_suffix
        self.pattern = pattern


class Node:
    """One node of the header trie."""

    __slots__ = ("parent", "depth", "long", "short", "has_suffix", "exact", "suffixed",
                 "set_entry", "query_entry")

    def __init__(self, parent: Node | None, long: str = "", short: str = "",
                 has_suffix: bool = False):
        self.parent = parent
        self.depth: int = 0 if parent is None else parent.depth + 1
        self.long = long
        self.short = short
        self.has_suffix = has_suffix
        self.exact: dict[str, Node] = {}     # short and long forms -> child
        self.suffixed: dict[str, Node] = {}  # forms of children that take a suffix
        self.set_entry: Entry | None = None
        self.query_entry: Entry | None = None

    def child(self, long: str, short: str, has_suffix: bool, pattern: str) -> Node:
        """Existing or new child; ValueError when it would be ambiguous."""
        node = self.exact.get(long)
        if node is not None and node.long == long:
            if node.short != short or node.has_suffix != has_suffix:
                raise ValueError(f"pattern {pattern!r}: {long} conflicts with an earlier "
                                 f"registration ({node.short}/{node.long}, suffix={node.has_suffix})")
            return node
        for form in {short, long}:
            if form in self.exact:
                other = self.exact[form]
                raise ValueError(f"pattern {pattern!r}: form {form} of {long} is ambiguous "
                                 f"with sibling {other.long}")
        node = Node(self, long, short, has_suffix)
        for form in {short, long}:
            self.exact[form] = node
            if has_suffix:
                self.suffixed[form] = node
        return node

    def path(self) -> str:
        """Long-form path of this node, e.g. ``SENSE:VOLTAGE``."""
        names = []
        node = self
        while node.parent is not None:
            names.append(node.long + ("#" if node.has_suffix else ""))
            node = node.parent
        return ":".join(reversed(names))


def _parse_pattern(pattern: str) -> list[tuple[str, int | None]]:
    """Split a pattern into (mnemonic, optional-group id or None)."""
    nodes: list[tuple[str, int | None]] = []
    group: int | None = None
    groups = 0
    cur = ""

    def flush():
        nonlocal cur
        if cur:
            nodes.append((cur, group))
            cur = ""

    for ch in pattern:
        if ch == "[":
            if group is not None:
                raise ValueError(f"pattern {pattern!r}: nested '['")
            flush()
            groups += 1
            group = groups
        elif ch == "]":
            if group is None:
                raise ValueError(f"pattern {pattern!r}: ']' without '['")
            flush()
            group = None
        elif ch == ":":
            flush()
        else:
            cur += ch
    if group is not None:
        raise ValueError(f"pattern {pattern!r}: unclosed '['")
    flush()
    if not nodes:
        raise ValueError(f"pattern {pattern!r} has no mnemonic")
    return nodes


def compile_pattern(root: Node, commons: dict[str, Node], pattern: str,
                    set_func: Callable | None, query_func: Callable | None,
                    max_suffix: int | tuple | None = None) -> None:
    """Insert ``pattern`` into the trie (or the common-command table) with handlers."""
    if not isinstance(pattern, str):
        raise TypeError(f"pattern must be a str, got {pattern!r}")
    text = pattern.strip()
    if text.endswith("?"):
        text = text[:-1]
    if text.startswith("*"):
        if not _COMMON.fullmatch(text):
            raise ValueError(f"common command pattern {pattern!r} must be '*' + letters")
        key = text.upper()
        node = commons.get(key)
        if node is None:
            node = commons[key] = Node(None, key, key)
        _bind(node, Entry, set_func, query_func, (), (), pattern)
        return
    parsed = _parse_pattern(text)
    mnemonics = []
    for name, group in parsed:
        m = _MNEMONIC.fullmatch(name)
        if m is None:
            raise ValueError(f"pattern {pattern!r}: bad mnemonic {name!r} (want e.g. VOLTage or OUTPut#)")
        short = m.group(1)
        long = short + (m.group(2) or "").upper()
        mnemonics.append((long, short, m.group(3) is not None, group))
    n_suffix = sum(1 for mn in mnemonics if mn[2])
    if max_suffix is None:
        limits = (MAX_SUFFIX,) * n_suffix
    elif isinstance(max_suffix, int):
        limits = (max_suffix,) * n_suffix
    else:
        limits = tuple(MAX_SUFFIX if x is None else x for x in max_suffix)
        if len(limits) != n_suffix:
            raise ValueError(f"pattern {pattern!r} has {n_suffix} '#' but max_suffix has {len(limits)} entries")
    if any(not 1 <= lim <= MAX_SUFFIX for lim in limits):
        raise ValueError(f"max_suffix {max_suffix!r} must be within 1..{MAX_SUFFIX}")
    group_ids = sorted({g for *_, g in mnemonics if g is not None})
    for included in itertools.product((True, False), repeat=len(group_ids)):
        keep = {g for g, inc in zip(group_ids, included) if inc}
        node = root
        slots: list[int | None] = []
        for long, short, has_suffix, group in mnemonics:
            if group is not None and group not in keep:
                if has_suffix:
                    slots.append(None)
                continue
            node = node.child(long, short, has_suffix, pattern)
            if has_suffix:
                slots.append(node.depth - 1)
        if node is root:
            raise ValueError(f"pattern {pattern!r}: an expansion has no mnemonic left")
        _bind(node, Entry, set_func, query_func, tuple(slots), limits, pattern)


def _bind(node: Node, entry_cls, set_func, query_func, slots, limits, pattern) -> None:
    if set_func is not None:
        node.set_entry = entry_cls(set_func, slots, limits, pattern)
    if query_func is not None:
        node.query_entry = entry_cls(query_func, slots, limits, pattern)


def resolve(start: Node, tokens: list[str]) -> tuple[Node, tuple]:
    """Walk upper-cased header mnemonics from ``start``.

    Returns the node reached and, per token, its numeric suffix (``None`` for nodes
    without ``#``; 1 when the suffix was omitted).

    Raises:
        LookupError: args ``(code, detail)`` with -113 or -114.
    """
    node = start
    suffixes = []
    for tok in tokens:
        child = node.exact.get(tok)
        if child is not None:
            suffixes.append(1 if child.has_suffix else None)
            node = child
            continue
        j = len(tok)
        while j and tok[j - 1].isdigit():
            j -= 1
        child = node.suffixed.get(tok[:j]) if 0 < j < len(tok) else None
        if child is None:
            raise LookupError(-113, f"{tok} not under {node.path() or 'the root'}")
        digits = tok[j:]
        value = int(digits) if len(digits) <= 9 else MAX_SUFFIX + 1
        if not 1 <= value <= MAX_SUFFIX:
            raise LookupError(-114, f"suffix {digits} of {tok[:j]} not in 1..{MAX_SUFFIX}")
        suffixes.append(value)
        node = child
    return node, tuple(suffixes)


def registered_patterns(root: Node, commons: dict[str, Node]) -> dict[str, set[str]]:
    """Every pattern registered in a tree, as given to ``compile_pattern``, with its kinds.

    Returns ``{pattern: {"set", "query"}}`` (one or both): the command tree as a table,
    for checking it against a documented vocabulary.  A trailing ``?`` of a pattern is
    dropped (query-ness is the kind); every expansion of a pattern reports the same one.
    """
    found: dict[str, set[str]] = {}

    def note(node: Node) -> None:
        for kind, entry in (("set", node.set_entry), ("query", node.query_entry)):
            if entry is not None:
                found.setdefault(entry.pattern.strip().removesuffix("?"), set()).add(kind)

    stack = [root, *commons.values()]
    seen: set[int] = set()
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        note(node)
        stack.extend(node.exact.values())
    return found
