"""One run: build its parts from the config, claim its directory, simulate, log."""
