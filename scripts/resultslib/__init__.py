"""The results pages (docs/results/) and the data files they are generated from (docs/data/).

- data.py: the stamp every data file carries (commit, machine, load, command, date) and
  writing a data file; the measuring scripts (scripts/bench's suites, scripts/memory-calibration,
  ...) use it.
- pages.py: templates (templates/NAME.md.in: prose and placeholders, never figures) plus data
  files -> docs/results/NAME.md; the check that every committed page is exactly what its
  template and data give (`scripts/results --check`, CTest docs.results_generated).

Standard library only. The format is described in docs/guide/results.md.
"""
