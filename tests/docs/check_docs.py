#!/usr/bin/env python3
"""Checks the documentation as a reader with only the repository meets it.

1. Every page under docs/ (every *.md but docs/README.md itself) is linked from the index,
   docs/README.md, and from the docs row of the top-level README.md.
2. Every relative markdown link in the repository's own markdown files (README.md,
   CHANGELOG.md, docs/**/*.md and every other *.md outside version control, output and build
   folders) points to a file or folder that exists inside the repository. Links with a
   scheme (https:, mailto:) and links to an anchor of the same page are not checked; an
   absolute path (/...) counts as outside the repository. A link to a heading of a markdown
   page (page.md#heading, #heading) must name a heading that page has (GitHub's anchors).
3. No page under docs/ — whichever folder, or a page the index lists under any heading —
   carries a change log ("Since:") or an issue number ("issue 16", "issues 16 and 18"): dated
   entries belong in CHANGELOG.md. (The results pages are generated: their data files and
   templates are held to this through the pages, tests/docs/check_results.py.)

Run from anywhere:  check_docs.py --source-dir DIR              (exit 1, one line per problem)
                    check_docs.py --source-dir DIR --self-test  (plants errors in a copy of
                    the documents and fails unless each one is reported)
Standard library only.
"""
import argparse
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

# Folders whose markdown is not the repository's own documentation: version control, output,
# and build trees (any folder named build*, or holding a CMakeCache.txt, e.g. with _deps/).
SKIP_DIRS = {".git", "out", "node_modules", "__pycache__", "_deps", ".cache", ".venv", "venv"}


def skipped(parent: Path, name: str) -> bool:
    return (name in SKIP_DIRS or name.startswith(("build", "cmake-build"))
            or (parent / name / "CMakeCache.txt").exists())


# [text](target) and ![alt](target); the target up to whitespace or ')'.
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
# [label]: target
REFERENCE_LINK = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$", re.M)
FENCE = re.compile(r"^([ \t]*)(```|~~~).*?^\1\2[^\n]*$", re.M | re.S)
INLINE_CODE = re.compile(r"(`+)(?:(?!\1).)+?\1", re.S)
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")

CHANGELOG_WORDS = re.compile(r"\bSince:")
ISSUE_NUMBER = re.compile(r"\bissues?\s+#?\d+", re.I)
# Index headings and folders whose pages must carry no change log and no issue number.
CLEAN_GROUPS = ("guide", "reference", "design", "results")
CLEAN_DIRS = ("docs/",)


def markdown_files(root: Path):
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not skipped(Path(dirpath), d))
        for name in sorted(filenames):
            if name.endswith(".md"):
                out.append(Path(dirpath) / name)
    return out


def strip_code(text: str) -> str:
    """The text without fenced code blocks and inline code spans (links there are examples)."""
    text = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    return INLINE_CODE.sub(lambda m: " " * len(m.group(0)), text)


def links(text: str):
    """(line number, target) of every link of a markdown text."""
    plain = strip_code(text)
    found = []
    for pattern in (INLINE_LINK, REFERENCE_LINK):
        for m in pattern.finditer(plain):
            found.append((plain.count("\n", 0, m.start(1)) + 1, m.group(1)))
    return sorted(found)


HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")


def anchors(path: Path):
    """The anchors GitHub gives the headings of a markdown page: lower case, punctuation but
    '-' and '_' dropped, spaces as '-', '-1', '-2', ... for repeated headings."""
    out, seen = set(), {}
    text = FENCE.sub("", path.read_text(encoding="utf-8"))
    for line in text.split("\n"):
        m = HEADING.match(line)
        if not m:
            continue
        title = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", m.group(2)).replace("`", "")
        slug = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
        if slug in seen:
            seen[slug] += 1
            out.add(f"{slug}-{seen[slug]}")
        else:
            seen[slug] = 0
            out.add(slug)
    return out


def check_links(root: Path, files):
    problems = []
    cache = {}

    def anchors_of(page: Path):
        if page not in cache:
            cache[page] = anchors(page)
        return cache[page]

    for f in files:
        rel = f.relative_to(root)
        for line, target in links(f.read_text(encoding="utf-8")):
            if SCHEME.match(target):
                continue
            path, _, fragment = target.partition("#")
            path = path.split("?", 1)[0]
            if not path:
                if fragment and fragment not in anchors_of(f):
                    problems.append(f"{rel}:{line}: link {target}: no such heading in this page")
                continue
            if path.startswith("/"):
                problems.append(f"{rel}:{line}: link {target} is an absolute path "
                                "(outside the repository)")
                continue
            resolved = Path(os.path.normpath(f.parent / path))
            try:
                resolved.relative_to(root)
            except ValueError:
                problems.append(f"{rel}:{line}: link {target} points outside the repository")
                continue
            if not resolved.exists():
                problems.append(f"{rel}:{line}: link {target} points to a missing file")
            elif fragment and resolved.suffix == ".md" and fragment not in anchors_of(resolved):
                problems.append(f"{rel}:{line}: link {target}: no such heading in "
                                f"{resolved.relative_to(root).as_posix()}")
    return problems


def index_groups(root: Path):
    """{page path relative to the root: lower-cased title of the index's ## heading above the
    link} for every link of docs/README.md to a markdown file."""
    index = root / "docs" / "README.md"
    groups, heading = {}, ""
    plain = strip_code(index.read_text(encoding="utf-8"))
    for line in plain.split("\n"):
        if line.startswith("## "):
            heading = line[3:].strip().lower()
            continue
        for m in INLINE_LINK.finditer(line):
            target = m.group(1).split("#", 1)[0]
            if not target or SCHEME.match(target) or not target.endswith(".md"):
                continue
            page = Path(os.path.normpath(index.parent / target))
            try:
                groups.setdefault(page.relative_to(root).as_posix(), heading)
            except ValueError:
                pass
    return groups


def check_index(root: Path, files):
    index = root / "docs" / "README.md"
    if not index.exists():
        return ["docs/README.md: the index is missing"], {}
    groups = index_groups(root)
    problems = []
    for f in files:
        rel = f.relative_to(root).as_posix()
        if rel.startswith("docs/") and rel != "docs/README.md" and rel not in groups:
            problems.append(f"{rel}: not linked from docs/README.md")
    readme = root / "README.md"
    in_readme = set()
    if readme.exists():
        for _, target in links(readme.read_text(encoding="utf-8")):
            path = Path(os.path.normpath(root / target.split("#", 1)[0]))
            if path.is_relative_to(root):
                in_readme.add(path.relative_to(root).as_posix())
    for f in files:
        rel = f.relative_to(root).as_posix()
        if rel.startswith("docs/") and rel not in in_readme:
            problems.append(f"{rel}: not linked from README.md (its docs row)")
    return problems, groups


def check_clean(root: Path, files, groups):
    problems = []
    for f in files:
        rel = f.relative_to(root).as_posix()
        group = groups.get(rel, "")
        if not (rel.startswith(CLEAN_DIRS) or group.startswith(CLEAN_GROUPS)):
            continue
        # Code spans and blocks quote the patterns (this checker's own description does).
        for n, line in enumerate(strip_code(f.read_text(encoding="utf-8")).split("\n"), 1):
            for pattern, what in ((CHANGELOG_WORDS, "a change log (\"Since:\")"),
                                  (ISSUE_NUMBER, "an issue number")):
                m = pattern.search(line)
                if m:
                    problems.append(f"{rel}:{n}: {what} in a documentation page: "
                                    f"\"{m.group(0)}\" (dated entries go to CHANGELOG.md)")
    return problems


def check(root: Path):
    root = root.resolve()
    files = markdown_files(root)
    problems = check_links(root, files)
    index_problems, groups = check_index(root, files)
    problems += index_problems
    problems += check_clean(root, files, groups)
    return problems


def self_test(root: Path) -> int:
    """Plants one error of each kind in a copy of the markdown files; each must be reported."""
    root = root.resolve()
    clean = check(root)
    if clean:
        print("self-test: the tree itself has problems, fix them first:")
        print("\n".join(clean))
        return 1
    plants = [
        ("unindexed page", lambda t: (t / "docs" / "orphan.md").write_text("# Orphan\n"),
         "docs/orphan.md: not linked from docs/README.md"),
        ("page missing from README.md", lambda t: _replace(t / "README.md", "(docs/results/upbp.md)",
                                                           "(docs/results/upbp-gone.md)"),
         "docs/results/upbp.md: not linked from README.md"),
        ("missing target", lambda t: _append(t / "README.md", "\n[gone](docs/no-such-page.md)\n"),
         "points to a missing file"),
        ("outside the repository", lambda t: _append(t / "docs" / "README.md",
                                                     "\n[shared](../../shared/DESIGN.md)\n"),
         "points outside the repository"),
        ("heading that is gone", lambda t: _append(t / "README.md",
                                                   "\n[x](docs/guide/service.md#no-such-heading)\n"),
         "no such heading"),
        # A fence opened after a blank line closes at its own closing line, not at the next
        # fence that follows a blank line (links between two code blocks are checked).
        ("link between code blocks", lambda t: _append(
            t / "README.md", "\n\n```\ncode\n```\n\n[gone](docs/gone-between-fences.md)\n\n"
            "```\nmore code\n```\n"), "link docs/gone-between-fences.md points to a missing file"),
        ("absolute path", lambda t: _append(t / "README.md", "\n[abs](/etc/passwd)\n"),
         "absolute path"),
        ("change log in design", lambda t: _append(t / "docs" / "design" / "design.md",
                                                   "\n## Since: something changed\n"),
         "a change log"),
        ("issue number in a reference page", lambda t: _append(_first_in_group(t, "reference"),
                                                               "\nAs issue 16 asked.\n"),
         "an issue number"),
        ("issue number in a results page", lambda t: _append(_first_in_group(t, "results"),
                                                             "\nMeasured for issue 16.\n"),
         "an issue number"),
        ("issue number in a guide page", lambda t: _append(_first_in_group(t, "guide"),
                                                           "\nSee issues 16 and 18.\n"),
         "an issue number"),
    ]
    failed = 0
    with tempfile.TemporaryDirectory(prefix="check-docs-") as tmp:
        copy = Path(tmp) / "repo"
        _copy_markdown_tree(root, copy)
        pristine = {f: f.read_bytes() for f in markdown_files(copy)}
        for name, plant, expected in plants:
            plant(copy)
            reported = check(copy)
            if not any(expected in p for p in reported):
                print(f"self-test: planted {name} was not reported (got: {reported})")
                failed += 1
            else:
                print(f"self-test: planted {name}: reported")
            # Undo the plant: the markdown files as copied, no other markdown file.
            for f in markdown_files(copy):
                if f not in pristine:
                    f.unlink()
            for f, data in pristine.items():
                f.write_bytes(data)
            if check(copy):
                print(f"self-test: undoing the planted {name} failed")
                return 1
    # Links inside code are examples, not links.
    if links("`[x](nowhere.md)`\n\n```\n[y](nowhere.md)\n```\n"):
        print("self-test: a link inside code was taken for a link")
        failed += 1
    return 1 if failed else 0


def _append(path: Path, text: str):
    with open(path, "a", encoding="utf-8") as f:
        f.write(text)


def _replace(path: Path, old: str, new: str):
    text = path.read_text(encoding="utf-8")
    if old not in text:
        raise RuntimeError(f"self-test: {old} not in {path}")
    path.write_text(text.replace(old, new), encoding="utf-8")


def _first_in_group(root: Path, group: str) -> Path:
    for page, heading in sorted(index_groups(root).items()):
        if heading.startswith(group):
            return root / page
    raise RuntimeError(f"the index lists no page under a '{group}' heading")


def _copy_markdown_tree(src: Path, dst: Path):
    """A copy of the tree that holds every markdown file and, as empty files, everything a
    link could point to (so that existence checks behave as in the real tree)."""
    for dirpath, dirnames, filenames in os.walk(src):
        dirnames[:] = [d for d in dirnames if not skipped(Path(dirpath), d)]
        rel = Path(dirpath).relative_to(src)
        (dst / rel).mkdir(parents=True, exist_ok=True)
        for name in filenames:
            if name.endswith(".md"):
                shutil.copyfile(Path(dirpath) / name, dst / rel / name)
            else:
                (dst / rel / name).touch()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--source-dir", default=str(Path(__file__).resolve().parents[2]))
    parser.add_argument("--self-test", action="store_true")
    args = parser.parse_args()
    root = Path(args.source_dir)
    if args.self_test:
        return self_test(root)
    problems = check(root)
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} documentation problem(s)")
        return 1
    print("docs: every page indexed, every link inside the repository and present, "
          "no change log or issue number in any page")
    return 0


if __name__ == "__main__":
    sys.exit(main())
