#!/usr/bin/python3
"""Turns a markdown table a measuring script printed into a stamped data file.

    SCRIPT | record_table.py FILE --command "SCRIPT ARGS" [--load-before "L"] [--name TABLE]
                             [--value KEY=TEXT ...]

Reads the table (lines starting with '|') from stdin; cells that are numbers become JSON
numbers, the others stay text. Writes FILE (docs/data/PAGE/NAME.json) with its stamp
(data.stamp: commit, machine, load, command, date). For scripts that are not Python, e.g.
scripts/memory-calibration --data FILE.
"""
import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from resultslib import data  # noqa: E402


def cell(text):
    text = text.strip()
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def parse_table(lines):
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines
            if line.startswith("|")]
    if len(rows) < 2:
        raise ValueError("no markdown table on stdin")
    columns, texts = rows[0], rows[2:]
    body = [[cell(c) for c in row] for row in texts]
    # Numbers are shown as printed: a column whose numbers all have N decimals keeps them
    # (".Nf", so 1.80 stays 1.80); otherwise six significant digits ("g").
    formats = []
    for i in range(len(columns)):
        decimals = {len(r[i].split(".")[1]) if "." in r[i] else 0
                    for r, v in zip(texts, body) if isinstance(v[i], (int, float))}
        if not any(isinstance(v[i], float) for v in body):
            formats.append(None)
        else:
            formats.append(f".{decimals.pop()}f" if len(decimals) == 1 else "g")
    return {"columns": columns, "rows": body, "formats": formats}


def main(argv):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", type=Path)
    p.add_argument("--command", required=True)
    p.add_argument("--load-before")
    p.add_argument("--name", default="main")
    p.add_argument("--note")
    p.add_argument("--value", action="append", default=[], metavar="KEY=TEXT",
                   help="a value the page quotes, e.g. a claim's verdict (repeatable)")
    args = p.parse_args(argv)
    table = parse_table(sys.stdin.read().split("\n"))
    stamp = data.stamp(args.command, load_before=args.load_before)
    if args.note:
        stamp["note"] = args.note
    values = dict(v.split("=", 1) for v in args.value)
    content = {"stamp": stamp, "measured": True, "tables": {args.name: table}}
    if values:
        content["values"] = values
    data.write(args.file, content)
    print(f"record_table: wrote {args.file} ({len(table['rows'])} rows)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
