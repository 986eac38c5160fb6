"""The package version (one place; read by ``iamp.__version__`` and the CLI)."""

__version__ = "0.2.0"
