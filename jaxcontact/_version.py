"""The package's version, in a module of its own so that the modules below the
package's `__init__` (e.g. `_dataset`, which records it) can read it."""

__version__ = "0.1.0"
