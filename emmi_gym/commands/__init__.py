"""The ``emmi-gym`` subcommands, one module each: the module builds its subcommand's parser
(``add_parser``) and runs it (``run``), importing the heavy packages only when it runs. (``train``,
``clone``, ``evaluate`` and ``benchmark`` are still built in :mod:`emmi_gym.cli`.)"""
