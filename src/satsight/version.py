"""The package version (also in pyproject.toml's [project] table)."""

__version__ = "0.1.0"
