"""Generates the results pages from their templates and data files, and checks the committed
pages against them.

A template, templates/NAME.md.in, is the page's prose with placeholders, one per line or
inline, each naming a data file relative to the data folder (docs/data/):

    {{table FILE [TABLE]}}   the stamp of FILE, then its table TABLE (the only one when omitted)
    {{block FILE [BLOCK]}}   the stamp of FILE, then its block of markdown lines
    {{stamp FILE}}           the stamp of FILE alone
    {{value FILE KEY}}       one value (KEY: a dotted path into "values"), inline

A data file with "measured": false turns {{table}} and {{block}} into "not measured at this
commit" with its command, and {{value}} into "not measured". The page gets, after its title,
a notice saying it is generated, by what command, from which template and data files.

Templates carry no figures: `check` rejects a decimal number or a number with a unit in a
template's prose (headings, code spans and placeholders excepted).

Standard library only.
"""

import json
import re
from pathlib import Path

from resultslib import data as datafile

PLACEHOLDER = re.compile(r"\{\{\s*(table|block|stamp|value)\s+([^\s}]+)(?:\s+([^\s}]+))?\s*\}\}")
ANY_PLACEHOLDER = re.compile(r"\{\{.*?\}\}")
TEMPLATE_SUFFIX = ".md.in"
TEMPLATES_DIR = Path(__file__).resolve().parent / "templates"
GENERATOR = "scripts/results"

# A figure typed into a template: a decimal number, a percentage, a ratio "2x"/"2×", or a
# number with a unit of time, size or rate. Integers alone stay allowed (section numbers,
# scene names such as 1-glm_c, "1 to 8 workers").
TYPED_FIGURE = re.compile(
    r"(?<![\w.\-/])(\d+\.\d+|\d+(?:\.\d+)?\s?(?:%|×|x\b|ms\b|s\b|µs\b|us\b|ns\b|min\b|"
    r"KiB\b|MiB\b|GiB\b|kB\b|MB\b|GB\b|M rays|rays/s|it/s))")
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1")


class TemplateError(Exception):
    """A template names a data file, table, block or value that does not exist."""


def data_dir(docs_dir):
    return Path(docs_dir) / "data"


def results_dir(docs_dir):
    return Path(docs_dir) / "results"


def template_names(templates_dir=TEMPLATES_DIR):
    return sorted(p.name[:-len(TEMPLATE_SUFFIX)] for p in Path(templates_dir).iterdir()
                  if p.name.endswith(TEMPLATE_SUFFIX))


def load_data(docs_dir, name, cache):
    if name not in cache:
        path = data_dir(docs_dir) / name
        if not path.is_file():
            raise TemplateError(f"data file docs/data/{name} does not exist")
        try:
            cache[name] = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as e:
            raise TemplateError(f"data file docs/data/{name}: {e}") from e
    return cache[name]


def stamp_line(name, data):
    """One line: where the figures of the data file `name` come from."""
    s = data["stamp"]
    link = f"[`{name}`](../data/{name})"
    if data.get("measured", True) is False:
        reason = f" {data['reason'].rstrip('.')}." if data.get("reason") else ""
        return (f"> **Not measured at this commit** (`{s['commit']}`).{reason} To measure: "
                f"`{s['command']}` (writes {link}).")
    note = f" {s['note'].rstrip('.')}." if s.get("note") else ""
    return (f"> Measured at commit `{s['commit']}` on {s['date']} by `{s['command']}`; "
            f"machine: {s['machine']}; load: {s['load']}. Data: {link}.{note}")


def format_cell(value, fmt):
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)) and fmt:
        return format(value, fmt)
    if isinstance(value, float):
        return format(value, ".3g")
    return str(value).replace("|", "\\|").replace("\n", " ")


def table_lines(name, data, table):
    tables = data.get("tables") or {}
    if table is None:
        if len(tables) != 1:
            raise TemplateError(f"docs/data/{name}: {len(tables)} tables; name one")
        table = next(iter(tables))
    if table not in tables:
        raise TemplateError(f"docs/data/{name} has no table {table!r}")
    t = tables[table]
    columns = t["columns"]
    formats = t.get("formats") or [None] * len(columns)
    lines = ["| " + " | ".join(columns) + " |", "|" + " --- |" * len(columns)]
    for row in t["rows"]:
        if len(row) != len(columns):
            raise TemplateError(f"docs/data/{name}, table {table!r}: a row of {len(row)} "
                                f"cells under {len(columns)} columns")
        lines.append("| " + " | ".join(format_cell(v, f) for v, f in zip(row, formats)) + " |")
    return lines


def value_of(name, data, key):
    if data.get("measured", True) is False:
        return "not measured"
    node = data.get("values", {})
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise TemplateError(f"docs/data/{name} has no value {key!r}")
        node = node[part]
    return format_cell(node, None)


def expand(line, docs_dir, cache, used):
    """The lines a template line becomes."""
    whole = PLACEHOLDER.fullmatch(line.strip())
    if whole and whole.group(1) in ("table", "block", "stamp"):
        kind, name, arg = whole.groups()
        data = load_data(docs_dir, name, cache)
        used.append(name)
        out = [stamp_line(name, data)]
        if kind == "stamp" or data.get("measured", True) is False:
            return out
        if kind == "table":
            return out + [""] + table_lines(name, data, arg)
        blocks = data.get("blocks") or {}
        block = arg if arg is not None else (next(iter(blocks)) if len(blocks) == 1 else None)
        if block not in blocks:
            raise TemplateError(f"docs/data/{name} has no block {arg!r}")
        return out + [""] + list(blocks[block])

    def inline(m):
        kind, name, arg = m.groups()
        data = load_data(docs_dir, name, cache)
        used.append(name)
        if kind != "value" or arg is None:
            raise TemplateError(f"{m.group(0)}: only {{{{value FILE KEY}}}} may stand inside "
                                "a line")
        return value_of(name, data, arg)

    out = PLACEHOLDER.sub(inline, line)
    stray = ANY_PLACEHOLDER.search(out)
    if stray:
        raise TemplateError(f"unknown placeholder {stray.group(0)}")
    return [out]


def notice(page, used):
    files = ", ".join(f"[`{n}`](../data/{n})" for n in dict.fromkeys(used))
    source = f" and the data files {files}" if files else " (no data file)"
    return [f"*Generated by `{GENERATOR}` from the template "
            f"`scripts/resultslib/templates/{page}{TEMPLATE_SUFFIX}`{source}; do not edit by hand: "
            "measure again with the command beside each table (it rewrites the data file), then "
            f"run `{GENERATOR}`. How results are made: [guide/results.md](../guide/results.md).*"]


def render(page, docs_dir, templates_dir=TEMPLATES_DIR):
    """The text of docs/results/PAGE.md from its template and the data files under docs_dir."""
    template = (Path(templates_dir) / (page + TEMPLATE_SUFFIX)).read_text(encoding="utf-8")
    lines = template.rstrip("\n").split("\n")
    if not lines or not lines[0].startswith("# "):
        raise TemplateError(f"{page}{TEMPLATE_SUFFIX}: the first line must be the page's title")
    cache, used, body = {}, [], []
    try:
        for line in lines[1:]:
            body.extend(expand(line, docs_dir, cache, used))
    except TemplateError as e:
        raise TemplateError(f"{page}{TEMPLATE_SUFFIX}: {e}") from None
    return "\n".join([lines[0], ""] + notice(page, used) + body).rstrip("\n") + "\n"


def write(pages, docs_dir, templates_dir=TEMPLATES_DIR):
    """Writes each page; returns their paths."""
    out = []
    for page in pages:
        path = results_dir(docs_dir) / (page + ".md")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(render(page, docs_dir, templates_dir), encoding="utf-8")
        out.append(path)
    return out


def typed_figures(template_text):
    """(line number, figure) of every figure typed into a template's prose."""
    found, fence = [], False
    for number, line in enumerate(template_text.split("\n"), 1):
        if line.lstrip().startswith(("```", "~~~")):
            fence = not fence
            continue
        if fence or line.startswith("#") or line.startswith("    "):
            continue
        prose = CODE_SPAN.sub(" ", ANY_PLACEHOLDER.sub(" ", line))
        prose = re.sub(r"\]\([^)]*\)", "]", prose)  # link targets (file names, anchors)
        found += [(number, m.group(1)) for m in TYPED_FIGURE.finditer(prose)]
    return found


def check(docs_dir, templates_dir=TEMPLATES_DIR):
    """Problems (one line each) of the results pages and data files under docs_dir."""
    problems = []
    names = template_names(templates_dir)
    pages = sorted(p.stem for p in results_dir(docs_dir).glob("*.md"))
    for page in pages:
        if page not in names:
            problems.append(f"docs/results/{page}.md: no template "
                            f"scripts/resultslib/templates/{page}{TEMPLATE_SUFFIX} (a page "
                            "written by hand)")
    for page in names:
        template = Path(templates_dir) / (page + TEMPLATE_SUFFIX)
        for number, figure in typed_figures(template.read_text(encoding="utf-8")):
            problems.append(f"{template.name}:{number}: a figure typed into the template: "
                            f"{figure!r} (figures come from data files)")
        path = results_dir(docs_dir) / (page + ".md")
        try:
            expected = render(page, docs_dir, templates_dir)
        except (TemplateError, KeyError, TypeError, ValueError) as e:
            problems.append(f"docs/results/{page}.md: cannot be generated: {e}")
            continue
        if not path.exists():
            problems.append(f"docs/results/{page}.md: missing (run {GENERATOR})")
            continue
        actual = path.read_text(encoding="utf-8")
        if actual != expected:
            problems.append(f"docs/results/{page}.md: differs from what its template and data "
                            f"give (edited by hand?), first at line {first_difference(actual, expected)}; "
                            f"run {GENERATOR}")
    for path in sorted(data_dir(docs_dir).rglob("*.json")):
        rel = path.relative_to(data_dir(docs_dir))
        try:
            content = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            problems.append(f"docs/data/{rel}: not JSON: {e}")
            continue
        lacking = datafile.missing_stamps(content)
        if lacking:
            problems.append(f"docs/data/{rel}: no stamp {', '.join(lacking)} (stamp.{'/'.join(datafile.STAMP_KEYS)})")
    return problems


def first_difference(a, b):
    for number, (x, y) in enumerate(zip(a.split("\n"), b.split("\n")), 1):
        if x != y:
            return number
    return min(a.count("\n"), b.count("\n")) + 1


def publish_blocks(docs_dir, page, lines, command, *, load_before=None, name="benchmark.json",
                   block="page"):
    """What a benchmark that formats its own page calls instead of writing the page: its lines
    (a "# Title" first, which the template holds) go, stamped, to DOCS/data/PAGE/NAME as one
    block, and DOCS/results/PAGE.md is generated from the template. Returns the page's path."""
    body = list(lines)
    if body and body[0].startswith("# "):
        body = body[1:]
    while body and not body[0].strip():
        body.pop(0)
    while body and not body[-1].strip():
        body.pop()
    stamp = datafile.stamp(command, load_before=load_before)
    datafile.write(data_dir(docs_dir) / page / name,
                   {"stamp": stamp, "measured": True, "blocks": {block: body}})
    return write([page], docs_dir)[0]


def load_text(load_average):
    """A load average tuple (1, 5, 15 min) as the stamps write it; None stays None."""
    if not load_average:
        return None
    return " / ".join(f"{x:.2f}" if isinstance(x, float) else str(x)
                      for x in load_average) + " (1 / 5 / 15 min)"


def adopt(page, stamp, docs_dir, templates_dir=TEMPLATES_DIR):
    """Turns docs/results/PAGE.md, as a benchmark wrote it, into DOCS/data/PAGE/benchmark.json
    (its body as one block, stamped with `stamp`: what the run recorded) and a template that
    shows that block; then generates the page. Returns the page's path."""
    path = results_dir(docs_dir) / (page + ".md")
    template = Path(templates_dir) / (page + TEMPLATE_SUFFIX)
    if template.exists():
        raise TemplateError(f"{template} exists already")
    lines = path.read_text(encoding="utf-8").rstrip("\n").split("\n")
    if not lines[0].startswith("# "):
        raise TemplateError(f"{path}: the first line is not a title")
    body = lines[1:]
    while body and not body[0].strip():
        body.pop(0)
    datafile.write(data_dir(docs_dir) / page / "benchmark.json",
                   {"stamp": dict(stamp), "measured": True, "blocks": {"page": body}})
    template.write_text(f"{lines[0]}\n\n{{{{block {page}/benchmark.json}}}}\n", encoding="utf-8")
    return write([page], docs_dir, templates_dir)[0]
