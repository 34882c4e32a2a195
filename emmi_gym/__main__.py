"""``python -m emmi_gym``: the ``emmi-gym`` command."""

import sys

from emmi_gym.tools.cli import main

if __name__ == "__main__":
    sys.exit(main())
