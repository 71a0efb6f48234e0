"""Shared pytest configuration.

Under CI (``CI`` set, as ``.ci/run`` is run) Hypothesis is derandomized: the same
examples every run, so a submission's result does not depend on luck. Local runs keep
exploring new examples (and replay any failure from the local example database).
"""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
