"""A pytest plugin for ``suite_memory.py``: writes the id of the test that starts to the file named by
``SUITE_MEMORY_CURRENT``, so that the sampler can say which test ran at each sample."""

import os
from pathlib import Path


def pytest_runtest_logstart(nodeid, location):
    Path(os.environ["SUITE_MEMORY_CURRENT"]).write_text(nodeid)
