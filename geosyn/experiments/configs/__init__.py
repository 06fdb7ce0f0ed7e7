"""Built-in experiment configurations (YAML files shipped as package data)."""
