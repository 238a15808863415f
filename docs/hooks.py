"""MkDocs hooks for the jaxarm site (mkdocs.yml `hooks:`).

The docstrings use Sphinx-style roles (:func:`x`, :class:`~a.b`) that Markdown leaves as text; in the rendered API
reference the role prefix is dropped and a leading ``~`` shortens the name to its last component, as Sphinx does.
"""
import re

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|obj|exc|const):(?=<code>)")
_TILDE = re.compile(r"<code>~(?:[\w.]*\.)?(\w+)</code>")


def on_page_content(html, page, config, files):
    html = _ROLE.sub("", html)
    return _TILDE.sub(r"<code>\1</code>", html)
