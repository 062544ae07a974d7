"""Reports on the ground floor: one page layout for every kinid report, as HTML and as PDF, and the
matplotlib figures it holds (saved whole or not at all).

- :mod:`kinid.reports.html` — the page (a Jinja2 template, every value escaped) and the report folder;
- :mod:`kinid.reports.pdf` — the same content as A4 pages;
- :mod:`kinid.reports.figures` — figures without pyplot state, saved as PNG whole or not at all.

Imports only the rest of the ground floor.
"""
__all__ = ["html", "pdf", "figures"]
