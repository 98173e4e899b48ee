"""MkDocs hooks of the demfem manual (mkdocs.yml, `hooks:`). Not a page: removed from the site.

* Links from a page to a file of the repository outside docs/ (`../tests/fuzz/README.md`)
  are checked (the file must exist) and written as the file's path in the source tree, since
  the site has no copy of it. A missing one is a warning, so `mkdocs build --strict` fails.
* A line `--8<-- "PATH"` (PATH relative to the top of the repository) is replaced by that
  file's text, so that a page shows a scene file exactly as it is in the tree (a missing file
  is a warning).
* After the build every internal link of every page is checked, anchors included (MkDocs 1.4
  checks only that a linked page exists): a link to a missing page or to a heading that is
  not there is a warning, so the strict build fails.
* A user page (every page outside reports/) holds no commit hash, no load average and no
  date: those belong to the measurement history in reports/, the user page keeps the result
  and the command that reproduces it. Each one found is a warning naming the page and line.
  Allowed (DATED_TEXT_ALLOWED): none today.
* The API pages (api_pages.py): `<!-- python-api: MODULE -->` lines become the Python SDK's
  reference from its docstrings; Doxygen writes the C++ SDK's into the site's api/cpp/
  before the links are checked. Either failing is a warning.
"""

import html.parser
import logging
import os
import posixpath
import re
import sys
from urllib.parse import unquote, urlsplit

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import api_pages  # noqa: E402  (beside this file, which MkDocs loads by path)

log = logging.getLogger("mkdocs.hooks.demfem")

_FENCE = re.compile(r"^(```|~~~)")
_INCLUDE = re.compile(r'^--8<-- "([^"]+)"\s*$')
_LINK = re.compile(r"\[([^\]\n]*)\]\((\.\./[^)\s#]+)(#[^)\s]*)?\)")

# Dated text: a commit hash (7 to 12 hex digits with a letter and a digit, or 40, not part of
# a number, a path or a name such as a segment's), a load average ("load average 11",
# "(load 10–13)", "load about 6)"; not "load 51 kg"), an ISO date.
_DATED = [
    ("a commit hash", re.compile(r"(?<![\w./-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])"
                                 r"(?:[0-9a-f]{40}|[0-9a-f]{7,12})(?![\w.])")),
    ("a load average", re.compile(r"\bload averages?\b|\bload (?:about |of |≈ ?|~ ?)?\d+(?:\.\d+)?"
                                  r"(?:\s*[–-]\s*\d+(?:\.\d+)?)?(?=\s*[),;]|\s*$)", re.I)),
    ("a date", re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")),
]
# Pages or parts of pages whose dated text is still to move to reports/: a page's whole text
# (None) or the sections (H2 headings) named, or the exact texts named.
DATED_TEXT_ALLOWED = {
}


def on_files(files, config):
    """Leaves docs/_site (this hook) out of the site."""
    for f in list(files):
        if f.src_path.replace(os.sep, "/").startswith("_site/"):
            files.remove(f)
    return files


def _rewrite_outside_links(line, page, config):
    docs_dir = config["docs_dir"]
    page_dir = os.path.dirname(os.path.join(docs_dir, page.file.src_path))
    repo = os.path.dirname(os.path.abspath(docs_dir))

    def repl(m):
        target = os.path.normpath(os.path.join(page_dir, unquote(m.group(2))))
        inside_docs = os.path.commonpath([target, os.path.abspath(docs_dir)]) == os.path.abspath(docs_dir)
        if inside_docs:
            return m.group(0)  # MkDocs checks those itself
        rel = os.path.relpath(target, repo).replace(os.sep, "/")
        if rel.startswith("..") or not os.path.exists(target):
            log.warning(f"{page.file.src_path}: link to '{m.group(2)}', which is not in the repository")
            return m.group(0)
        return f"{m.group(1)} (source file `{rel}`)"

    return _LINK.sub(repl, line)


def dated_text(markdown, src_path):
    """[(line number, what, text)] of the dated text in a user page's Markdown."""
    path = src_path.replace(os.sep, "/")
    if path.startswith("reports/"):
        return []
    allowed = DATED_TEXT_ALLOWED.get(path, {})
    if allowed is None:
        return []
    found, section = [], ""
    for number, line in enumerate(markdown.split("\n"), 1):
        if line.startswith("## "):
            section = line.strip()
        if section in allowed.get("sections", []):
            continue
        for what, pattern in _DATED:
            for m in pattern.finditer(line):
                if m.group(0) not in allowed.get("texts", []):
                    found.append((number, what, m.group(0)))
    return found


def _build_dir(config):
    repo = os.path.dirname(os.path.abspath(config["docs_dir"]))
    return os.environ.get("DEMFEM_BUILD_DIR") or os.path.join(repo, "build")


def on_page_markdown(markdown, page, config, files):
    markdown, errors = api_pages.python_api(markdown, _build_dir(config))
    for e in errors:
        log.warning(f"{page.file.src_path}: {e}")
    for number, what, text in dated_text(markdown, page.file.src_path):
        log.warning(f"{page.file.src_path}:{number}: {what} ('{text}') in a user page: move "
                    "the measurement's history to docs/reports/, keep the result and its command")
    repo = os.path.dirname(os.path.abspath(config["docs_dir"]))
    out, fenced = [], False
    for line in markdown.split("\n"):
        m = _INCLUDE.match(line)
        if m:
            path = os.path.join(repo, m.group(1))
            if not os.path.isfile(path):
                log.warning(f"{page.file.src_path}: '{m.group(1)}' to include is not in the repository")
                out.append(line)
            else:
                with open(path, encoding="utf-8") as f:
                    out.append(f.read().rstrip("\n"))
            continue
        if _FENCE.match(line.lstrip()):
            fenced = not fenced
        out.append(line if fenced else _rewrite_outside_links(line, page, config))
    return "\n".join(out)


class _Anchors(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.hrefs = set(), []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("name"):
            self.ids.add(a["name"])
        if tag == "a" and a.get("href") is not None:
            self.hrefs.append(a["href"])


def _parse(path, cache):
    if path not in cache:
        p = _Anchors()
        with open(path, encoding="utf-8") as f:
            p.feed(f.read())
        cache[path] = p
    return cache[path]


def on_post_build(config):
    site = config["site_dir"]
    repo = os.path.dirname(os.path.abspath(config["docs_dir"]))
    for e in api_pages.cpp_api(repo, site):
        log.warning(e)
    cache, checked, broken = {}, 0, 0
    for dirpath, dirnames, filenames in os.walk(site):
        # Doxygen's pages (api/cpp) are its own; the links into them are checked
        dirnames[:] = [d for d in dirnames if d not in ("assets", "search")
                       and os.path.relpath(os.path.join(dirpath, d), site) != os.path.join("api", "cpp")]
        for name in filenames:
            if not name.endswith(".html") or name == "404.html":
                continue
            page = os.path.join(dirpath, name)
            for href in _parse(page, cache).hrefs:
                parts = urlsplit(href)
                if parts.scheme or parts.netloc or href.startswith(("/", "mailto:")):
                    continue
                path = unquote(parts.path)
                if path == "":
                    target = page
                else:
                    target = os.path.normpath(os.path.join(dirpath, path))
                    if os.path.isdir(target) or path.endswith("/"):
                        target = os.path.join(target, "index.html")
                checked += 1
                where = os.path.relpath(page, site)
                if not os.path.exists(target):
                    log.warning(f"{where}: link '{href}' leads nowhere (no {os.path.relpath(target, site)})")
                    broken += 1
                elif parts.fragment and target.endswith(".html"):
                    if unquote(parts.fragment) not in _parse(target, cache).ids:
                        log.warning(f"{where}: link '{href}': no heading or anchor "
                                    f"'#{parts.fragment}' in {os.path.relpath(target, site)}")
                        broken += 1
    log.info(f"demfem hooks: checked {checked} internal links, {broken} broken")
