"""MkDocs hook (mkdocs.yml ``hooks:``): the Sphinx roles of the docstrings as links in the API pages.

The docstrings cross-reference with Sphinx roles (``:class:`~emmi_gym.env.config.EnvConfig```), which
Markdown renders as the role's text followed by code. This turns each into an autorefs reference:
a link where the target is documented on the site, the name in code otherwise (relative names such
as ``:meth:`action_masks``` stay code). ``~`` shows the last part of the name only, as in Sphinx.
"""

from __future__ import annotations

import re

ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj|const|py:\w+):<code>(~?)([\w.]+)(\(\))?</code>")


def _reference(match: re.Match) -> str:
    tilde, name, call = match.group(1), match.group(2), match.group(3) or ""
    title = name.rsplit(".", 1)[-1] if tilde else name.lstrip(".")
    if name.startswith("."):
        return f"<code>{title}{call}</code>"
    return f'<autoref identifier="{name}" optional><code>{title}{call}</code></autoref>'


def on_page_content(html: str, **kwargs) -> str:
    return ROLE.sub(_reference, html)
