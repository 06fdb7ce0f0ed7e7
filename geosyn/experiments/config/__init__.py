"""Reading an experiment's YAML: `loader` (files, ``--set`` overrides, validation in
stages), `problems` (every problem of a file, with the closest valid names),
`resource_limits` (encodings, sizes, nesting, run and tick limits)."""

__all__: list[str] = []
