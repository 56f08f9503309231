"""The package version (one place; deep modules import it from here, not from the face)."""

__version__ = "0.1.0"
