"""Reading an experiment's YAML: the loader, every problem of a file, resource limits."""
