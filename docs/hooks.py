"""MkDocs hooks for the jaxarm site (mkdocs.yml `hooks:`).

* **Sphinx roles.** The docstrings use Sphinx-style roles (:func:`x`, :class:`~a.b`) that Markdown leaves as text; in
  the rendered API reference the role prefix is dropped and a leading ``~`` shortens the name to its last component,
  as Sphinx does.
* **Numbers from result files.** A page states a measured number by naming its result file in ``docs/results/``
  and the field, never by copying it: ``{{ result: FILE : PATH }}`` or ``{{ result: FILE : PATH : FORMAT }}`` is
  replaced by the value at PATH (dot-separated keys) of ``docs/results/FILE``, and ``{{ results table: FILE }}`` by
  the whole results table of a ``jaxarm reproduce`` file (its ``success_table.json``); ``{{ profile table: FILE }}``
  by the table of a ``benchmarks/profile.py`` result file. FORMAT is a Python format
  spec (``.1f``, ``,.0f``) or one of :data:`FORMATS`. Where a page is read unrendered (README.md on GitHub), the
  number is written out and followed by ``<!-- result: FILE : PATH [: FORMAT] -->``; the build (for the site's
  pages) and tests/test_docs.py (for README.md too) fail when the number before such a marker is not the file's.
* **The tutorials' links.** A notebook links the documentation as ``../docs/PAGE.md`` (right on GitHub and in
  Jupyter); on the site those links point to the page (:func:`notebook_links`).
* **The command-line reference** (``cli.md``) is generated from the argument parsers of the ``jaxarm`` commands
  (:func:`jaxarm.cli.parser`) whenever the site is built, so it lists exactly the options they accept.
"""
from __future__ import annotations

import argparse
import html
import json
import re
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|obj|exc|const):(?=<code>)")
_TILDE = re.compile(r"<code>~(?:[\w.]*\.)?(\w+)</code>")

PLACEHOLDER = re.compile(r"\{\{\s*result:([^{}]*)\}\}")
TABLE = re.compile(r"\{\{\s*results table:\s*([\w.-]+)\s*\}\}")
PROFILE_TABLE = re.compile(r"\{\{\s*profile table:\s*([\w.-]+)\s*\}\}")
MARKER = re.compile(r"<!--\s*result:(.*?)-->")


def _minutes(v) -> str:
    return f"{round(v / 60)}"


def _minutes_seconds(v) -> str:
    m, s = divmod(round(v), 60)
    return f"{m} min {s} s"


#: Named formats: ``count`` writes ``K/N`` with N the sibling field ``<key>_n`` (``targets.left.seeds`` ->
#: ``29/30``); ``min`` a number of seconds in whole minutes; ``min s`` in minutes and seconds (``15 min 5 s``).
FORMATS = {"min": _minutes, "min s": _minutes_seconds}


class ResultError(ValueError):
    """A reference to a result that does not resolve, or a written-out number that differs from its file."""


def _load(name: str) -> dict:
    path = RESULTS / name
    if not path.is_file():
        raise ResultError(f"result file docs/results/{name} not found; files: "
                          f"{', '.join(sorted(p.name for p in RESULTS.glob('*.json')))}")
    return json.loads(path.read_text())


def result(spec: str) -> str:
    """The formatted value of ``FILE : PATH [: FORMAT]``."""
    parts = [p.strip() for p in spec.split(":")]
    if len(parts) not in (2, 3) or not all(parts):
        raise ResultError(f"result reference {spec.strip()!r}: write FILE : PATH or FILE : PATH : FORMAT")
    name, path, fmt = parts[0], parts[1], parts[2] if len(parts) == 3 else ""
    parent, value = None, _load(name)
    for key in path.split("."):
        if isinstance(value, list) and key.isdigit() and int(key) < len(value):  # a list's item by its index
            parent, value = value, value[int(key)]
            continue
        if not isinstance(value, dict) or key not in value:
            raise ResultError(f"docs/results/{name}: no field {path!r} (at {key!r})")
        parent, value = value, value[key]
    if fmt == "count":
        total = parent.get(f"{key}_n")
        if total is None:
            raise ResultError(f"docs/results/{name}: {path!r} has no sibling {key}_n for the format 'count'")
        return f"{value}/{total}"
    if fmt in FORMATS:
        return FORMATS[fmt](value)
    try:
        return format(value, fmt)
    except (TypeError, ValueError) as e:
        raise ResultError(f"docs/results/{name} {path} = {value!r}: format {fmt!r}: {e}") from None


def results_table(name: str) -> str:
    """The whole results table of a ``jaxarm reproduce`` result file, as the command prints it."""
    from jaxarm.paper.reproduce import results_markdown

    return results_markdown(_load(name))


def profile_table(name: str) -> str:
    """The table of a ``benchmarks/profile.py`` result file, as the script prints it (benchmarks/profile_table.py)."""
    import importlib.util

    path = Path(__file__).resolve().parent.parent / "benchmarks" / "profile_table.py"
    spec = importlib.util.spec_from_file_location("profile_table", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.table(_load(name)["results"])


def render(markdown: str) -> str:
    """``markdown`` with every result placeholder replaced by its value."""
    markdown = TABLE.sub(lambda m: results_table(m.group(1)), markdown)
    markdown = PROFILE_TABLE.sub(lambda m: profile_table(m.group(1)), markdown)
    return PLACEHOLDER.sub(lambda m: result(m.group(1)), markdown)


def marker_mismatches(markdown: str) -> list[str]:
    """One line per ``<!-- result: ... -->`` marker whose written-out number (just before it, bold or not) is not
    its file's value."""
    out = []
    for m in MARKER.finditer(markdown):
        want = result(m.group(1))
        before = markdown[:m.start()].rstrip("*")
        ok = before.endswith(want) and not re.search(r"[\w.,/]$", before[:len(before) - len(want)])
        if not ok:
            line = markdown.count("\n", 0, m.start()) + 1
            got = re.search(r"[^\s(*]*$", before).group(0)
            out.append(f"line {line}: {got!r} where docs/results/{m.group(1).strip()} is {want!r}")
    return out


# ---------------------------------------------------------------- the command-line reference
def _cell(text: str) -> str:
    """Text for a Markdown table cell: `code` spans as <code>, everything else inert (no emphasis, no HTML, no
    column breaks)."""
    def inert(s):
        return html.escape(s).replace("|", "&#124;").replace("*", "&#42;").replace("_", "&#95;")

    parts = str(text).split("`")
    return "".join(f"<code>{inert(p)}</code>" if i % 2 else inert(p) for i, p in enumerate(parts)).replace("\n", " ")


def _default(action: argparse.Action) -> str:
    if action.required:
        return "required"
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return "off"
    d = action.default
    if d is None or d is argparse.SUPPRESS or d == []:
        return "–"
    return _cell(f"`{' '.join(map(str, d)) if isinstance(d, (list, tuple)) else d}`")


def command_reference(name: str, one_line: str, ap: argparse.ArgumentParser) -> str:
    """One command's section: its one-line help, its description as ``--help`` prints it, a table per option
    group (option, default, help)."""
    fmt = ap.formatter_class(prog=ap.prog, width=100)
    lines = [f"## jaxarm {name}", "", _cell(one_line) + ".", ""]
    if ap.description:
        fmt.add_text(ap.description)
        lines += ["```text", fmt.format_help().strip("\n"), "```", ""]
    for group in ap._action_groups:
        actions = [a for a in group._group_actions if not isinstance(a, argparse._HelpAction)]
        if not actions:
            continue
        lines += [f"**{_cell(group.title)}**", "", "| option | default | help |", "|---|---|---|"]
        for a in actions:
            usage = fmt._format_action_invocation(a) if a.option_strings else fmt._metavar_formatter(a, a.dest)(1)[0]
            help_ = _cell(fmt._expand_help(a)) if a.help else ""
            lines.append(f"| <code>{_cell(usage)}</code> | {_default(a)} | {help_} |")
        lines.append("")
    return "\n".join(lines)


def cli_reference() -> str:
    """The command-line reference page: every ``jaxarm`` command, every option with its default and help."""
    from jaxarm import cli

    lines = ["# Command line", "",
             "Every `jaxarm` command with every option, its default and its help, generated from the commands' own "
             "argument parsers when this site is built (`jaxarm COMMAND --help` prints the same). Help texts that "
             "name this machine's cores name those of the machine that built the site.", "",
             "| command | what it does |", "|---|---|"]
    lines += [f"| [`jaxarm {name}`](#jaxarm-{name}) | {_cell(help_)} |" for name, (_, help_) in cli.COMMANDS.items()]
    lines.append("")
    lines += [command_reference(name, help_, cli.parser(name)) for name, (_, help_) in cli.COMMANDS.items()]
    return "\n".join(lines)


#: Pages made at build time: path in the site -> the function that writes them.
GENERATED = {"cli.md": cli_reference}


# ---------------------------------------------------------------- the tutorials' links
_NOTEBOOK_LINK = re.compile(r'href="\.\./docs/([\w/-]+)\.md(#[^"]*)?"')


def notebook_links(html_: str) -> str:
    """A tutorial links the documentation as ``../docs/PAGE.md``, which resolves where the notebook is read (GitHub,
    Jupyter in ``notebooks/``); on the site, where the notebook is the page ``tutorials/NAME/``, that link becomes
    ``../../PAGE/``."""
    return _NOTEBOOK_LINK.sub(lambda m: f'href="../../{m.group(1)}/{m.group(2) or ""}"', html_)


# ---------------------------------------------------------------- MkDocs events
def on_files(files, config):
    from mkdocs.structure.files import File

    for path, make in GENERATED.items():
        files.append(File.generated(config, path, content=make()))
    return files


def on_page_markdown(markdown, page, config, files):
    from mkdocs.exceptions import PluginError

    try:
        bad = marker_mismatches(markdown)
        if bad:
            raise ResultError("; ".join(bad))
        return render(markdown)
    except ResultError as e:
        raise PluginError(f"{page.file.src_uri}: {e}") from None


def on_page_content(html_, page, config, files):
    if page.file.src_uri.endswith(".ipynb"):
        html_ = notebook_links(html_)
    html_ = _ROLE.sub("", html_)
    return _TILDE.sub(r"<code>\1</code>", html_)
