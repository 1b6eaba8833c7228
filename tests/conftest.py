"""Hypothesis profiles: the default one is derandomized, so the suite gives the same verdict on every run.

Profile "default" (plain ``pytest``): fixed examples, CI-sized.  Profile "fuzz"
(``HYPOTHESIS_PROFILE=fuzz pytest -k any``): random examples on demand, 2000 where a
test does not set its own count.
"""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("default", derandomize=True, print_blob=True)
settings.register_profile("fuzz", derandomize=False, max_examples=2000, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))
