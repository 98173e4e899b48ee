"""The API pages of the manual, made while the site builds (docs/_site/hooks.py calls these).

* Python SDK: a line `<!-- python-api: MODULE -->` in a page is replaced by MODULE's reference
  rendered from its docstrings (module, then each name of its __all__: classes with their
  methods and properties, functions, enumerations, constants). The package is imported from
  the build: $DEMFEM_BUILD_DIR/python (default build/python), which `./demfem docs` builds
  first; the signatures are the interpreter's (pybind11 writes them into the docstrings of
  the compiled part).
* C++ SDK: Doxygen (Debian's doxygen) writes the HTML reference of the installed headers
  (docs/_site/Doxyfile) into the site's api/cpp/, with warnings as errors.

A failure is returned as a message for the caller to log as a warning, so that the strict
build fails with it.
"""

import importlib
import inspect
import os
import re
import subprocess
import sys

PYTHON_API = re.compile(r"^<!-- python-api: ([\w.]+) -->\s*$")


def _block(text, lang="text"):
    return f"```{lang}\n{inspect.cleandoc(text).rstrip()}\n```\n" if text and text.strip() else ""


def _signature(name, obj):
    """`name(args)` of a Python callable; None for a compiled one (its docstring has it)."""
    try:
        return f"{name}{inspect.signature(obj)}"
    except (TypeError, ValueError):
        return None


def _callable(qualified, obj, level):
    doc = inspect.getdoc(obj) or ""
    signature = _signature(qualified.rsplit(".", 1)[-1], obj)
    out = [f"{'#' * level} `{qualified}`\n"]
    if signature:
        out.append(_block(signature, "python"))
    out.append(_block(doc))
    return "\n\n".join(o for o in out if o)


def _members(cls):
    """The public methods and properties the class itself defines, in source order where
    Python knows it (a compiled class: its dictionary's order)."""
    for name, member in vars(cls).items():
        if name.startswith("_") and name != "__init__":
            continue
        if isinstance(member, property) or type(member).__name__ in ("property",):
            yield name, member, "property"
        elif callable(member) or isinstance(member, (staticmethod, classmethod)):
            yield name, member, "method"


def _class(qualified, cls, level):
    doc = inspect.getdoc(cls) or ""
    entries = getattr(cls, "__entries", None)
    if isinstance(entries, dict):  # a pybind11 enumeration: its values listed below instead
        doc = doc.split("\n\nMembers:")[0]
    out = [f"{'#' * level} `{qualified}`\n", _block(doc)]
    if isinstance(entries, dict):
        out.append("| value | meaning |\n| --- | --- |\n" + "".join(
            f"| `{qualified}.{k}` | {v[1] or ''} |\n" for k, v in entries.items()))
        return "\n\n".join(o for o in out if o)
    for name, member, kind in _members(cls):
        # the member's own docstring, not one inherited from object
        doc = inspect.cleandoc(getattr(member, "__doc__", None) or "")
        if name == "__init__" and (not doc or doc.startswith("Initialize self")) and \
                _signature(name, member) in (None, "__init__(self, /, *args, **kwargs)"):
            continue  # no constructor of its own to show
        if kind == "property":
            out.append(f"* **`{name}`** (property): {' '.join(doc.split())}" if doc
                       else f"* **`{name}`** (property)")
            continue
        func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
        signature = _signature(name, func)
        out.append(f"* **`{name}`**\n")
        if signature:
            out.append(_indent(_block(signature, "python")))
        if doc:
            out.append(_indent(_block(doc)))
    return "\n\n".join(o for o in out if o)


def _indent(text):
    return "\n".join("    " + line if line else line for line in text.split("\n"))


def render_module(module_name, build_dir):
    """The Markdown reference of `module_name`, or raises ImportError naming the fix."""
    python_dir = os.path.join(build_dir, "python")
    if python_dir not in sys.path:
        sys.path.insert(0, python_dir)
    try:
        module = importlib.import_module(module_name)
    except ImportError as e:
        raise ImportError(f"cannot import {module_name} from {python_dir} ({e}): build the "
                          "Python SDK first (`./demfem docs` does, or `./demfem build`), or set "
                          "DEMFEM_BUILD_DIR") from None
    out = [f"## `{module_name}`\n", _block(inspect.getdoc(module) or "")]
    constants = []
    for name in getattr(module, "__all__", []):
        obj = getattr(module, name)
        qualified = f"{module_name}.{name}"
        if inspect.isclass(obj):
            out.append(_class(qualified, obj, 3))
        elif callable(obj):
            out.append(_callable(qualified, obj, 3))
        else:
            constants.append((name, obj))
    if constants:
        out.append(f"### Constants of `{module_name}`\n\n| name | value |\n| --- | --- |\n" +
                   "".join(f"| `{n}` | `{v!r}` |\n" for n, v in constants))
    return "\n\n".join(o for o in out if o)


def python_api(markdown, build_dir):
    """The page with each `<!-- python-api: MODULE -->` line rendered; [errors]."""
    out, errors = [], []
    for line in markdown.split("\n"):
        m = PYTHON_API.match(line)
        if not m:
            out.append(line)
            continue
        try:
            out.append(render_module(m.group(1), build_dir))
        except ImportError as e:
            errors.append(str(e))
            out.append(line)
    return "\n".join(out), errors


def cpp_api(repo, site_dir):
    """Runs Doxygen on docs/_site/Doxyfile into <site>/api/cpp; returns [errors]."""
    doxyfile = os.path.join(repo, "docs", "_site", "Doxyfile")
    with open(doxyfile, encoding="utf-8") as f:
        config = f.read() + f"\nOUTPUT_DIRECTORY = {os.path.join(site_dir, 'api')}\nHTML_OUTPUT = cpp\n"
    try:
        r = subprocess.run(["doxygen", "-"], input=config, cwd=repo, capture_output=True,
                           text=True, timeout=300)
    except FileNotFoundError:
        return ["doxygen is missing: install Debian's doxygen (`./demfem setup` does); the C++ "
                "API pages need it"]
    if r.returncode != 0 or r.stderr.strip():
        return [f"doxygen ({doxyfile}) failed, status {r.returncode}:\n{r.stderr.strip()}"]
    if not os.path.isfile(os.path.join(site_dir, "api", "cpp", "index.html")):
        return [f"doxygen wrote no {os.path.join(site_dir, 'api', 'cpp', 'index.html')}"]
    return []
