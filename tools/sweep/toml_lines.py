"""Line numbers of the keys of a TOML file, for error messages (tomllib gives none).

Maps key paths such as ('parameter', 1, 'keys', 'dem.insert[0].mass') to the line where the
key or table header is written. It understands table headers, arrays of tables, dotted and
quoted keys, and skips the insides of multi-line arrays, inline tables and multi-line
strings; a key it cannot place gets no line (the message then names file and key only)."""

import re

_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _split_key(text):
    """'a."b.c".d' -> ['a', 'b.c', 'd'] (None when it is not a plain key)."""
    parts, i, text = [], 0, text.strip()
    while i < len(text):
        while i < len(text) and text[i] in " \t":
            i += 1
        if i < len(text) and text[i] in "\"'":
            q = text[i]
            j = text.find(q, i + 1)
            if j < 0:
                return None
            parts.append(text[i + 1:j])
            i = j + 1
        else:
            m = _BARE.match(text, i)
            if not m:
                return None
            parts.append(m.group(0))
            i = m.end()
        while i < len(text) and text[i] in " \t":
            i += 1
        if i < len(text):
            if text[i] != ".":
                return None
            i += 1
    return parts


def _key_end(line):
    """Index of the '=' that ends the key of a `key = value` line, or -1."""
    q = None
    for i, c in enumerate(line):
        if q:
            if c == q:
                q = None
        elif c in "\"'":
            q = c
        elif c == "=":
            return i
        elif c == "#":
            return -1
    return -1


def _open_depth(value):
    """Net brackets/braces left open by a value's text (strings and comments skipped), and
    whether a multi-line string starts and stays open."""
    depth, i, n = 0, 0, len(value)
    while i < n:
        c = value[i]
        if value.startswith('"""', i) or value.startswith("'''", i):
            q = value[i:i + 3]
            j = value.find(q, i + 3)
            if j < 0:
                return depth, q
            i = j + 3
            continue
        if c in "\"'":
            j = i + 1
            while j < n and value[j] != c:
                j += 2 if (c == '"' and value[j] == "\\") else 1
            i = j + 1
            continue
        if c == "#":
            break
        if c in "[{":
            depth += 1
        elif c in "]}":
            depth -= 1
        i += 1
    return depth, None


def key_lines(text):
    lines = {}
    counts = {}  # array-of-tables path (with indices of its parents) -> entries so far
    current = ()
    depth, open_string = 0, None

    def resolve(parts):
        path = ()
        for p in parts:
            path += (p,)
            if path in counts:
                path += (counts[path] - 1,)
        return path

    for no, raw in enumerate(text.splitlines(), start=1):
        if open_string:
            if open_string in raw:
                open_string = None
            continue
        if depth > 0:
            d, open_string = _open_depth(raw)
            depth += d
            continue
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("[["):
            end = line.find("]]")
            parts = _split_key(line[2:end]) if end > 0 else None
            if parts:
                parent = resolve(parts[:-1])
                key = parent + (parts[-1],)
                counts[key] = counts.get(key, 0) + 1
                current = key + (counts[key] - 1,)
                lines.setdefault(current, no)
                lines.setdefault(key, no)
            continue
        if line.startswith("["):
            end = line.find("]")
            parts = _split_key(line[1:end]) if end > 0 else None
            if parts:
                current = resolve(parts)
                lines.setdefault(current, no)
            continue
        eq = _key_end(line)
        if eq < 0:
            continue
        parts = _split_key(line[:eq])
        if parts:
            lines.setdefault(current + tuple(parts), no)
        d, open_string = _open_depth(line[eq + 1:])
        depth = max(d, 0)
    return lines
