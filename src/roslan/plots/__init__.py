"""Figures: ``roslan plot ...`` subcommands (one module per figure family)."""

from __future__ import annotations
