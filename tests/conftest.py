"""Shared test settings.

Hypothesis deadlines are off: tests never assert wall-clock time (numba compiles on
first call and CI machines are shared). The number of examples stays modest so that
the suite runs in minutes.
"""

import os

from hypothesis import HealthCheck, settings

settings.register_profile("default", deadline=None, max_examples=60,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", deadline=None, max_examples=1000,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))
