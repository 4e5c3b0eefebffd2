"""The package version (one place; setuptools reads pyproject.toml)."""

__version__ = "0.1.0"
