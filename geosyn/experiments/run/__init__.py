"""One run: build its parts from the config, claim its directory, run a procedure, log.

`scene` (the run's world, built once: `BuiltScene`), `build` (metric, synergies,
controllers, disturbances, simulations), `references` (every reference section),
`runner` (`run_experiment`), `rundir` (a run directory claimed by one writer),
`termination` (SIGTERM ends a run cleanly), `runlog` (run log, provenance), `progress`
(progress bars), `run_metrics` (the standard metrics of every run). The modules are
imported by name; nothing is re-exported here, so that ``geosyn --help`` stays light.
"""

__all__: list[str] = []
