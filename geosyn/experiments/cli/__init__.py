"""The ``geosyn`` command line (`main`, the console script's entry point).

`main` parses and dispatches; `registry` holds the `Command` record; the commands are in
`experiment_commands` (robots, list, run, sweep, report), `schema_commands` (schema,
init) and `viewer_commands` (view, explore).
"""

from geosyn.experiments.cli.main import COMMANDS, build_parser, main

__all__ = ["COMMANDS", "build_parser", "main"]
