"""The output-folder contract of one run (OUTDIR)."""

from __future__ import annotations

__all__: list[str] = []
