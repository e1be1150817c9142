"""Data files of the results pages: docs/data/PAGE/NAME.json.

A data file is one measurement set as a JSON object:

    {"stamp": {"commit": ..., "machine": ..., "load": ..., "command": ..., "date": ...},
     "measured": true,                      # false: not measured at this commit (see below)
     "tables": {"NAME": {"columns": [...], "rows": [[...], ...], "formats": [...]}},
     "values": {"key": value, ...},         # single figures quoted in prose
     "blocks": {"NAME": ["markdown line", ...]}}   # sections a benchmark formats itself

The stamp says where the figures come from: the commit measured, the machine, the load while
measuring (/proc/loadavg), the command that wrote the file (run from the repository root) and
the date. A file with "measured": false holds no figures: its page says "not measured at this
commit" and shows the command that measures it.

Standard library only.
"""

import datetime
import json
import os
import platform
import re
import subprocess
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
STAMP_KEYS = ("commit", "machine", "load", "command", "date")


def commit(root=REPO_ROOT):
    """The checked-out commit (12 hex digits), with "+changes" when tracked files differ from
    it: the figures then come from code that no commit holds."""
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no", "--", ":!docs"],
                               capture_output=True, text=True).stdout.strip()
        return head + ("+changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def machine():
    """CPU model, cores, memory and kernel, e.g. "AMD EPYC, 2 cores, 23.5 GiB, Linux 6.1"."""
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    memory = "? GiB"
    try:
        kb = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1))
        memory = f"{kb / 2**20:.1f} GiB"
    except (OSError, AttributeError):
        pass
    return f"{model}, {os.cpu_count()} cores, {memory}, {platform.system()} {platform.release()}"


def load():
    """The 1, 5 and 15 minute load averages now, as /proc/loadavg gives them."""
    try:
        return " / ".join(Path("/proc/loadavg").read_text().split()[:3]) + " (1 / 5 / 15 min)"
    except OSError:
        return "unknown"


def now():
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def stamp(command, *, load_before=None, root=REPO_ROOT):
    """The stamp of a measurement made now by `command`. `load_before` (from load()) is the load
    when the measurement started; the load now is added as "after"."""
    after = load()
    text = f"{load_before} before, {after} after" if load_before else after
    return {"commit": commit(root), "machine": machine(), "load": text, "command": command,
            "date": now()}


def missing_stamps(data):
    """The stamp keys a data file's object lacks (or leaves empty)."""
    s = data.get("stamp") if isinstance(data, dict) else None
    if not isinstance(s, dict):
        return list(STAMP_KEYS)
    return [k for k in STAMP_KEYS if not isinstance(s.get(k), str) or not s[k].strip()]


def write(path, data):
    """Writes a data file (sorted keys, one value per line, so diffs are readable) after
    checking its stamp; raises ValueError when a stamp key is missing."""
    lacking = missing_stamps(data)
    if lacking:
        raise ValueError(f"{path}: data file without stamp(s) {', '.join(lacking)}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, sort_keys=True, ensure_ascii=False) + "\n")


def not_measured(command, reason, *, root=REPO_ROOT):
    """A data file for a figure not measured at this commit: the command that measures it and
    why it was not run."""
    return {"stamp": {"commit": commit(root), "machine": "not measured", "load": "not measured",
                      "command": command, "date": now()},
            "measured": False, "reason": reason}
