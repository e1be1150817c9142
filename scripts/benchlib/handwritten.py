"""Links from a generated page to the sections of docs/results/performance-notes.md.

That page is generated too (scripts/resultslib/templates/performance-notes.md.in): it keeps the
headings of the measurements made by hand at past commits and links each dated record in
CHANGELOG.md. `section_links` builds links to those headings and raises when one the caller
names is missing (a heading renamed or removed there), instead of losing it silently.

Standard library only.
"""

import re
from pathlib import Path

HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")


def anchors(text):
    """{heading line: its GitHub anchor} of a markdown text (first occurrence of each heading),
    as tests/docs/check_docs.py computes them."""
    out, seen = {}, {}
    in_fence = False
    for line in text.split("\n"):
        if line.lstrip().startswith(("```", "~~~")):
            in_fence = not in_fence
            continue
        m = HEADING.match(line)
        if in_fence or not m:
            continue
        title = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", m.group(2)).replace("`", "")
        slug = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
        if slug in seen:
            seen[slug] += 1
            slug = f"{slug}-{seen[slug]}"
        else:
            seen[slug] = 0
        out.setdefault(line.strip(), slug)
    return out


def section_links(page, titles, link):
    """Markdown list items linking each heading in `titles` (full heading lines, e.g.
    "## Start-up") of the hand-written `page`, through the relative `link` to it. Raises
    RuntimeError naming every title the page lacks."""
    page = Path(page)
    if not page.exists():
        raise RuntimeError(f"{page}: the hand-written page the generated document links to is "
                           "missing")
    found = anchors(page.read_text())
    missing = [t for t in titles if t not in found]
    if missing:
        raise RuntimeError(f"{page}: hand-written section(s) the generated document links to "
                           "are missing (renamed or removed?): " + "; ".join(missing)
                           + ". Restore them or update the generator's list.")
    return [f"- [{HEADING.match(t).group(2)}]({link}#{found[t]})" for t in titles]
