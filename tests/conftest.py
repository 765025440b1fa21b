"""Test-suite set-up: property-based tests draw the same examples on every run.

Hypothesis draws new random examples each run by default, so a bound that a rare example breaks turns CI red at
random (session 34: a Manhattan frame's heading bound, `tests/panogeom/test_vanishing.py`). With ``derandomize``
the examples follow from each test's code, every run and every machine alike; a test's own ``@settings`` still
sets its example count. ``HYPOTHESIS_PROFILE=explore`` draws fresh random examples, for looking for new failures.
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
