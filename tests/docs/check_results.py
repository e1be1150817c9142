#!/usr/bin/env python3
"""Checks that the results pages are generated only (docs/guide/results.md).

1. Every page docs/results/NAME.md has a template scripts/resultslib/templates/NAME.md.in, and
   regenerating it from the template and docs/data/ (`scripts/results`) gives the committed
   page byte for byte: a figure edited by hand in a page fails.
2. Every data file docs/data/**/*.json carries a stamp with commit, machine, load, command and
   date.
3. No template holds a typed figure (a decimal number, a percentage, a number with a unit).

Run from anywhere:  check_results.py --source-dir DIR              (exit 1, one line per problem)
                    check_results.py --source-dir DIR --self-test  (plants errors in a copy of
                    the pages, data and templates and fails unless each one is reported)
Standard library only.
"""
import argparse
import json
import re
import shutil
import sys
import tempfile
from pathlib import Path


def load_pages_module(source_dir: Path):
    sys.path.insert(0, str(source_dir / "scripts"))
    from resultslib import pages
    return pages


def check(source_dir: Path, docs_dir: Path, templates_dir: Path):
    pages = load_pages_module(source_dir)
    return pages.check(docs_dir, templates_dir)


def copy_tree(source_dir: Path, dst: Path):
    """docs/results, docs/data and the templates (all the check reads) into dst."""
    shutil.copytree(source_dir / "docs" / "results", dst / "docs" / "results")
    shutil.copytree(source_dir / "docs" / "data", dst / "docs" / "data")
    shutil.copytree(source_dir / "scripts" / "resultslib" / "templates", dst / "templates")
    return dst / "docs", dst / "templates"


def edit_figure_in_page(docs: Path, templates: Path):
    """Changes one digit of a table row of a generated page, as a hand edit would."""
    for page in sorted((docs / "results").glob("*.md")):
        lines = page.read_text().split("\n")
        for i, line in enumerate(lines):
            if line.startswith("| ") and re.search(r"\d", line) and "---" not in line:
                lines[i] = re.sub(r"\d", lambda m: str((int(m.group(0)) + 1) % 10), line, count=1)
                page.write_text("\n".join(lines))
                return
    raise AssertionError("no table row with a figure in any results page")


def drop_stamp_key(key):
    def plant(docs: Path, templates: Path):
        path = sorted((docs / "data").rglob("*.json"))[0]
        data = json.loads(path.read_text())
        del data["stamp"][key]
        path.write_text(json.dumps(data))
    return plant


def edit_figure_in_data(docs: Path, templates: Path):
    """A figure changed in a data file a page shows: the committed page no longer matches."""
    path = docs / "data" / "performance" / "benchmark.json"
    data = json.loads(path.read_text())
    block = data["blocks"]["page"]
    i = next(i for i, line in enumerate(block) if line.startswith("| ") and re.search(r"\d", line)
             and "---" not in line)
    block[i] = re.sub(r"\d", lambda m: str((int(m.group(0)) + 1) % 10), block[i], count=1)
    path.write_text(json.dumps(data))


def page_without_template(docs: Path, templates: Path):
    (docs / "results" / "typed-by-hand.md").write_text("# Typed by hand\n\n| a |\n| --- |\n| 1.5 |\n")


def figure_in_template(docs: Path, templates: Path):
    path = sorted(templates.glob("*.md.in"))[0]
    path.write_text(path.read_text() + "\nIt renders an iteration in 0.35 s.\n")


def missing_data_file(docs: Path, templates: Path):
    path = sorted(templates.glob("*.md.in"))[0]
    path.write_text(path.read_text() + "\n{{table nowhere/missing.json}}\n")


PLANTS = [
    ("a figure edited by hand in a page", edit_figure_in_page, "differs from what its template"),
    ("a data file without its load stamp", drop_stamp_key("load"), "no stamp load"),
    ("a data file without its commit stamp", drop_stamp_key("commit"), "no stamp commit"),
    ("a data file without its command stamp", drop_stamp_key("command"), "no stamp command"),
    ("a data file without its machine stamp", drop_stamp_key("machine"), "no stamp machine"),
    ("a figure changed in a data file, page not regenerated", edit_figure_in_data,
     "docs/results/performance.md: differs"),
    ("a page without a template", page_without_template, "typed-by-hand.md: no template"),
    ("a figure typed into a template", figure_in_template, "a figure typed into the template"),
    ("a template naming a missing data file", missing_data_file, "cannot be generated"),
]


def self_test(source_dir: Path) -> int:
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        docs, templates = copy_tree(source_dir, Path(tmp) / "clean")
        clean = check(source_dir, docs, templates)
        if clean:
            print("self-test: the unchanged copy already has problems:\n  " + "\n  ".join(clean))
            return 1
        for number, (name, plant, expected) in enumerate(PLANTS):
            docs, templates = copy_tree(source_dir, Path(tmp) / f"plant{number}")
            plant(docs, templates)
            problems = check(source_dir, docs, templates)
            if any(expected in p for p in problems):
                print(f"self-test: reported {name}")
            else:
                failures += 1
                print(f"self-test: NOT reported: {name} (expected {expected!r}; got "
                      f"{problems or 'no problem'})")
    print(f"self-test: {len(PLANTS) - failures} of {len(PLANTS)} planted errors reported")
    return 1 if failures else 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--source-dir", type=Path, required=True)
    p.add_argument("--self-test", action="store_true")
    args = p.parse_args()
    source_dir = args.source_dir.resolve()
    if args.self_test:
        return self_test(source_dir)
    problems = check(source_dir, source_dir / "docs",
                     source_dir / "scripts" / "resultslib" / "templates")
    for problem in problems:
        print(problem)
    print(f"{len(problems)} results problem(s): every page generated from its template and "
          "stamped data (scripts/results), no figure typed into a template")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
