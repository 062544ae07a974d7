"""Axis error tables, the controller files that load them, and those files read back as their controllers read
them (docs/compensation.md).

- :mod:`kinid.axis_tables.formats` — the controller formats' registry and the writer every method shares;
- :mod:`kinid.axis_tables.readers` — each format's file read back and applied as its controller applies it
  (``kinid compensate`` checks its own files with them before writing).
"""
from .formats import *  # noqa: F401,F403 (the registry and the writers: the package's front door)
from .formats import __all__ as _formats
from .readers import FileTable, applied, csv_tables, linuxcnc_table, sinumerik_table, twincat_table  # noqa: F401

__all__ = list(_formats) + ["FileTable", "applied", "csv_tables", "linuxcnc_table", "sinumerik_table",
                            "twincat_table"]
