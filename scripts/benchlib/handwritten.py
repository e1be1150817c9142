"""Links from a generated document to the sections of a hand-written page.

The generated docs/results/performance.md carries no hand-written text: measurements made by hand live
in docs/results/performance-notes.md, and the generated document lists links to their sections.
These helpers build those links and fail loudly instead of losing anything silently:

- `section_links` raises when a section the generator links to is missing from the
  hand-written page (a heading renamed or removed there);
- `check_nothing_dropped` raises when the document about to be overwritten holds a section the
  new one does not (a section written by hand into the generated document).

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


def check_nothing_dropped(path, new_lines):
    """Raises RuntimeError when the existing document at `path` has a heading that `new_lines`
    lacks: text written by hand into the generated document, which the rewrite would lose.
    Move such a section to the hand-written page and link it from the generator."""
    try:
        old = Path(path).read_text()
    except OSError:
        return
    new = set(anchors("\n".join(new_lines)))
    lost = [h for h in anchors(old) if h not in new]
    if lost:
        raise RuntimeError(f"{path}: rewriting it would drop section(s) not generated: "
                           + "; ".join(lost) + ". Move them to docs/results/performance-notes.md "
                           "(and link them from scripts/benchlib/performance.py's "
                           "NOTES_SECTIONS) first.")
