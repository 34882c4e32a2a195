"""The tools over the environment library: training and evaluating agents (:mod:`.training`), the
experiments and their reports (:mod:`.experiments`), the scripted policies (:mod:`.policies`), the
shipped agents (:mod:`.pretrained`) and the ``emmi-gym`` command (:mod:`.cli`, :mod:`.commands`).

The tools import the library; the library never imports the tools (``tests/project/test_layout.py``)."""
