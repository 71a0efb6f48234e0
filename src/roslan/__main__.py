"""``python -m roslan`` = the ``roslan`` command."""

from __future__ import annotations

import sys

from roslan.cli import main

sys.exit(main())
